// msid bench crest: the design's set-up time for large P -- crest factors by two real DFTs per
// input and experiment (MSID_CREST_FFT, O(m nu P log P)) against direct synthesis
// (MSID_CREST_DIRECT, O(m nu P L)) and a NumPy peer (tools/peers/msid_peers/crest_peer.py: one
// irfft per input) on the same coefficients in the same run; reports the agreement of the crest
// factors.
#include "bench_util.hpp"

#include "msid_host_util.hpp"
#include "msid_json_file.hpp"

extern "C" {
#include "msid/msid_fft_fftw.h"
}

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <unistd.h>

namespace msidbench {

using msidfmt::Json;
using msidutil::check;
using msidutil::fmt;
using msidutil::Mem;

namespace {

struct Setup {
    uint32_t P, L, nu = 2, m = 2;
    std::vector<uint32_t> bins;
    Mem mtw;
    msid_twiddle tw{};
    explicit Setup(uint32_t P_, uint32_t L_) : P(P_), L(L_)
    {
        for (uint32_t l = 0; l < L; ++l) bins.push_back(1 + l * ((P / 2 - 2) / L));   // spread below Nyquist
        mtw = Mem(msid_twiddle_mem_size(P));
        check(msid_twiddle_init(&tw, P, mtw.p, mtw.n), "twiddle table");
    }
    // One msid_design_init with the given crest mode: (wall, cpu) seconds; the design kept in d/mem.
    std::pair<double, double> init(msid_crest_mode mode, msid_design &d, Mem &mem) const
    {
        msid_design_cfg c{};
        c.period = P;
        c.n_lines = L;
        c.bins = bins.data();
        c.phase_mode = MSID_PHASE_SCHROEDER;
        c.n_inputs = nu;
        c.n_experiments = m;
        c.twiddle = &tw;
        c.crest = mode;
        msid_fft_fftw f{};
        if (mode == MSID_CREST_FFT) {
            check(msid_fft_fftw_create(&f, P, MSID_FFTW_ESTIMATE), "FFTW plan");
            c.fft = &f.be;
        }
        mem = Mem(msid_design_mem_size(&c));
        const double t0 = wall_s(), c0 = process_cpu_s();
        const msid_status st = msid_design_init(&d, &c, mem.p, mem.n);
        const std::pair<double, double> t{wall_s() - t0, process_cpu_s() - c0};
        if (mode == MSID_CREST_FFT) msid_fft_fftw_destroy(&f);
        check(st, "design");
        return t;
    }
};

// The NumPy peer on the design's coefficients: "wall / cpu" into `sP`, the largest relative
// difference of its crest factors into `diffP`.
void run_peer(const Setup &S, const msid_design &dF, std::string &sP, std::string &diffP)
{
    char tmpl[] = "/tmp/msid-bench-crest-XXXXXX";
    const int fd = mkstemp(tmpl);
    if (fd < 0) throw msidutil::Error("cannot create a temporary file");
    FILE *f = fdopen(fd, "wb");
    std::fwrite(S.bins.data(), sizeof(uint32_t), S.L, f);
    for (uint32_t e = 0; e < S.m; ++e)
        for (uint32_t i = 0; i < S.nu; ++i)
            for (uint32_t l = 0; l < S.L; ++l) {
                const msid_cplx c = msid_design_coef(&dF, e, i, l);
                std::fwrite(&c, sizeof c, 1, f);
            }
    std::fclose(f);
    const std::string pydir = peers_dir();
    const std::string cmd = fmt("python3 '%s/msid_peers/crest_peer.py' '%s' %u %u %u %u 2>&1", pydir.c_str(), tmpl, S.P,
                                S.L, S.m, S.nu);
    std::string out;
    const int rc = capture(cmd, out);
    std::remove(tmpl);
    try {
        if (rc != 0) throw std::runtime_error("exit status");
        const Json pj = Json::parse(out);
        double w = 0;
        for (uint32_t k = 0; k < S.m * S.nu; ++k) w = std::max(w, std::fabs(dF.crest[k] / pj["crest"][k].get<double>() - 1));
        diffP = fmt("%.1e", w);
        sP = fmt("%8.4f / %8.4f", pj["sec"].get<double>(), pj["cpu"].get<double>());
    } catch (const std::exception &) {
        sP = "(peer failed: " + out.substr(0, 60) + ")";
    }
}

// One period: the FFT set-up, the direct one up to `direct_max`, the peer; its row of the table.
CrestBenchRow crest_row(Writer &w, const CrestBenchRequest &rq, uint32_t P)
{
    const uint32_t L = std::min<uint32_t>(1000, P / 2 - 2);
    const Setup S(P, L);
    msid_design dF{}, dD{};
    Mem mF, mD;
    const auto tF = S.init(MSID_CREST_FFT, dF, mF);
    std::string sD = "(skipped)", diffD = "-", diffP = "-", sP = "(no peer)";
    if (P <= rq.direct_max) {
        const auto tD = S.init(MSID_CREST_DIRECT, dD, mD);
        sD = fmt("%8.4f / %8.4f", tD.first, tD.second);
        double d = 0;
        for (uint32_t k = 0; k < S.m * S.nu; ++k) d = std::max(d, std::fabs(dF.crest[k] / dD.crest[k] - 1));
        diffD = fmt("%.1e", d);
    }
    if (rq.peer) run_peer(S, dF, sP, diffP);
    w.print("  %8u %6u | %8.4f / %8.4f | %19s | %19s | %s, %s\n", P, L, tF.first, tF.second, sD.c_str(), sP.c_str(),
            diffD.c_str(), diffP.c_str());
    CrestBenchRow row;
    row.period = P;
    row.lines = L;
    row.fft_wall_s = tF.first;
    row.fft_cpu_s = tF.second;
    return row;
}

}  // namespace

CrestBenchResult bench_crest(const CrestBenchRequest &rq, const Sink &sink)
{
    CrestBenchResult res;
    Writer w(sink, res.report);
    const uint32_t top = rq.quick ? 16 : 22;
    w.print("msid bench crest  (msid %s)\nmachine: %s\n", MSID_VERSION, machine().c_str());
    w.print("design: 2 inputs, 2 experiments, Schroeder phases, 1000 lines (P/2 - 1 if fewer); one run each\n\n");
    w.print("  %8s %6s | %-19s | %-19s | %-19s | %s\n", "P", "lines", "msid FFT wall/cpu", "msid direct wall/cpu",
            "NumPy irfft wall/cpu", "max rel. diff (FFT vs direct, vs NumPy)");
    for (uint32_t e2 = 12; e2 <= top; e2 += 2) res.rows.push_back(crest_row(w, rq, 1u << e2));
    return res;
}

}  // namespace msidbench
