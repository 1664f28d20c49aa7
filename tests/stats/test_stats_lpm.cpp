// Monte Carlo tests (fixed seeds) of the host estimators for arbitrary records (tools/est):
//  - LPM (Pintelon et al. 2010): random-noise excitation of a plant started from a
//    non-zero state (transient) with white and AR(1)-coloured noise, SISO, 2x2 from one
//    experiment, 2x2 from two experiments: the F(2, 2q) 95% regions cover 95% +- 2.5%,
//    the reported variance matches the empirical spread (10%), the bias is far below
//    the reported std. Negative controls: the chi-square region (infinite dof) must
//    under-cover; an LPM without the transient polynomial must have a larger error.
//  - ETFE (Tsiamis et al. 2024, case T1): the maximum error over the grid decays like
//    N^-1/2, the M = 2047 error is about sqrt(2) times the M = 1023 error, and the
//    Theorem 1 bound holds in at least 1 - delta of the runs; the reported covariance's
//    F(2, 2 dof) regions cover 95%. Negative control: the noise level alone (no
//    concentration term) is exceeded in most runs.
#include "etfe.hpp"
#include "lpm.hpp"
#include "lpm_sim.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <random>
#include <vector>
#include <cstdarg>
#include <cstddef>
#include <csetjmp>
#include <cstdint>
extern "C" {
#include <cmocka.h>
#include "msid_test_sim.h"
}

using namespace msidest;
using namespace lpmsim;

