// msid excite: design a multisine, write msid-design/1 and optional input CSVs.
#include "commands.hpp"
#include "host_libs.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <sys/stat.h>
#include <unistd.h>

namespace msidcli {

static const char *EXCITE_HELP =
    "usage: msid excite --period P (--lines L1,L2,a:b,... | --omega W1,W2,... --sample-time H)\n"
    "                   [--amplitudes A | A1,...,AL | nu*L values] [--phases random|schroeder] [--seed S]\n"
    "                   [--inputs NU] [--experiments M] [--pattern dft|hadamard] [--periods K]\n"
    "                   -o design.json [--csv DIR]\n"
    "\n"
    "  --period P        samples per period\n"
    "  --lines           excited DFT bins (0 < bin < P/2; 0 is a DC line); ranges a:b and a:step:b\n"
    "  --omega, --sample-time  continuous-time lines in rad/s sampled every H s; each line must complete\n"
    "                    a whole number of cycles in P*H; lines above Nyquist fold (aliasing is allowed)\n"
    "  --amplitudes      peak amplitude per line (one value for all), default 1\n"
    "  --phases          random (seeded, reproducible on every platform) or schroeder; default random\n"
    "  --inputs, --experiments  nu inputs and m >= nu experiments (default m = nu)\n"
    "  --pattern         phase pattern across experiments: dft (any m) or hadamard (m a power of 2)\n"
    "  --periods K       periods per experiment in the CSVs (default 8)\n"
    "  --csv DIR         write DIR/e1.csv .. DIR/e<m>.csv with columns u1..u<nu>\n";

int cmd_excite(int argc, char **argv)
{
    Args a(argc, argv, 2, EXCITE_HELP,
           {"period", "lines", "omega", "sample-time", "amplitudes", "phases", "seed", "inputs", "experiments",
            "pattern", "periods", "output", "csv"},
           {});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    DesignParams p;
    p.period = parse_u32(a.require("period"), "--period");
    if (a.has("lines") == a.has("omega")) throw UsageError("give either --lines (bins) or --omega with --sample-time");
    size_t L = 0;
    if (a.has("lines")) {
        if (a.has("sample-time")) throw UsageError("--sample-time goes with --omega, not --lines");
        p.bins = parse_uint_list(a.get("lines"), "--lines");
        L = p.bins.size();
    } else {
        p.omega = parse_double_list(a.get("omega"), "--omega");
        p.sample_time = parse_double(a.require("sample-time"), "--sample-time");
        L = p.omega.size();
    }
    p.n_inputs = a.u32("inputs", 1);
    p.n_experiments = a.u32("experiments", p.n_inputs);
    if (a.has("amplitudes")) {
        p.amplitudes = parse_double_list(a.get("amplitudes"), "--amplitudes");
        if (p.amplitudes.size() == 1) p.amplitudes.assign(L, p.amplitudes[0]);
        p.amp_per_input = p.amplitudes.size() == (size_t)p.n_inputs * L && p.n_inputs > 1;
    }
    p.phase_mode = a.enum_<msid_phase_mode>("phases", MSID_PHASE_RANDOM,
                                            {{"random", MSID_PHASE_RANDOM}, {"schroeder", MSID_PHASE_SCHROEDER}});
    p.seed = a.u64("seed", 1);
    p.pattern = a.enum_<msid_pattern>("pattern", MSID_PATTERN_DFT,
                                      {{"dft", MSID_PATTERN_DFT}, {"hadamard", MSID_PATTERN_HADAMARD}});
    p.periods = a.u32("periods", 8);
    if (p.periods == 0) throw UsageError("--periods must be at least 1");
    const std::string out = a.require("output");

    auto D = build_design(p);
    const msid_design &d = D->d;

    // Input CSVs: one per experiment, written to temporaries and renamed at the end.
    std::vector<std::pair<std::string, std::string>> files;
    std::string dir;
    if (a.has("csv")) {
        dir = a.get("csv");
        const size_t n = (size_t)p.periods * d.period, nu = d.n_inputs;
        if (n * nu > (size_t)1 << 31) throw Error("--periods * --period is too large for CSV output");
        std::vector<std::string> header;
        for (uint32_t i = 0; i < nu; ++i) header.push_back("u" + std::to_string(i + 1));
        std::vector<double> u(n * nu);
        for (uint32_t e = 0; e < d.n_experiments; ++e) {
            msid_gen_cfg gc{&d, &D->tw, e, 1};
            Mem gm(msid_gen_mem_size(&gc));
            msid_gen g;
            check(msid_gen_init(&g, &gc, gm.p, gm.n), "generator");
            msid_gen_block(&g, u.data(), n, nu);
            files.emplace_back(dir + "/e" + std::to_string(e + 1) + ".csv", format_csv(header, u.data(), n, nu));
        }
    }
    // Write everything or nothing (the CSV directory too, if we created it).
    std::vector<std::string> done;
    bool made_dir = false;
    try {
        if (!dir.empty()) {
            if (::mkdir(dir.c_str(), 0755) == 0) made_dir = true;
            else if (errno != EEXIST) throw Error("cannot create directory '" + dir + "': " + std::strerror(errno));
        }
        for (auto &f : files) { write_file_atomic(f.first, f.second); done.push_back(f.first); }
        write_json_file(out, design_to_json(*D));
    } catch (...) {
        for (auto &f : done) ::unlink(f.c_str());
        if (made_dir) ::rmdir(dir.c_str());
        throw;
    }
    std::printf("wrote %s: P=%u, %u lines, %u input(s) x %u experiment(s), max condition number %.4g\n", out.c_str(),
                d.period, d.n_lines, d.n_inputs, d.n_experiments, d.cond_max);
    for (uint32_t e = 0; e < d.n_experiments; ++e) {
        std::printf("  experiment %u crest factor:", e + 1);
        for (uint32_t i = 0; i < d.n_inputs; ++i) std::printf(" u%u %.3f", i + 1, msid_design_crest_factor(&d, e, i));
        std::printf("\n");
    }
    for (auto &f : files) std::printf("wrote %s (%u periods)\n", f.first.c_str(), p.periods);
    return 0;
}

}  // namespace msidcli
