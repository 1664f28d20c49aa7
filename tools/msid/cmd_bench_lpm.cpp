// msid bench lpm: the local polynomial method (tools/est) on a 2x2 record of
// 10^6 samples -- one FFT per channel plus the local LS at every bin -- with one
// and two threads, against the NumPy peer (tools/peers/msid_peers/lpm_peer.py) on the
// same samples in the same run; prints the agreement of the two estimates.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "lpm.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <random>
#include <unistd.h>

namespace msidcli {

static double seconds_now()
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int cmd_bench_lpm(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid bench lpm [--samples N] [--runs K] [--no-peer]\n"
        "Times `msid frf --method lpm` without file I/O (FFTW spectra + local LS at every bin,\n"
        "R = 2, default window) on a simulated 2x2 record of N samples (default 10^6), best of K\n"
        "runs (default 3) with 1 and 2 threads, and the NumPy peer on the same samples.\n";
    Args a(argc, argv, 3, HELP, {"samples", "runs"}, {"no-peer"});
    const size_t N = a.u64("samples", 1000000);
    const unsigned runs = a.u32("runs", 3);
    if (N < 64 || runs < 1) throw UsageError("--samples must be >= 64 and --runs >= 1");
    const unsigned nu = 2, ny = 2, C = nu + ny;
    // 2x2 plant of second-order sections (pole radius 0.95), white inputs, white output noise
    std::vector<double> rows(N * C);
    std::mt19937_64 g(7);
    std::normal_distribution<double> nd;
    double st[2][2][2] = {};
    for (size_t t = 0; t < N; ++t) {
        double *r = &rows[t * C];
        r[0] = nd(g);
        r[1] = nd(g);
        for (unsigned i = 0; i < ny; ++i) {
            double y = 0;
            for (unsigned j = 0; j < nu; ++j) {
                const double rr = 0.95, th = 0.3 + 0.4 * i + 0.7 * j, x = r[j];
                const double o = 0.1 * x + st[i][j][0];
                st[i][j][0] = 2 * rr * std::cos(th) * o + st[i][j][1];
                st[i][j][1] = -rr * rr * o;
                y += o;
            }
            r[nu + i] = y + 0.1 * nd(g);
        }
    }
    std::vector<msidest::RecordView> views{{rows.data(), N, C}};
    msidest::LpmConfig cfg;
    msidest::LpmResult res;
    // wall time, and the CPU time of the process (the machine may be shared: CPU time shows the work)
    double best[3] = {1e300, 1e300, 1e300}, cpu[3] = {1e300, 1e300, 1e300};
    for (unsigned th = 1; th <= 2; ++th)
        for (unsigned k = 0; k < runs; ++k) {
            cfg.threads = th;
            const double t0 = seconds_now(), c0 = (double)std::clock() / CLOCKS_PER_SEC;
            const auto S = msidest::record_spectra(views, nu, ny);
            const double t1 = seconds_now(), c1 = (double)std::clock() / CLOCKS_PER_SEC;
            res = msidest::lpm(S, cfg);
            const double t2 = seconds_now(), c2 = (double)std::clock() / CLOCKS_PER_SEC;
            best[th] = std::min(best[th], t2 - t0);
            cpu[th] = std::min(cpu[th], c2 - c0);
            if (th == 1) best[0] = std::min(best[0], t1 - t0), cpu[0] = std::min(cpu[0], c1 - c0);
        }
    std::printf("msid bench lpm  (msid %s)\nmachine: %s\n", MSID_VERSION, bench_machine().c_str());
    std::printf("data: 2x2, %zu samples, white inputs, R = %u, W = %u (2W+1 = %u bins), q = %u, %zu lines; "
                "best of %u runs\n\n",
                N, res.R, res.W, 2 * res.W + 1, res.q, res.bins.size(), runs);
    std::printf("  %-26s %9s   %9s\n", "", "wall", "cpu");
    std::printf("  %-26s %9.3f s %9.3f s\n", "msid, 1 thread", best[1], cpu[1]);
    std::printf("  %-26s %9.3f s %9.3f s\n", "msid, 2 threads", best[2], cpu[2]);
    std::printf("  %-26s %9.3f s %9.3f s   (4 FFTs, FFTW estimate plans)\n", "  of which spectra", best[0], cpu[0]);
    if (a.has("no-peer")) return 0;
    char tmpl[] = "/tmp/msid-bench-lpm-XXXXXX";
    if (!mkdtemp(tmpl)) throw Error("cannot create a temporary directory");
    const std::string dir = tmpl, file = dir + "/rec.f64";
    {
        FILE *f = std::fopen(file.c_str(), "wb");
        if (!f || std::fwrite(rows.data(), sizeof(double), rows.size(), f) != rows.size()) throw Error("cannot write " + file);
        std::fclose(f);
    }
    const std::string cmd = "python3 '" + bench_peers_dir() + "/msid_peers/lpm_peer.py' '" + file + "' " + std::to_string(N) + " 2 2 " +
                            std::to_string(res.R) + " " + std::to_string(res.W) + " 2>&1";
    FILE *p = popen(cmd.c_str(), "r");
    std::string out;
    char buf[4096];
    while (p && std::fgets(buf, sizeof buf, p)) out += buf;
    const int rc = p ? pclose(p) : -1;
    std::remove(file.c_str());
    rmdir(dir.c_str());
    Json pj;
    try {
        if (rc != 0) throw std::runtime_error("exit status");
        pj = Json::parse(out);
    } catch (const std::exception &) {
        std::printf("  peer failed: %s\n", out.substr(0, 300).c_str());
        return 0;
    }
    // agreement at every 1000th bin: max |G_msid - G_peer| / |G_peer|
    double worst = 0;
    const auto &bins = pj["bins"], &gr = pj["G_re"], &gi = pj["G_im"];
    for (size_t b = 0; b < bins.size(); ++b) {
        const size_t bi = bins[b].get<size_t>() - res.bins[0];
        for (unsigned t = 0; t < nu * ny; ++t) {
            const std::complex<double> gp(gr[b * 4 + t].get<double>(), gi[b * 4 + t].get<double>());
            worst = std::max(worst, std::abs(res.G[bi * 4 + t] - gp) / std::abs(gp));
        }
    }
    const double tp = pj["sec"].get<double>(), cp = pj["cpu"].get<double>();
    std::printf("  %-26s %9.3f s %9.3f s   (numpy %s, batched numpy.linalg, best of 2)\n", "NumPy peer", tp, cp,
                pj["numpy"].get<std::string>().c_str());
    std::printf("\n  msid is %.1fx (1 thread) / %.1fx (2 threads) faster in wall time, %.1fx in CPU time (1 thread);\n"
                "  max relative difference of G at %zu bins: %.2g\n",
                tp / best[1], tp / best[2], cp / cpu[1], bins.size(), worst);
    return 0;
}

}  // namespace msidcli