namespace {

struct Case {
    unsigned nu = 1, ny = 1, m = 1;
    size_t N = 2048;
    double sigma = 0.3;         // innovation std of the output noise
    double ar = 0.0;            // AR(1) pole of the noise (0: white)
    double x0 = 300.0;          // scale of the plant's random initial state (the transient)
    unsigned runs = 150;
    uint64_t seed = 1;
};

struct Tally {
    size_t n = 0, in_f = 0, in_chi2 = 0;
    double err2 = 0, var = 0;   // sums of |e|^2 and of the reported variance
    std::vector<cd> bias_sum;   // per tested (bin, element)
    std::vector<double> var_sum;
};

// Simulate one case and run the LPM on every record; tally the errors at bins 2W+1 apart.
Tally run_case(const Case &c, bool transient)
{
    Rng rng(c.seed);
    std::vector<std::vector<Iir>> P;   // P[i][j]
    for (unsigned i = 0; i < c.ny; ++i) {
        P.emplace_back();
        for (unsigned j = 0; j < c.nu; ++j) P[i].push_back(plant(0.25 + 0.35 * i + 0.6 * j, 0.1 * (1 + i + j), 0.5 - 0.3 * j));
    }
    LpmConfig cfg;
    cfg.transient = transient;
    if (!transient) cfg.window = lpm_default_window(cfg.order, c.nu, c.ny, c.m);
    Tally t;
    std::vector<size_t> test_bins;
    for (unsigned run = 0; run < c.runs; ++run) {
        std::vector<std::vector<double>> rows(c.m, std::vector<double>(c.N * (c.nu + c.ny)));
        for (unsigned e = 0; e < c.m; ++e) {
            auto Pe = P;   // fresh copies, random initial state
            for (auto &row : Pe)
                for (auto &f : row)
                    for (auto &s : f.s) s = 0;
            for (auto &row : Pe)
                for (auto &f : row) f.s[0] = c.x0 * rng.n() * 0.1, f.s[1] = c.x0 * rng.n() * 0.1;
            std::vector<double> v(c.ny, 0.0);
            for (unsigned i = 0; i < c.ny; ++i) v[i] = c.ar ? rng.n() * c.sigma / std::sqrt(1 - c.ar * c.ar) : 0.0;
            for (size_t n = 0; n < c.N; ++n) {
                double *r = &rows[e][n * (c.nu + c.ny)];
                for (unsigned j = 0; j < c.nu; ++j) r[j] = rng.n();
                for (unsigned i = 0; i < c.ny; ++i) {
                    double y = 0;
                    for (unsigned j = 0; j < c.nu; ++j) y += Pe[i][j].step(r[j]);
                    v[i] = c.ar * v[i] + c.sigma * rng.n();
                    r[c.nu + i] = y + v[i];
                }
            }
        }
        std::vector<RecordView> views;
        for (auto &r : rows) views.push_back({r.data(), c.N, (size_t)(c.nu + c.ny)});
        const Spectra S = record_spectra(views, c.nu, c.ny);
        const LpmResult R = lpm(S, cfg);
        if (test_bins.empty()) {
            for (size_t k = 2 * R.W + 1; k + 2 * R.W + 1 < (c.N - 1) / 2; k += 2 * R.W + 1) test_bins.push_back(k);
            t.bias_sum.assign(test_bins.size() * c.ny * c.nu, 0.0);
            t.var_sum.assign(test_bins.size() * c.ny * c.nu, 0.0);
        }
        const double f95 = tsim_fquant(1, R.q, 0.05), chi95 = -std::log(0.05);
        const size_t g = (size_t)c.ny * c.nu;
        for (size_t b = 0; b < test_bins.size(); ++b) {
            const size_t k = test_bins[b], bi = k - R.bins[0];
            for (unsigned i = 0; i < c.ny; ++i)
                for (unsigned j = 0; j < c.nu; ++j) {
                    cd G0 = 0;
                    G0 = P[i][j].freq((double)k / c.N);
                    const cd e = R.G[bi * g + i * c.nu + j] - G0;
                    const double v = R.cov[bi * g * g + (i + c.ny * j) * (g + 1)].real();
                    const double z = std::norm(e) / v;
                    t.n++;
                    t.in_f += z <= f95;
                    t.in_chi2 += z <= chi95;
                    t.err2 += std::norm(e);
                    t.var += v;
                    t.bias_sum[b * g + i * c.nu + j] += e;
                    t.var_sum[b * g + i * c.nu + j] += v;
                }
        }
    }
    return t;
}

void check_lpm_case(const char *name, const Case &c)
{
    const Tally t = run_case(c, true);
    const double cov_f = (double)t.in_f / t.n, cov_chi = (double)t.in_chi2 / t.n, ratio = t.err2 / t.var;
    // bias: mean error per (bin, element) over runs against the reported std; and its
    // normalised square, which is ~1 per element when the estimator is unbiased
    double worst = 0, zsum = 0;
    for (size_t a = 0; a < t.bias_sum.size(); ++a) {
        const double vbar = t.var_sum[a] / c.runs;
        const cd bias = t.bias_sum[a] / (double)c.runs;
        worst = std::max(worst, std::abs(bias) / std::sqrt(vbar));
        zsum += std::norm(bias) / (vbar / c.runs);
    }
    const double zmean = zsum / t.bias_sum.size();
    const Tally nt = run_case(c, false);
    const double cov_not = (double)nt.in_f / nt.n, mse_not = nt.err2 / t.err2;
    std::printf("%-26s n=%zu  cover F %.4f  chi2 %.4f  |e|^2/var %.3f  max|bias|/std %.3f  "
                "mean |bias|^2/(var/runs) %.2f  | no T: cover %.4f, MSE x%.2f\n",
                name, t.n, cov_f, cov_chi, ratio, worst, zmean, cov_not, mse_not);
    assert_true(std::fabs(cov_f - 0.95) <= 0.025);
    assert_true(std::fabs(ratio - 1.0) <= 0.10);
    assert_true(worst < 0.5);    // bias far below the reported std (MC noise alone: ~0.08 std per element)
    assert_true(zmean < 2.0);    // unbiased at Monte Carlo resolution (expectation 1)
    // negative controls: the chi-square region (dof taken as infinite) must under-cover; without
    // the transient polynomial the (random-input) transient acts as extra noise: the error grows
    assert_true(cov_chi < 0.925);
    assert_true(mse_not > 1.5);
}

Case lpm_case(unsigned n_io, unsigned m, double ar, unsigned runs, uint64_t seed)
{
    Case c;
    c.nu = c.ny = n_io;
    c.m = m;
    c.ar = ar;
    if (ar) c.sigma = 0.1;
    c.runs = runs;
    c.seed = seed;
    return c;
}

void lpm_siso_white(void **) { check_lpm_case("lpm SISO white", lpm_case(1, 1, 0.0, 150, 101)); }
void lpm_siso_coloured(void **) { check_lpm_case("lpm SISO AR(1) 0.8", lpm_case(1, 1, 0.8, 150, 102)); }
void lpm_mimo_white(void **) { check_lpm_case("lpm 2x2 white", lpm_case(2, 1, 0.0, 80, 103)); }
void lpm_mimo_coloured(void **) { check_lpm_case("lpm 2x2 AR(1) 0.8", lpm_case(2, 1, 0.8, 80, 104)); }
void lpm_mimo_two_experiments(void **) { check_lpm_case("lpm 2x2 two experiments", lpm_case(2, 2, 0.0, 60, 105)); }

// ---------------- T1: Tsiamis et al. §5 ----------------

// Maximal-length PRBS (+-1) of period 2^d - 1 (Fibonacci LFSR, primitive trinomials).
std::vector<double> prbs(unsigned d)
{
    const unsigned tap = d == 10 ? 7 : 9;   // x^10 + x^7 + 1, x^11 + x^9 + 1
    const size_t M = ((size_t)1 << d) - 1;
    unsigned reg = 1;
    std::vector<double> u(M);
    for (size_t t = 0; t < M; ++t) {
        const unsigned bit = ((reg >> (d - 1)) ^ (reg >> (tap - 1))) & 1u;
        u[t] = (reg & 1u) ? 1.0 : -1.0;
        reg = ((reg << 1) | bit) & ((1u << d) - 1);
    }
    return u;
}

Iir t1_plant() { return Iir({0, 0.12, 0.18}, {1, -1.4, 1.443, -1.123, 0.7729}); }

struct T1Stats {
    double mean_max_err = 0;
    double frac_bound_violated = 0, frac_noise_level_exceeded = 0, median_bound_over_err = 0;
    double cover = 0;   // F(2, 2 dof) 95% regions of the reported cov, over lines and runs
};

T1Stats t1_run(unsigned d, size_t Np, unsigned runs, uint64_t seed, double gstar)
{
    const auto per = prbs(d);
    const size_t M = per.size(), N = M * Np;
    const double offset = 0.5, sig_e = std::sqrt(0.1);
    Rng rng(seed);
    T1Stats st;
    std::vector<double> ratios;
    for (unsigned r = 0; r < runs; ++r) {
        Iir G = t1_plant();
        std::vector<double> rows(2 * N);
        double v = rng.n() * sig_e / std::sqrt(1 - 0.04);   // H = 1/(1 - 0.2 q^-1), stationary start
        for (size_t t = 0; t < N; ++t) {
            const double u = per[t % M] + offset;   // zero past inputs: the plant starts at rest
            v = 0.2 * v + sig_e * rng.n();
            rows[2 * t] = u;
            rows[2 * t + 1] = G.step(u) + v;
        }
        std::vector<RecordView> views{{rows.data(), N, 2}};
        const Spectra S = record_spectra(views, 1, 1);
        EtfeConfig c;
        c.M = M;
        c.delta = 0.05;
        c.gstar = gstar;
        c.du_max = max_input_norm(views, 1);
        c.l_lo = 0;
        const EtfeResult E = etfe(S, c);
        const Iir G0 = t1_plant();
        double maxerr = 0, worst_excess = -1e300, worst_noise = -1e300, minratio = 1e300;
        const double f95 = tsim_fquant(1, E.dof, 0.05);
        for (size_t l = 0; l < E.lines.size(); ++l) {
            const double err = std::abs(E.G[l] - G0.freq((double)E.lines[l] / M));
            if (E.lines[l] > 0) st.cover += (err * err / E.cov[l].real() <= f95) / (double)(runs * (E.lines.size() - 1));
            maxerr = std::max(maxerr, err);
            worst_excess = std::max(worst_excess, err - E.bound[l]);
            // the noise level alone: sqrt(||Phi||) sqrt(dy) / sigma_min(U), no concentration term
            const double level = E.bound_noise[l] / (1.0 + 24.0 * std::sqrt(E.log_term));
            worst_noise = std::max(worst_noise, err - level);
            minratio = std::min(minratio, E.bound[l] / std::max(err, 1e-300));
        }
        st.mean_max_err += maxerr / runs;
        st.frac_bound_violated += (worst_excess > 0) / (double)runs;
        st.frac_noise_level_exceeded += (worst_noise > 0) / (double)runs;
        ratios.push_back(minratio);
    }
    std::sort(ratios.begin(), ratios.end());
    st.median_bound_over_err = ratios[ratios.size() / 2];
    return st;
}

void etfe_t1(void **)
{
    // ||G||_* = sum_t t |g_t| of the T1 plant (impulse response to t = 4000)
    double gstar = 0;
    {
        Iir G = t1_plant();
        for (int t = 0; t < 4000; ++t) gstar += t * std::fabs(G.step(t == 0 ? 1.0 : 0.0));
    }
    const unsigned runs = 100;
    const size_t np1023[] = {4, 8, 16, 32};
    double lx[4], ly[4];
    T1Stats s1023[4], s2047[4];
    for (int i = 0; i < 4; ++i) {
        s1023[i] = t1_run(10, np1023[i], runs, 2024 + i, gstar);
        s2047[i] = t1_run(11, np1023[i] / 2, runs, 3024 + i, gstar);
        lx[i] = std::log((double)np1023[i] * 1023);
        ly[i] = std::log(s1023[i].mean_max_err);
        std::printf("T1 N=%6zu  max err M=1023 %.4f  M=2047 %.4f  ratio %.3f  bound violated %.2f/%.2f  "
                    "noise level exceeded %.2f/%.2f  median min(bound/err) %.1f  cov cover %.4f/%.4f\n",
                    np1023[i] * 1023, s1023[i].mean_max_err, s2047[i].mean_max_err,
                    s2047[i].mean_max_err / s1023[i].mean_max_err, s1023[i].frac_bound_violated,
                    s2047[i].frac_bound_violated, s1023[i].frac_noise_level_exceeded,
                    s2047[i].frac_noise_level_exceeded, s1023[i].median_bound_over_err, s1023[i].cover, s2047[i].cover);
    }
    double mx = 0, my = 0, sxy = 0, sxx = 0;
    for (int i = 0; i < 4; ++i) mx += lx[i] / 4, my += ly[i] / 4;
    for (int i = 0; i < 4; ++i) sxy += (lx[i] - mx) * (ly[i] - my), sxx += (lx[i] - mx) * (lx[i] - mx);
    const double slope = sxy / sxx;
    std::printf("T1 slope of log max err vs log N (M = 1023): %.3f (theory -0.5)\n", slope);
    assert_true(std::fabs(slope + 0.5) < 0.08);
    for (int i = 0; i < 4; ++i) {
        const double ratio = s2047[i].mean_max_err / s1023[i].mean_max_err;
        assert_true(ratio > 1.25 && ratio < 1.7);   // about sqrt(2) (x ~1.05 for the max over twice the lines)
        assert_true(s1023[i].frac_bound_violated <= 0.05 && s2047[i].frac_bound_violated <= 0.05);
        assert_true(s1023[i].frac_noise_level_exceeded > 0.5);   // negative control
        // the reported covariance M^T kron Phihat with dof m(Np - 1): exact F(2, 2 dof) regions
        // (about 51,000 line tests per case: Monte Carlo std 0.001)
        assert_true(std::fabs(s1023[i].cover - 0.95) < 0.01 && std::fabs(s2047[i].cover - 0.95) < 0.01);
    }
}

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(lpm_siso_white),
        cmocka_unit_test(lpm_siso_coloured),
        cmocka_unit_test(lpm_mimo_white),
        cmocka_unit_test(lpm_mimo_coloured),
        cmocka_unit_test(lpm_mimo_two_experiments),
        cmocka_unit_test(etfe_t1),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
