// msid frf: experiment CSVs -> msid-frf/1.
#include "commands.hpp"
#include "frf_io.hpp"
#include "periodicity.hpp"
#include "pipeline.hpp"

#include <cstdio>
#include <cstring>

namespace msidcli {

static const char *HELP =
    "usage: msid frf (--design design.json | --period P|auto --lines L1,L2,...|auto) --experiment e1.csv\n"
    "                [--experiment e2.csv ...] [--columns u1=NAME,y1=NAME,...] [--skip-periods K] [--fs HZ]\n"
    "                [--detect-lines D1,...] [--transient flag|drop|off] [--alpha A] [--dft auto|stream|fft]\n"
    "                -o frf.json\n"
    "\n"
    "  --design          take period, lines (and CT frequencies) from an msid-design/1 file\n"
    "  --period, --lines samples per period and excited DFT bins (ranges a:b, a:step:b)\n"
    "  --period auto     find the period from the input's repetition (says so when there is none)\n"
    "  --lines auto      find the excited bins from the input spectrum (F test, 1% family-wise false\n"
    "                    alarm; the bins are printed)\n"
    "  --experiment      one record per experiment (m >= nu files), periods back to back, one sample\n"
    "                    per row: CSV (',', ';' or tab; header u1..u<nu>, y1..y<ny>, optional time\n"
    "                    column), NumPy .npy/.npz or MATLAB .mat (v5, v7.3); see README \"CSV records\"\n"
    "  --columns         map named columns (or .mat/.npz variables, 'name:k' for matrix column k)\n"
    "                    to u1.., y1..; other columns are ignored\n"
    "  --skip-periods K  ignore the first K periods of every experiment (plant transient)\n"
    "  --fs HZ           sample rate, adds freq_hz to every line\n"
    "  --detect-lines    non-excited bins to report (noise level, nonlinear distortion test)\n"
    "  --transient       test every period against the others: flag (report, default), drop, off\n"
    "  --alpha A         false-alarm probability of that test per experiment (default 0.01)\n"
    "  --dft             line DFT path: auto (default), stream, fft\n"
    "  --direct          direct time-domain LS FRF (Gonzalez et al. 2025 eq. 19-23): records need not be\n"
    "                    whole periods; needs --design; exact covariance Sigma kron Z^-1 with Sigma from the\n"
    "                    residuals, plus the pseudo-covariance pcov of each line\n";

int cmd_frf(int argc, char **argv)
{
    for (int i = 2; i < argc; ++i)
        if (!std::strcmp(argv[i], "--help")) { std::fputs(HELP, stdout); return 0; }
    Args a(argc, argv, 2,
           {"design", "period", "lines", "skip-periods", "fs", "detect-lines", "transient", "alpha", "dft", "block",
            "output", "columns"},
           {"direct"}, {"experiment"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "' (use --experiment)");
    const std::string out = a.require("output");
    FrfRequest rq;
    std::unique_ptr<Design> D;
    if (a.has("design")) {
        if (a.has("period") || a.has("lines")) throw UsageError("give either --design or --period/--lines, not both");
        D = read_design_file(a.get("design"));
        request_from_design(rq, *D);
    } else {
        if (!a.has("period") || !a.has("lines")) throw UsageError("give --design, or both --period and --lines");
        if (a.get("period") != "auto") rq.period = parse_u32(a.get("period"), "--period");
        if (a.get("lines") != "auto") rq.bins = parse_uint_list(a.get("lines"), "--lines");
    }
    const bool auto_period = !D && a.get("period") == "auto", auto_lines = !D && a.get("lines") == "auto";
    if ((auto_period || auto_lines) && a.has("direct")) throw UsageError("--direct needs --design (no auto period/lines)");
    if (a.has("fs")) {
        rq.fs = parse_double(a.get("fs"), "--fs");
        if (!(rq.fs > 0)) throw UsageError("--fs must be positive");
        if (D && D->is_ct()) throw UsageError("--fs does not apply to a continuous-time design (it has a sample time)");
    }
    parse_estimate_options(a, rq);
    const std::string dp = a.get("dft", "auto");
    if (dp == "auto") rq.path = MSID_DFT_AUTO;
    else if (dp == "stream") rq.path = MSID_DFT_STREAM;
    else if (dp == "fft") rq.path = MSID_DFT_FFT;
    else throw UsageError("--dft must be auto, stream or fft (got '" + dp + "')");
    if (a.has("block")) {
        rq.block = parse_u64(a.get("block"), "--block");
        if (rq.block == 0) throw UsageError("--block must be positive");
    }
    if (a.all("experiment").empty()) throw UsageError("missing --experiment <file.csv>");

    const ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns")) : ColumnMap{};
    std::vector<Record> recs;
    for (const auto &p : a.all("experiment")) recs.push_back(read_experiment(p, cols, true));   // read via data()
    if (!a.has("direct")) check_records(rq, recs);
    if (auto_period) {
        std::string rep;
        rq.period = find_period(recs, rep);
        std::printf("--period auto: %s\n", rep.c_str());
    }
    if (!a.has("direct") && rq.period >= MSID_MIN_PERIOD && rq.period <= MSID_MAX_PERIOD)
        check_periodic_inputs(rq.period, rq.skip, rq.bins, recs);
    if (auto_lines) {
        std::string rep;
        rq.bins = find_lines(recs, rq.period, rq.skip, rep);
        std::printf("--lines auto: %s:\n  %s\n", rep.c_str(), format_bins(rq.bins).c_str());
    }
    if (a.has("direct")) {
        if (!D) throw UsageError("--direct needs --design (the input is the design's exact multisine)");
        for (const char *k : {"detect-lines", "dft", "block", "transient", "alpha"})
            if (a.has(k)) throw UsageError(std::string("--") + k + " does not apply to --direct");
    }
    FrfOutcome o = a.has("direct") ? run_frf_direct(rq, *D, recs) : run_frf(rq, recs);
    write_json_file(out, o.doc);
    for (const auto &n : o.notes) std::fprintf(stderr, "msid frf: note: %s\n", n.c_str());
    std::printf("wrote %s: %zu lines, %u output(s) x %u input(s), %zu experiment(s), %llu periods used, %llu rejected "
                "(%s)\n",
                out.c_str(), rq.bins.size(), recs[0].ny, recs[0].nu, recs.size(),
                (unsigned long long)o.doc["periods_used"].get<uint64_t>(),
                (unsigned long long)o.doc["periods_rejected"].get<uint64_t>(), o.dft_path.c_str());
    return 0;
}

}  // namespace msidcli
