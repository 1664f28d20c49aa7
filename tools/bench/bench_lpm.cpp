// msid bench lpm: the local polynomial method (tools/est) on a 2x2 record of 10^6 samples -- one
// FFT per channel plus the local LS at every bin -- with one and two threads, against the NumPy
// peer (tools/peers/msid_peers/lpm_peer.py) on the same samples in the same run; prints the
// agreement of the two estimates.
#include "bench_util.hpp"

#include "lpm.hpp"
#include "msid_host_util.hpp"
#include "msid_json_file.hpp"

#include <cmath>
#include <complex>
#include <cstdio>
#include <random>
#include <unistd.h>

namespace msidbench {

using msidfmt::Json;

namespace {

constexpr unsigned NU = 2, NY = 2, C = NU + NY;

// A 2x2 plant of second-order sections (pole radius 0.95), white inputs, white output noise: N rows of C.
std::vector<double> simulate(size_t N)
{
    std::vector<double> rows(N * C);
    std::mt19937_64 g(7);
    std::normal_distribution<double> nd;
    double st[2][2][2] = {};
    for (size_t t = 0; t < N; ++t) {
        double *r = &rows[t * C];
        r[0] = nd(g);
        r[1] = nd(g);
        for (unsigned i = 0; i < NY; ++i) {
            double y = 0;
            for (unsigned j = 0; j < NU; ++j) {
                const double rr = 0.95, th = 0.3 + 0.4 * i + 0.7 * j, x = r[j];
                const double o = 0.1 * x + st[i][j][0];
                st[i][j][0] = 2 * rr * std::cos(th) * o + st[i][j][1];
                st[i][j][1] = -rr * rr * o;
                y += o;
            }
            r[NU + i] = y + 0.1 * nd(g);
        }
    }
    return rows;
}

// The peer's result on the same samples, or an empty document with `out` holding what it printed.
Json run_peer(const std::vector<double> &rows, size_t N, const msidest::LpmResult &res, std::string &out)
{
    const std::string dir = temp_dir("msid-bench-lpm"), file = dir + "/rec.f64";
    {
        FILE *f = std::fopen(file.c_str(), "wb");
        if (!f || std::fwrite(rows.data(), sizeof(double), rows.size(), f) != rows.size())
            throw msidutil::Error("cannot write " + file);
        std::fclose(f);
    }
    const std::string cmd = "python3 '" + peers_dir() + "/msid_peers/lpm_peer.py' '" + file + "' " + std::to_string(N) +
                            " 2 2 " + std::to_string(res.R) + " " + std::to_string(res.W) + " 2>&1";
    const int rc = capture(cmd, out);
    std::remove(file.c_str());
    rmdir(dir.c_str());
    try {
        if (rc != 0) throw std::runtime_error("exit status");
        return Json::parse(out);
    } catch (const std::exception &) {
        return Json();
    }
}

// Agreement at the bins the peer returns (every 1000th): max |G_msid - G_peer| / |G_peer|.
double max_rel_diff(const Json &pj, const msidest::LpmResult &res)
{
    double worst = 0;
    const auto &bins = pj["bins"], &gr = pj["G_re"], &gi = pj["G_im"];
    for (size_t b = 0; b < bins.size(); ++b) {
        const size_t bi = bins[b].get<size_t>() - res.bins[0];
        for (unsigned t = 0; t < NU * NY; ++t) {
            const std::complex<double> gp(gr[b * 4 + t].get<double>(), gi[b * 4 + t].get<double>());
            worst = std::max(worst, std::abs(res.G[bi * 4 + t] - gp) / std::abs(gp));
        }
    }
    return worst;
}

}  // namespace

LpmBenchResult bench_lpm(const LpmBenchRequest &rq, const Sink &sink)
{
    if (rq.samples < 64 || rq.runs < 1) throw msidutil::UsageError("--samples must be >= 64 and --runs >= 1");
    LpmBenchResult out;
    Writer w(sink, out.report);
    const size_t N = rq.samples;
    const std::vector<double> rows = simulate(N);
    std::vector<msidest::RecordView> views{{rows.data(), N, C}};
    msidest::LpmConfig cfg;
    msidest::LpmResult res;
    // wall time, and the CPU time of the process (the machine may be shared: CPU time shows the work)
    double best[3] = {1e300, 1e300, 1e300}, cpu[3] = {1e300, 1e300, 1e300};
    for (unsigned th = 1; th <= 2; ++th)
        for (unsigned k = 0; k < rq.runs; ++k) {
            cfg.threads = th;
            const double t0 = wall_s(), c0 = process_cpu_s();
            const auto S = msidest::record_spectra(views, NU, NY);
            const double t1 = wall_s(), c1 = process_cpu_s();
            res = msidest::lpm(S, cfg);
            const double t2 = wall_s(), c2 = process_cpu_s();
            best[th] = std::min(best[th], t2 - t0);
            cpu[th] = std::min(cpu[th], c2 - c0);
            if (th == 1) best[0] = std::min(best[0], t1 - t0), cpu[0] = std::min(cpu[0], c1 - c0);
        }
    out.wall_spectra_s = best[0], out.wall_1thread_s = best[1], out.wall_2threads_s = best[2];
    out.cpu_spectra_s = cpu[0], out.cpu_1thread_s = cpu[1], out.cpu_2threads_s = cpu[2];
    w.print("msid bench lpm  (msid %s)\nmachine: %s\n", MSID_VERSION, machine().c_str());
    w.print("data: 2x2, %zu samples, white inputs, R = %u, W = %u (2W+1 = %u bins), q = %u, %zu lines; "
            "best of %u runs\n\n",
            N, res.R, res.W, 2 * res.W + 1, res.q, res.bins.size(), rq.runs);
    w.print("  %-26s %9s   %9s\n", "", "wall", "cpu");
    w.print("  %-26s %9.3f s %9.3f s\n", "msid, 1 thread", best[1], cpu[1]);
    w.print("  %-26s %9.3f s %9.3f s\n", "msid, 2 threads", best[2], cpu[2]);
    w.print("  %-26s %9.3f s %9.3f s   (4 FFTs, FFTW estimate plans)\n", "  of which spectra", best[0], cpu[0]);
    if (!rq.peer) return out;
    std::string text;
    const Json pj = run_peer(rows, N, res, text);
    if (pj.is_null()) {
        w.print("  peer failed: %s\n", text.substr(0, 300).c_str());
        return out;
    }
    out.max_rel_diff = max_rel_diff(pj, res);
    const double tp = pj["sec"].get<double>(), cp = pj["cpu"].get<double>();
    out.peer_wall_s = tp, out.peer_cpu_s = cp;
    w.print("  %-26s %9.3f s %9.3f s   (numpy %s, batched numpy.linalg, best of 2)\n", "NumPy peer", tp, cp,
            pj["numpy"].get<std::string>().c_str());
    w.print("\n  msid is %.1fx (1 thread) / %.1fx (2 threads) faster in wall time, %.1fx in CPU time (1 thread);\n"
            "  max relative difference of G at %zu bins: %.2g\n",
            tp / best[1], tp / best[2], cp / cpu[1], pj["bins"].size(), out.max_rel_diff);
    return out;
}

}  // namespace msidbench
