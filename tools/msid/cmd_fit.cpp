// msid fit | validate | compare: parametric models from msid-frf/1 files. The fit itself is one
// call of the fit job (tools/fitjob): options -> FitRequest -> fit_frf -> the model file.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"
#include "frf_import.hpp"
#include "msid_fit_job.hpp"

#include "model_io.hpp"
#include "stats.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace msidcli {

using namespace msidfit;

static const char *FIT_HELP =
    "Which method: ml for the model you report (weighted maximum likelihood: the best fit to the data's\n"
    "  noise, parameter standard deviations, modes with their uncertainty); subspace for a quick,\n"
    "  non-iterative model or a start; lmfd for a closed-form fit of a fraction D^-1 N (fixed entries with\n"
    "  --pin); multi for time records (ring-downs, free decays) without an FRF; cissim for periodic time\n"
    "  records in closed form. Without --order ml chooses the order (auto: stabilisation diagram, as msid\n"
    "  measure --fit does), subspace from its singular values. Check any model with msid validate.\n"
    "\n"
    "usage: msid fit --method subspace|lmfd|ml frf.json -o model.json [--format msid|touchstone|uff|csv|mat]\n"
    "                [--order n|auto|a:b | --nd K --nn J] [--domain dt|ct] [--weight cov|known-input|none]\n"
    "                [--noise-var S2] [--r R] [--stable] [--no-d] [--pin N0=0 ...] [--start subspace|sk|MODEL]\n"
    "                [--max-iter N] [--delta D] [--beta B] [--feedthrough auto|yes|no] [--param poles|lmfd]\n"
    "                [--allow-unstable] [--refine ml|none|N]\n"
    "       msid fit --method multi --experiment r1.csv ... --order n|auto -o model.json   (time records)\n"
    "\n"
    "  subspace  frequency-domain subspace (McKelvey; Pintelon 2002 Alg. 1, CT by the bilinear map,\n"
    "            Alg. 2.1) weighted by the FRF covariance; block rows r in {1.5n, 2n, 3n, 4n}, the one with the\n"
    "            smallest weighted cost (35), refined (--refine ml, the default: up to 30 Levenberg-Marquardt\n"
    "            steps; N: up to N steps; none: the bare estimate, as for cissim) on\n"
    "            that cost (never raising it); stable (constrained refinement); order from the singular values\n"
    "            when --order is omitted\n"
    "  lmfd      closed-form ML of a left matrix fraction D(p)^-1 N(p), fully or under-constrained\n"
    "            (Gonzalez et al. 2025 Thm 6): minimum-norm solution, kernel basis, --pin to fix entries\n"
    "  ml        weighted maximum likelihood (eq. 40): --param poles (default; dt with several inputs: lmfd)\n"
    "            pole-residue form from vector-fitting and subspace starts (subspace's refined model among them:\n"
    "            ml never ends above a start), scaled trust-region LM, order 40+; --param lmfd: LMFD from\n"
    "            subspace's model (default) or Sanathanan-Koerner, with bounds (45)-(46); stable models;\n"
    "            parameter covariance (pseudo-inverse Fisher information with its rank). When the iterations\n"
    "            run out the best iterate is written marked \"converged\": false and the exit status is 3\n"
    "  --start   ml --param lmfd: subspace (default) | sk; ml --param poles: MODEL.json, refine that model\n"
    "            (a previous fit, another tool's model): its poles are the only start; its order when --order\n"
    "            is left out\n"
    "  multi     time records of any lengths (ring-downs, free decays, transients), every record's initial\n"
    "            conditions eliminated (Markovsky & Pintelon): msid fit --method multi --help\n"
    "  --feedthrough auto (LR test at 1%, default) | yes | no: the direct term D (accelerations need it)\n"
    "  stable models by default (subspace, ml): a stable plant's model is stable, whatever the cost says\n"
    "  --allow-unstable  no stability constraint: for plants that are unstable (measured in closed loop)\n"
    "  --stable  the default (subspace: also reflects unstable poles in the r scan)\n"
    "  --order n     state order (ml poles: number of poles); LMFD degrees nD = n/ny, nN from --feedthrough;\n"
    "                auto (ml's default), a:b or a:step:b: order selection with a\n"
    "                stabilisation diagram (docs/fitting.md);\n"
    "                on LPM files the cost and p-value of every (2W+1)-th line, as msid validate\n"
    "  --nd, --nn    LMFD degrees (p = s for ct, p = 1/z for dt)\n"
    "  --weight      covariance for the weighting: cov (nonparametric, default), known-input, none (the\n"
    "                default for an FRF without covariance: unweighted, no p-value)\n"
    "  --format      the FRF file's format (default: by its extension and content): msid-frf/1, or one\n"
    "                measured by another tool (Touchstone .sNp, UFF 58 .uff/.unv, CSV, idfrd .mat; msid import)\n"
    "  --noise-var   known white output noise variance per sample (replaces the estimated noise)\n"
    "  --weight-smooth H  ml, and subspace's refinement, with --weight cov|known-input: weights from the\n"
    "                covariance pooled over 2H+1 neighbouring lines (default H = 4 when the file has at least\n"
    "                4(2H+1) lines, else 0; 0: each line's own sample covariance); only lines whose own dof\n"
    "                are few, only neighbours whose covariance matrix equals the line's (LR test at 5%)\n"
    "  --method cissim  discrete-cISSIM (You et al. 2023) from periodic time records, no FRF file:\n"
    "                --period P --lines .. --experiment e.csv; `msid fit --method cissim --help`\n";

