// msid fit --method cissim: discrete-cISSIM from periodic time records (You et al. 2023), with the
// noise covariances of section 4.3 (docs/fitting.md, "cissim"): options -> CissimRequest ->
// fit_cissim (tools/fitjob) -> the model file.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "msid_fit_job.hpp"

namespace msidcli {

static const char *CISSIM_HELP =
    "usage: msid fit --method cissim --period P --lines L1,L2,... --experiment e.csv [--experiment e2.csv ...]\n"
    "                [--order n] [--reduced] [--block-rows NBAR] [--max-order N] [--skip-periods K]\n"
    "                [--isp auto|direct|fft] [--no-d] [--lags M] [--no-covariance] [--columns u1=..,y1=..]\n"
    "                [--refine ml|none]\n"
    "                -o model.json\n"
    "\n"
    "Discrete-cISSIM (You, Huang, Zhang 2023) on periodic time records (the records of `msid frf`, whole\n"
    "periods of P samples; one experiment may excite all inputs): invariant-subspace regression (Alg. 1 by\n"
    "per-period sums and one product per line, or Alg. 3 by one FFT, chosen by the number of lines), A, C\n"
    "and the order by QR + SVD (Alg. 4), B and D by the Sylvester regression (Alg. 5).\n"
    "  --lines          the excited lines (bins below P/2; ranges a:b, a:step:b)\n"
    "  --reduced        use only --lines in the regression (reduced set); default: the full set of bins\n"
    "                   0 .. ceil(P/2) - 1\n"
    "  --order n        state order; without it the largest singular-value gap up to --max-order (10)\n"
    "  --block-rows     nbar of Alg. 4 (default 2n, or max-order + 1 when the order is estimated)\n"
    "  --skip-periods   leading periods of each record to ignore (default 1, as the paper: transient)\n"
    "  --lags M         correlation lags of the noise covariance (default max(ceil(n^2/ny^2) + 1, N^(1/3)), <= 50)\n"
    "  --unweighted     the published Alg. 4 (no whitening of R22 by the noise of the block rows; biased\n"
    "                   for a reduced set of lines in a band at finite N)\n"
    "  --allow-unstable keep poles of A outside the unit circle (default: reflected, Assumption 1)\n"
    "  --no-covariance  skip Sigma_ww, Sigma_vv, Sigma_tt (section 4.3, Alg. 6-7)\n"
    "  --refine ml      (default) refine the cissim model by weighted output error (maximum likelihood) on the\n"
    "                   same phasors, weights from the per-line sample covariance over the periods, and report\n"
    "                   the covariance of the model FRF at --lines (frf[].cov); needs >= 2 periods after the\n"
    "                   skipped ones and noise. --refine none: the paper's estimate alone (no FRF covariance)\n";

int cmd_fit_cissim(int argc, char **argv)
{
    Args a(argc, argv, 2, CISSIM_HELP,
           {"method", "period", "lines", "order", "block-rows", "max-order", "skip-periods", "isp", "lags", "columns",
            "output", "refine"},
           {"reduced", "no-d", "no-covariance", "unweighted", "allow-unstable"}, {"experiment"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "' (use --experiment)");
    const std::string out = a.require("output");
    msidfitjob::CissimRequest rq;
    rq.period = parse_u32(a.require("period"), "--period");
    rq.lines = parse_uint_list(a.require("lines"), "--lines");
    msidfitjob::check_cissim(rq);
    if (a.all("experiment").empty()) throw UsageError("missing --experiment <file.csv>");
    if (a.has("order")) rq.order = parse_u32(a.get("order"), "--order");
    if (a.has("max-order")) rq.max_order = parse_u32(a.get("max-order"), "--max-order");
    if (a.has("block-rows")) rq.block_rows = parse_u32(a.get("block-rows"), "--block-rows");
    rq.no_d = a.has("no-d");
    rq.unweighted = a.has("unweighted");
    rq.allow_unstable = a.has("allow-unstable");
    rq.skip_periods = a.u32("skip-periods", 1);
    rq.isp = a.get("isp", "auto");
    rq.reduced = a.has("reduced");
    rq.refine = a.get("refine", "ml");
    rq.no_covariance = a.has("no-covariance");
    msidfitjob::check_cissim(rq);
    const ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns")) : ColumnMap{};
    // FFTW's first plan (the planner's own set-up, dearer than the fit's transforms) on another thread
    // while the files are read (msid_fftw_planner.hpp)
    if (rq.period >= MSID_MIN_PERIOD && rq.period <= MSID_MAX_PERIOD) fftw_warmup_start(rq.period);
    std::vector<Record> recs;
    for (const auto &p : a.all("experiment")) recs.push_back(read_experiment(p, cols, true));
    if (a.has("lags")) rq.lags = parse_u32(a.get("lags"), "--lags");
    return write_fit(msidfitjob::fit_cissim(recs, rq, print_fit_note), out, true);
}

}  // namespace msidcli
