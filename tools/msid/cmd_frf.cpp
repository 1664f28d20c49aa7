// msid frf: experiment CSVs -> msid-frf/1.
#include "commands.hpp"
#include "frf_io.hpp"
#include "pipeline.hpp"
#include "frf_bla.hpp"

#include <cstdio>
#include <cstring>

namespace msidcli {

static const char *HELP =
    "usage: msid frf (--design design.json | --period P --lines L1,L2,...) --experiment e1.csv\n"
    "                [--experiment e2.csv ...] [--skip-periods K] [--fs HZ] [--detect-lines D1,...]\n"
    "                [--transient flag|drop|off] [--alpha A] [--dft auto|stream|fft] -o frf.json\n"
    "\n"
    "  --design          take period, lines (and CT frequencies) from an msid-design/1 file\n"
    "  --period, --lines samples per period and excited DFT bins (ranges a:b, a:step:b)\n"
    "  --experiment      CSV with header u1..u<nu>, y1..y<ny> (optional time column); one row per\n"
    "                    sample, periods back to back; one file per experiment, m >= nu files\n"
    "  --skip-periods K  ignore the first K periods of every experiment (plant transient)\n"
    "  --fs HZ           sample rate, adds freq_hz to every line\n"
    "  --detect-lines    non-excited bins to report (noise level, nonlinear distortion test)\n"
    "  --transient       test every period against the others: flag (report, default), drop, off\n"
    "  --alpha A         false-alarm probability of that test per experiment (default 0.01)\n"
    "  --dft             line DFT path: auto (default), stream, fft\n"
    "  --direct          direct time-domain LS FRF (Gonzalez et al. 2025 eq. 19-23): records need not be\n"
    "                    whole periods; needs --design; exact covariance Sigma kron Z^-1 with Sigma from the\n"
    "                    residuals, plus the pseudo-covariance pcov of each line\n"
    "  --realisations R  the experiments are R blocks of equal size, one per random-phase realisation: the\n"
    "                    FRF is the best linear approximation (mean over realisations), cov its total\n"
    "                    covariance (noise + nonlinear distortion, dof R-1), cov_noise the noise part\n"
    "                    (robust method, Pintelon & Schoukens 2012 sec. 4.3.1; docs/statistics.md)\n";

int cmd_frf(int argc, char **argv)
{
    for (int i = 2; i < argc; ++i)
        if (!std::strcmp(argv[i], "--help")) { std::fputs(HELP, stdout); return 0; }
    Args a(argc, argv, 2,
           {"design", "period", "lines", "skip-periods", "fs", "detect-lines", "transient", "alpha", "dft", "block",
            "output", "realisations"},
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
        rq.period = parse_u32(a.get("period"), "--period");
        rq.bins = parse_uint_list(a.get("lines"), "--lines");
    }
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

    std::vector<Record> recs;
    for (const auto &p : a.all("experiment")) recs.push_back(read_record_csv(p));
    if (a.has("direct")) {
        if (!D) throw UsageError("--direct needs --design (the input is the design's exact multisine)");
        for (const char *k : {"detect-lines", "dft", "block", "transient", "alpha"})
            if (a.has(k)) throw UsageError(std::string("--") + k + " does not apply to --direct");
    }
    const uint32_t R = a.has("realisations") ? parse_u32(a.get("realisations"), "--realisations") : 1;
    if (a.has("realisations") && a.has("direct")) throw UsageError("--realisations does not apply to --direct");
    FrfOutcome o = a.has("direct") ? run_frf_direct(rq, *D, recs)
                   : a.has("realisations") ? run_frf_realisations(rq, recs, R)   // BLA + noise/distortion split
                                           : run_frf(rq, recs);
    if (!a.has("realisations") && !a.has("direct")) {
        const Json nl = detection_distortion(o.doc);   // one realisation: level from the detection lines
        if (!nl.is_null()) {
            o.doc["nonlinear_distortion"] = nl;
            if (nl["distortion_detected"].get<bool>())
                o.notes.push_back("the detection lines show nonlinear distortion (" +
                                  (nl["nl_to_noise_db"].is_number() ? fmt("%.1f dB", nl["nl_to_noise_db"].get<double>()) : std::string("?")) +
                                  " relative to the noise); cov holds the noise only: measure several realisations "
                                  "(--realisations R) to include it");
        }
    }
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