static const std::vector<std::pair<std::string, Weight>> WEIGHTS = {
    {"cov", Weight::Cov}, {"known-input", Weight::KnownInput}, {"none", Weight::None}};

// Exit status of `msid fit` when the iterations ran out: the best iterate is written, marked
// "converged": false (docs/fitting.md). 1 = error, 2 = usage error.
static const int EXIT_NOT_CONVERGED = 3;

// The options of `msid fit --method subspace|lmfd|ml` as the fit job's request.
static msidfitjob::FitRequest fit_request(const Args &a)
{
    msidfitjob::FitRequest rq;
    rq.method = a.get("method");
    rq.order = a.get("order");
    if (a.has("nd")) rq.nd = a.u32("nd", 1);
    if (a.has("nn")) rq.nn = a.u32("nn", 0);
    rq.domain = a.get("domain");
    rq.weight = a.get("weight");   // "": cov, or unit weights for an FRF without covariance
    if (a.has("noise-var")) rq.noise_var = a.f64("noise-var", 0.0);
    if (a.has("r")) rq.r = a.u32("r", 0);
    rq.stable = a.has("stable");
    rq.allow_unstable = a.has("allow-unstable");
    rq.no_d = a.has("no-d");
    rq.pins = a.all("pin");
    rq.start = a.get("start");
    if (a.has("max-iter")) rq.max_iter = a.u32("max-iter", 0);
    if (a.has("delta")) rq.delta = a.f64("delta", 0.0);
    if (a.has("beta")) rq.beta = a.f64("beta", 0.0);
    rq.feedthrough = a.get("feedthrough");
    rq.param = a.get("param");
    rq.refine = a.get("refine");
    if (a.has("weight-smooth")) rq.weight_smooth = a.u32("weight-smooth", 0);
    return rq;
}

// The notes of a fit as they arise, on stderr.
void print_fit_note(const std::string &note) { std::fprintf(stderr, "msid fit: %s\n", note.c_str()); }

// The model file of a fit and what msid prints of it; exit status 3 when the iterations ran out.
int write_fit(const msidfitjob::FitOutcome &o, const std::string &out, bool durable)
{
    std::fputs(o.before.c_str(), stdout);
    write_json_file(out, o.model, durable);   // derived from files (docs/model-format.md)
    std::printf("%s%s%s", o.head.c_str(), out.c_str(), o.tail.c_str());
    std::fputs(o.after.c_str(), stdout);
    if (o.converged) return 0;
    std::fprintf(stderr, "msid fit: warning: %s%s marked \"converged\": false (exit status %d)\n",
                 o.not_converged.c_str(), out.c_str(), EXIT_NOT_CONVERGED);
    return EXIT_NOT_CONVERGED;
}

int cmd_fit(int argc, char **argv)
{
#ifdef __GLIBC__
    // A fit is one short process that reads a file of up to some MB into a JSON tree and frees it:
    // keep large blocks on the heap (not a fresh mmap each, whose pages fault in zeroed every time)
    // and grow the heap 4 MB at a time.
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TOP_PAD, 4 << 20);
#endif
    if (fit_method_is(argc, argv, "multi")) return cmd_fit_multi(argc, argv);   // cmd_fit_multi.cpp
    if (cissim_requested(argc, argv)) return cmd_fit_cissim(argc, argv);
    Args a(argc, argv, 2, FIT_HELP,
           {"method", "order", "nd", "nn", "domain", "weight", "noise-var", "r", "start", "max-iter", "delta", "beta",
            "feedthrough", "param", "output", "refine", "weight-smooth", "format"},
           {"stable", "no-d", "allow-unstable"}, {"pin"});
    const msidfitjob::FitRequest rq = fit_request(a);
    const bool scan = msidfitjob::order_is_scan(rq);
    // an order scan names its model file first; a fixed order its FRF file
    if (scan && !a.has("output")) throw UsageError("missing -o <model.json>");
    if (scan && a.positional().empty()) throw UsageError("give exactly one readable msid-frf/1 file");
    if (a.positional().size() != 1) throw UsageError("give exactly one msid-frf/1 file");
    const std::string out = a.require("output");
    const std::string method = a.require("method");
    // multi and cissim went their own ways above: listed so that a wrong name shows every method
    parse_enum(method, "--method", {"subspace", "lmfd", "ml", "multi", "cissim"});
    FrfData f;
    try {
        f = msidfrfimport::load_frf(a.positional()[0], a.get("format"));
    } catch (const FitError &e) {
        if (scan) throw UsageError("give exactly one readable msid-frf/1 file");
        throw Error(e.what());
    }
    try {
        return write_fit(msidfitjob::fit_frf(f, rq, print_fit_note), out, scan);
    } catch (const msidfitjob::Error &e) {
        std::fputs(e.before.c_str(), stdout);
        throw;
    }
}

