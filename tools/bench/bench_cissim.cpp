// msid bench fit --cissim: discrete-cISSIM (You et al. 2023) beside `subspace` and `ml` on the
// same samples (case Y1, Table 3), the authors' speed reference size, sparse lines on lightly
// damped systems, and the covariance trend of case Y2. Numbers: docs/benchmarks.md.
#include "bench_fit_parts.hpp"

#include "cissim.hpp"
#include "cissim_cases.hpp"
#include "lmfd_fit.hpp"
#include "msid_host_util.hpp"
#include "subspace.hpp"

#include <cmath>

namespace msidbench {

using namespace msidfit;
using msidutil::fmt;

namespace {

// One method's distances to the truth and times over the systems.
struct Acc {
    std::vector<double> d2, di, t, tc;
    void add(const SSModel &m, const SSModel &truth, double sec, double csec = 0)
    {
        tc.push_back(csec);
        double a = 1e9, b = 1e9;
        try {
            const Distance dd = ss_distance(m, truth);
            a = dd.h2, b = dd.hinf;
        } catch (const FitError &) {
        }
        d2.push_back(a), di.push_back(b), t.push_back(sec);
    }
};

// statistics over the stable estimates (an unstable one has no H2 distance: counted apart)
double mean(const std::vector<double> &v)
{
    double s = 0, k = 0;
    for (double x : v)
        if (x < 1e8) s += x, k += 1;
    return k > 0 ? s / k : 0;
}
int unstable(const std::vector<double> &v)
{
    int k = 0;
    for (double x : v) k += x >= 1e8;
    return k;
}
double sdev(const std::vector<double> &v)
{
    const double m = mean(v);
    double s = 0, k = 0;
    for (double x : v)
        if (x < 1e8) s += (x - m) * (x - m), k += 1;
    return k > 1 ? std::sqrt(s / (k - 1)) : 0;
}
double median(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v.empty() ? 0 : 0.5 * (v[v.size() / 2] + v[(v.size() - 1) / 2]);
}

SSModel ml_from_subspace(const FrfData &f, const std::vector<WeightedLine> &w, int n)
{
    SubspaceOptions so;
    so.order = n;
    const SubspaceResult sr = fit_subspace(f, Domain::DT, w, true, so);
    LmfdSpec ls;
    ls.nD = n;
    ls.nN = n;
    std::vector<MatC> target;
    for (const auto &l : w) target.push_back(ss_eval(sr.model, l.x));
    MlOptions mo;
    return lmfd_to_ss(lmfd_ml(w, Domain::DT, 0, ls, lmfd_sk(w, Domain::DT, 0, ls, 30, &target), mo, false).model);
}

// A stopwatch of wall and thread CPU time.
struct Clock {
    double t0 = wall_s(), c0 = thread_cpu_s();
    void restart() { t0 = wall_s(), c0 = thread_cpu_s(); }
    double wall() const { return wall_s() - t0; }
    double cpu() const { return thread_cpu_s() - c0; }
};

// The methods of one comparison, in the order of its table.
const char *const METHODS[] = {"cissim full (Alg. 3 FFT)", "cissim reduced", "cissim reduced, unweighted Alg. 4",
                               "cissim reduced + ML refinement", "msid frf (core, stream DFT)", "subspace (on that FRF)",
                               "ml (on that FRF)"};

// Every method of METHODS on one system's record (`with_full`: the full line set too).
void fit_one(Acc *a, const SSModel &truth, const CissimRecord &rec, uint32_t T, const std::vector<uint32_t> &full,
             const std::vector<uint32_t> &red, bool with_full)
{
    CissimOptions o;
    o.order = 4;
    Clock k;
    if (with_full) {
        const SSModel mf = cissim_fit({cissim_isp(rec.rows.data(), rec.n_rows, 1, 1, T, full, 1)}, o).model;
        a[0].add(mf, truth, k.wall(), k.cpu());
    }
    k.restart();
    const IspResult ir = cissim_isp(rec.rows.data(), rec.n_rows, 1, 1, T, red, 1);
    const SSModel mr = cissim_fit({ir}, o).model;
    a[1].add(mr, truth, k.wall(), k.cpu());
    k.restart();
    o.weighted = false;
    const SSModel mu = cissim_fit({cissim_isp(rec.rows.data(), rec.n_rows, 1, 1, T, red, 1)}, o).model;
    a[2].add(mu, truth, k.wall(), k.cpu());
    o.weighted = true;
    k.restart();
    {
        const IspResult il = cissim_isp(rec.rows.data(), rec.n_rows, 1, 1, T, red, 1, IspMethod::Auto, true);
        SSModel mm = cissim_fit({il}, o).model;
        try {
            mm = cissim_refine(mm, {il}).model;
        } catch (const FitError &) {
        }
        a[3].add(mm, truth, k.wall(), k.cpu());
    }
    k.restart();
    const FrfData f = core_frf(rec, red, 1);
    const auto w = weigh(f, Domain::DT, Weight::Cov);
    a[4].t.push_back(k.wall());
    a[4].tc.push_back(k.cpu());
    k.restart();
    SubspaceOptions so;
    so.order = 4;
    const SSModel ms = fit_subspace(f, Domain::DT, w, true, so).model;
    a[5].add(ms, truth, k.wall(), k.cpu());
    k.restart();
    SSModel mm;
    try {
        mm = ml_from_subspace(f, w, 4);
    } catch (const FitError &) {
        mm = ms;
    }
    a[6].add(mm, truth, k.wall(), k.cpu());
}

// One comparison over NS systems: records of K periods (first skipped), lines `red` for the reduced
// set and for the FRF of subspace/ml.
void compare(Writer &wr, const std::string &title, int NS, uint32_t T, uint32_t K, double snr,
             const std::vector<uint32_t> &red, double rmin, double rmax, uint64_t seed, bool with_full)
{
    msid_rng r;
    msid_rng_seed(&r, seed);
    std::vector<uint32_t> full;
    for (uint32_t b = 0; 2 * b < T; ++b) full.push_back(b);
    Acc a[7];
    for (int s = 0; s < NS; ++s) {
        const SSModel truth = y1_system(r, rmin, rmax);
        const CissimRecord rec = y1_record(truth, T, K, snr, r);
        fit_one(a, truth, rec, T, full, red, with_full);
    }
    wr.print("%s\n", title.c_str());
    wr.print("  %-36s %9s %9s %9s %9s %11s %11s %11s %9s\n", "method", "d2 mean", "d2 std", "d2 med", "dinf mean",
             "wall/system", "CPU/system", "CPU median", "unstable");
    for (int k = 0; k < 7; ++k) {
        if (k == 0 && !with_full) continue;
        if (k == 4) {
            wr.print("  %-36s %9s %9s %9s %9s %9.4f s %9.4f s %9.4f s\n", METHODS[k], "", "", "", "", mean(a[k].t),
                     mean(a[k].tc), median(a[k].tc));
            continue;
        }
        wr.print("  %-36s %9.4f %9.4f %9.4f %9.4f %9.4f s %9.4f s %9.4f s %9d\n", METHODS[k], mean(a[k].d2), sdev(a[k].d2),
                 median(a[k].d2), mean(a[k].di), mean(a[k].t), mean(a[k].tc), median(a[k].tc), unstable(a[k].d2));
    }
    wr.print("  published unweighted / ML refined: d2 mean %.1fx, median %.1fx\n", mean(a[2].d2) / mean(a[3].d2),
             median(a[2].d2) / median(a[3].d2));
    wr.print("\n");
}

// 1. speed at the authors' reference size (SISO n = 4, 24 periods of 3000 samples, 1200 lines) and
// at the Y1 size of Table 3.
void speed(Writer &w, uint32_t T, bool quick)
{
    msid_rng r;
    msid_rng_seed(&r, 77);
    const SSModel truth = y1_system(r);
    const CissimRecord rec = y1_record(truth, T, 24, 30.0, r);
    std::vector<uint32_t> lines;
    for (uint32_t b = 1; b <= 1200; ++b) lines.push_back(b);
    CissimOptions o;
    o.order = 4;
    const char *how[] = {"auto (FFT)", "direct (Alg. 1)"};
    w.print("speed: SISO n = 4, 24 periods x 3000 samples, 1200 lines (authors' MATLAB code under Octave, "
            "2 cores: ~0.5 s; target <= 0.1 s)\n");
    for (int k = 0; k < 2; ++k) {
        const IspMethod im = k == 0 ? IspMethod::Auto : IspMethod::Direct;
        double best = 1e9, bisp = 1e9;
        for (int rep = 0; rep < (quick ? 3 : 10); ++rep) {
            const double t0 = wall_s();
            const IspResult ir = cissim_isp(rec.rows.data(), rec.n_rows, 1, 1, T, lines, 0, im);
            const double t1 = wall_s();
            const CissimResult res = cissim_fit({ir}, o);
            const double t2 = wall_s();
            best = std::min(best, t2 - t0);
            bisp = std::min(bisp, t1 - t0);
            if (res.order != 4) w.print("?");
        }
        w.print("  ISP %-16s  total %8.4f s  (ISP %8.4f s, Alg. 4 + 5 %8.4f s)  best of runs\n", how[k], best, bisp,
                best - bisp);
    }
    const double t0 = wall_s();
    const Correlations c = cissim_correlations(rec.rows.data(), rec.n_rows, 1, 1, T, 1, 40);
    w.print("  noise correlations, Alg. 6 (FFT of the zero-padded residuals, M = 40): %.4f s\n\n", wall_s() - t0);
    (void)c;
    // the Y1 size of Table 3: N = 720000 (241 periods, the first skipped), reduced set of 100 lines
    const CissimRecord big = y1_record(truth, T, 241, 30.0, r);
    const std::vector<uint32_t> red = y1_reduced_bins(T, 100);
    double bw = 1e9, bc = 1e9, bwi = 1e9;
    for (int rep = 0; rep < (quick ? 5 : 20); ++rep) {
        const double t0w = wall_s(), t0c = thread_cpu_s();
        const IspResult ir = cissim_isp(big.rows.data(), big.n_rows, 1, 1, T, red, 1);
        const double t1w = wall_s();
        const CissimResult res = cissim_fit({ir}, o);
        bw = std::min(bw, wall_s() - t0w);
        bc = std::min(bc, thread_cpu_s() - t0c);
        bwi = std::min(bwi, t1w - t0w);
        if (res.order != 4) w.print("?");
    }
    w.print("speed at the Y1 size (Table 3: N = 720000, reduced set, 100 lines; published d-ISIM reduced "
            "0.0074 s):\n  cissim reduced  wall %.4f s (ISP %.4f s)  CPU %.4f s  best of runs\n\n", bw, bwi, bc);
}

// 4. Y2: the covariance errors against the record length.
void y2(Writer &w, bool quick)
{
    const uint32_t T2 = 600, Ks[] = {40, 100, 400};
    const int R = quick ? 3 : 10;
    w.print("Y2 (6.3): covariance errors, mean of %d runs (T = 600, random periodic input, order 2, M = N^(1/3))\n", R);
    for (uint32_t K : Ks) {
        CovErrors acc;
        double tt = 0;
        for (int rep = 0; rep < R; ++rep) {
            double sec = 0;
            const CovErrors e = y2_run(T2, K, 900 + 31 * (uint64_t)rep, &sec);
            tt += sec;
            acc.w += e.w / R, acc.v += e.v / R, acc.tau += e.tau / R, acc.r += e.r / R;
        }
        w.print("  N = %6u: eta_w %.4f  eta_v %.4f  eta_tau %.4f  eta_r(r=10) %.4f   %.4f s per estimate\n", K * T2, acc.w,
                acc.v, acc.tau, acc.r, tt / R);
    }
}

}  // namespace

void fit_cissim(Writer &w, const CissimBenchRequest &rq)
{
    if (rq.systems < 1) throw msidutil::UsageError("--systems must be at least 1");
    const int NS = rq.systems;
    w.print("msid bench fit --cissim  (msid %s)\nmachine: %s\n\n", MSID_VERSION, machine().c_str());
    const uint32_t T = 3000;
    speed(w, T, rq.quick);
    // 2. Y1
    compare(w,
            fmt("Y1 (Table 3): %d systems, T = 3000, N = 720000 (241 periods, first skipped), 30 dB output noise; "
                "reduced set and FRF: 100 lines in the chirp band", NS),
            NS, T, 241, 30.0, y1_reduced_bins(T, 100), 0.6, 0.95, 2023, true);
    w.print("  published (MATLAB, N = 720000): d-ISIM full d2 0.0193 (std 0.0007) dinf 0.0200 t 0.1806 s; reduced d2 "
            "0.0177 (0.0037) dinf 0.0204 t 0.0074 s;\n  tfest 0.0146 / 0.0177 / 0.2564 s; SIM time 0.0079 / 0.0089 / "
            "0.2744 s; SIM freq 0.0386 / 0.0416 / 0.0397 s\n\n");
    // 3. sparse lines, lightly damped, 20 dB
    compare(w,
            fmt("sparse: %d lightly damped systems (pole radii 0.97..0.995), 50 lines, 20 dB, T = 3000, 24 periods",
                std::max(NS / 2, 5)),
            std::max(NS / 2, 5), T, 25, 20.0, y1_reduced_bins(T, 50), 0.97, 0.995, 4242, false);
    y2(w, rq.quick);
}

CissimBenchResult bench_cissim(const CissimBenchRequest &rq, const Sink &sink)
{
    return with_report<CissimBenchResult>(fit_cissim, rq, sink);
}

}  // namespace msidbench
