// msid frf: experiment CSVs -> msid-frf/1.
#include "commands.hpp"
#include "host_libs.hpp"
#include "msid_candump_dbc.hpp"

#include <cstdio>
#include <cstring>
#include <memory>

namespace msidcli {

static const char *FRF_HELP =
    "usage: msid frf (--design design.json | --period P|auto --lines L1,L2,...|auto) --experiment e1.csv\n"
    "                [--experiment e2.csv ...] [--columns u1=NAME,y1=NAME,...] [--skip-periods K] [--fs HZ]\n"
    "                [--detect-lines D1,...] [--transient flag|drop|off] [--alpha A] [--dft auto|stream|fft]\n"
    "                [--reference r1=COL,...] -o frf.json\n"
    "       msid frf --dbc FILE.dbc --columns u1=MSG.SIG,...,y1=MSG.SIG,... --experiment run.log ... -o frf.json\n"
    "\n"
    "  --design          take period, lines (and CT frequencies) from an msid-design/1 file\n"
    "  --period, --lines samples per period and excited DFT bins (ranges a:b, a:step:b)\n"
    "  --period auto     find the period from the input's repetition (says so when there is none)\n"
    "  --lines auto      find the excited bins from the input spectrum (F test, 1% family-wise false\n"
    "                    alarm; the bins are printed, and the bins of the excitation's grid where the input\n"
    "                    is too weak to decide are named)\n"
    "  --reference r1=COL,...  with --lines auto: find the bins from the excitation's reference (the\n"
    "                    generator's signal, one column per input) instead of the inputs; a CSV whose\n"
    "                    header has r1.. is used so without asking\n"
    "  --experiment      one record per experiment (m >= nu files), periods back to back, one sample\n"
    "                    per row: CSV (',', ';' or tab; header u1..u<nu>, y1..y<ny>, optional time\n"
    "                    column), NumPy .npy/.npz or MATLAB .mat (v5, v7.3); see docs/records.md\n"
    "  --columns         map named columns (or .mat/.npz variables, 'name:k' for matrix column k)\n"
    "                    to u1.., y1..; other columns are ignored\n"
    "  --dbc FILE        the experiments are candump .log files whose frames FILE describes; --columns\n"
    "                    names MESSAGE.SIGNAL for each of u1.., y1..; one row per frame of u1's message, other\n"
    "                    messages' signals at their latest value; lost frames are NaN rows, whose periods are\n"
    "                    rejected and counted, never interpolated (docs/can-protocol.md)\n"
    "  --skip-periods K  ignore the first K periods of every experiment (plant transient)\n"
    "  --fs HZ           sample rate, adds freq_hz to every line\n"
    "  --detect-lines    non-excited bins to report (noise level, nonlinear distortion test)\n"
    "  --transient       test every period against the others: flag (report, default), drop, off\n"
    "  --alpha A         false-alarm probability of that test per experiment (default 0.01)\n"
    "  --dft             line DFT path: auto (default), stream, fft\n"
    "  --direct          direct time-domain LS FRF (Gonzalez et al. 2025 eq. 19-23): records need not be\n"
    "                    whole periods; needs --design; exact covariance Sigma kron Z^-1 with Sigma from the\n"
    "                    residuals, plus the pseudo-covariance pcov of each line\n"
    "  --method          periodic (default, this estimator), lpm or etfe for records that are not\n"
    "                    steady-state multisines (msid frf --method lpm --help)\n"
    "  --realisations R  the experiments are R blocks of equal size, one per random-phase realisation: the\n"
    "                    FRF is the best linear approximation (mean over realisations), cov its total\n"
    "                    covariance (noise + nonlinear distortion, dof R-1), cov_noise the noise part\n"
    "                    (robust method, Pintelon & Schoukens 2012 sec. 4.3.1; docs/statistics.md). One period\n"
    "                    per realisation (the benchmark layout): the BLA and its total covariance only\n"
    "                    (R >= ny nu + 1); the noise part is not estimated and a note says so\n";

// --dbc: every experiment is a candump log decoded with the DBC (msidrec::read_record_candump), then the
// FRF job on those records; what the reader counted (lost frames, ...) leads the notes.
static msidjob::FilesOutcome estimate_frf_dbc(const Args &a, FrfRequest &rq, const ColumnMap &cols,
                                              const msidjob::FrfPlan &plan)
{
    if (a.has("reference")) throw UsageError("--reference does not apply to --dbc");
    const msidrec::DbcFile dbc(a.get("dbc"));
    msidjob::FilesOutcome fo;
    std::vector<std::string> notes;
    for (const std::string &p : a.all("experiment")) fo.recs.push_back(msidrec::read_record_candump(p, dbc, cols, notes));
    fo.o = msidjob::estimate_frf(rq, fo.recs, plan);
    fo.o.notes.insert(fo.o.notes.begin(), notes.begin(), notes.end());
    fo.nu = fo.recs[0].nu;
    fo.ny = fo.recs[0].ny;
    fo.m = (uint32_t)fo.recs.size();
    return fo;
}

int cmd_frf(int argc, char **argv)
{
    for (int i = 2; i < argc; ++i)   // --method lpm|etfe: arbitrary records (cmd_frf_est.cpp)
        if ((!std::strcmp(argv[i], "--method") && i + 1 < argc && std::strcmp(argv[i + 1], "periodic")) ||
            (!std::strncmp(argv[i], "--method=", 9) && std::strcmp(argv[i] + 9, "periodic")))
            return cmd_frf_est(argc, argv);
    Args a(argc, argv, 2, FRF_HELP,
           {"design", "period", "lines", "skip-periods", "fs", "detect-lines", "transient", "alpha", "dft", "block",
            "output", "method", "columns", "realisations", "reference", "dbc"},
           {"direct"}, {"experiment"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "' (use --experiment)");
    const std::string out = a.require("output");
    FrfRequest rq;
    // the options as given; their rules (a design or the period and lines, what --direct takes, the
    // ranges) are the job's (msidjob::check_plan), checked before anything is read
    msidjob::FrfPlan plan;
    for (const char *k : {"design", "period", "lines", "fs", "detect-lines", "transient", "alpha", "dft", "block",
                          "realisations", "direct", "reference"})
        if (a.has(k)) plan.given.names.push_back(msidutil::option_id(k));
    plan.auto_period = !a.has("design") && a.get("period") == "auto";
    plan.auto_lines = !a.has("design") && a.get("lines") == "auto";
    plan.direct = a.has("direct");
    plan.bla = a.has("realisations");
    plan.realisations = a.u32("realisations", 1);
    if (a.has("period") && a.get("period") != "auto") rq.period = a.u32("period", 0);
    if (a.has("lines") && a.get("lines") != "auto") rq.bins = parse_uint_list(a.get("lines"), "--lines");
    if (a.has("fs")) rq.fs = a.f64("fs", 0.0);
    parse_estimate_options(a, rq);
    rq.path = a.enum_<msid_dft_path>("dft", MSID_DFT_AUTO,
                                     {{"auto", MSID_DFT_AUTO}, {"stream", MSID_DFT_STREAM}, {"fft", MSID_DFT_FFT}});
    rq.block = a.u64("block", 0);
    msidjob::check_plan(rq, plan);
    std::unique_ptr<Design> D;
    if (a.has("design")) {
        D = read_design_file(a.get("design"));
        request_from_design(rq, *D);
        plan.design = D.get();
    }
    const bool auto_lines = plan.auto_lines;
    if (a.all("experiment").empty()) throw UsageError("missing --experiment <file.csv>");

    const ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns")) : ColumnMap{};
    if (!a.has("dbc"))
        for (const std::string &p : a.all("experiment")) msidrec::refuse_candump_without_dbc(p);
    // FFTW's first plan (the planner's own set-up, far dearer than later plans) on another thread
    // while the files are read (msid_fftw_planner.hpp);
    // the line DFT path does not depend on the channel count (msid_linedft_choose)
    if (!a.has("direct") && rq.period >= MSID_MIN_PERIOD && rq.period <= MSID_MAX_PERIOD && rq.path != MSID_DFT_STREAM &&
        (auto_lines || rq.path == MSID_DFT_FFT ||
         msid_linedft_choose(rq.period, (uint32_t)(rq.bins.size() + rq.detect.size()), 1, 1) == MSID_DFT_FFT))
        fftw_warmup_start(rq.period);
    // --lines auto from the excitation's reference: named, or the file's own r1.. columns
    if (a.has("reference")) plan.reference = parse_reference(a.get("reference"));
    plan.report = [](const std::string &s) { std::fputs(s.c_str(), stdout); };
    msidjob::FilesOutcome fo = a.has("dbc") ? estimate_frf_dbc(a, rq, cols, plan)
                                            : msidjob::estimate_frf_files(rq, a.all("experiment"), cols, plan);
    FrfOutcome &o = fo.o;
    // no fsync: the file is reproduced by running msid frf again on the same files
    // (msid measure, whose samples are gone after the run, keeps it)
    msidjob::write_outcome(out, o, false);
    for (const auto &n : o.notes) std::fprintf(stderr, "msid frf: note: %s\n", n.c_str());
    std::printf("wrote %s: %zu lines, %u output(s) x %u input(s), %zu experiment(s), %llu periods used, %llu rejected "
                "(%s)\n",
                out.c_str(), rq.bins.size(), fo.ny, fo.nu, (size_t)fo.m,
                (unsigned long long)o.periods_used(), (unsigned long long)o.periods_rejected(), o.dft_path.c_str());
    return 0;
}

}  // namespace msidcli