static const char *VAL_HELP =
    "usage: msid validate model.json frf.json [--weight cov|known-input|none] [--lpm-lines independent|all]\n"
    "                     [--format msid|touchstone|uff|csv|mat] [-o report.json]\n"
    "       msid validate multi-model.json --experiment r1.csv ... [--lags M] [-o report.json]\n"
    "The weighted residual cost of the model on the FRF data against its expectation, with a p-value,\n"
    "per-line normalised residuals, and a verdict at 5%. Models of --method multi (free responses too)\n"
    "are validated on time records: residual whiteness and cost (msid validate --experiment x --help).\n"
    "LPM files: neighbouring lines share 2W of their 2W+1 window bins, so the cost is summed over every\n"
    "(2W+1)-th line, which are independent (--lpm-lines all: every line, an optimistic p-value).\n"
    "An FRF measured by another tool (--format, or by its extension: msid import) is read as msid import\n"
    "reads it; without a covariance the unweighted cost is reported, with no p-value and no verdict.\n";

int cmd_validate(int argc, char **argv)
{
    if (validate_on_records(argc, argv)) return cmd_validate_multi(argc, argv);   // time records (cmd_fit_multi.cpp)
    Args a(argc, argv, 2, VAL_HELP, {"weight", "output", "lpm-lines", "format"}, {});
    if (a.positional().size() != 2) throw UsageError("give a model file and an FRF file");
    try {
        const ModelFile mf = read_model(a.positional()[0]);
        msidfitjob::check_model_has_frf(mf);
        const Json frf_doc = msidfrfimport::load_document(a.positional()[1], a.get("format"));
        const FrfData f = msidfrf::parse_frf(frf_doc, a.positional()[1]);
        msidfitjob::ValidateRequest rq;
        if (a.has("weight")) rq.weight = a.enum_<Weight>("weight", Weight::Cov, WEIGHTS);
        if (a.has("lpm-lines")) rq.lpm_lines = a.get("lpm-lines");
        const msidfitjob::ValidateOutcome v = msidfitjob::validate_frf(mf, f, frf_doc, rq);
        for (const std::string &line : v.text) std::printf("%s\n", line.c_str());
        if (a.has("output")) write_json_file(a.get("output"), v.report, false);
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

int cmd_compare(int argc, char **argv)
{
    static const char *HELP = "usage: msid compare model.json reference.json [-o out.json]\n"
                              "Relative H2 and Hinf distance ||model - reference|| / ||reference||.\n";
    Args a(argc, argv, 2, HELP, {"output"}, {});
    if (a.positional().size() != 2) throw UsageError("give two model files (the second is the reference)");
    try {
        const ModelFile m1 = read_model(a.positional()[0]), m2 = read_model(a.positional()[1]);
        const Distance dd = ss_distance(m1.ss, m2.ss);
        if (!(dd.h2_ref > 0) || !(dd.hinf_ref > 0) || !std::isfinite(dd.h2_ref) || !std::isfinite(dd.hinf_ref))
            throw Error(fmt("'%s': the reference's H2 norm is %g and its Hinf norm %g: relative distances need a "
                            "reference with finite, non-zero norms", m2.path.c_str(), dd.h2_ref, dd.hinf_ref));
        std::printf("relative H2 distance %.6g, relative Hinf distance %.6g (reference H2 %.6g, Hinf %.6g)\n", dd.h2,
                    dd.hinf, dd.h2_ref, dd.hinf_ref);
        if (a.has("output"))
            write_json_file(a.get("output"), Json{{"format", "msid-compare/1"}, {"model", m1.path}, {"reference", m2.path},
                                                   {"h2_rel", dd.h2}, {"hinf_rel", dd.hinf}, {"h2_ref", dd.h2_ref},
                                                   {"hinf_ref", dd.hinf_ref}}, false);
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

}  // namespace msidcli
