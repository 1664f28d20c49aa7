// Monte Carlo tests (fixed seeds) of the LPM with a known reference (tools/est/lpm_eiv.cpp):
// a random-noise reference r drives the plant through an actuator (open loop) or through
// a proportional controller that feeds the measured output back (closed loop); the plant
// starts from a random state (transient); the measured input carries noise at 20 dB or
// 0 dB SNR, white or AR(1)-coloured, and the output noise is white or coloured.
// Checked at bins 2W+1 apart (independent lines): the F(2, 2q) 95% regions of the
// linearised covariance cover 95% +- 2.5%, |e|^2 / reported variance is about 1, and
// the bias is below the reported std. Negative control on the same records: the plain
// LPM of y on the noisy u is biased (its mean error is many Monte Carlo stds from 0)
// and its regions under-cover.
#include "lpm_eiv.hpp"
#include "lpm_sim.hpp"

#include <cmath>
#include <cstdio>
#include <vector>
#include <cstdarg>
#include <cstddef>
#include <csetjmp>
#include <cstdint>
extern "C" {
#include <cmocka.h>
#include "msid_test_sim.h"
}

using namespace lpmsim;

namespace {

struct Case {
    const char *name = "";
    unsigned n = 1;             // nu = ny = nr
    size_t N = 2048;
    double snr_u_db = 20;       // measured-input SNR: var(u0) / var(n_u)
    double sigma_y = 0.3;       // output noise innovation std
    double ar = 0.0;            // AR(1) pole of both noises (0: white)
    double k = 0.0;             // controller gain: u = r - k y_measured (0: open loop through the actuator)
    unsigned runs = 150;
    uint64_t seed = 1;
};

struct Tally {
    size_t n = 0, in_f = 0, in_f50 = 0;
    double f50 = 0;
    double err2 = 0, var = 0;
    std::vector<cd> bias_sum;
    std::vector<double> var_sum;
    void add(size_t a, cd e, double v, double f95)
    {
        n++;
        in_f += std::norm(e) / v <= f95;
        in_f50 += std::norm(e) / v <= f50;
        err2 += std::norm(e);
        var += v;
        bias_sum[a] += e;
        var_sum[a] += v;
    }
    double cover() const { return (double)in_f / n; }
    // max |mean error| / mean reported std, and mean |mean error|^2 / (var / runs) (1 if unbiased)
    void bias(unsigned runs, double &worst, double &zmean) const
    {
        worst = 0;
        double zsum = 0;
        for (size_t a = 0; a < bias_sum.size(); ++a) {
            const double vbar = var_sum[a] / runs;
            const cd b = bias_sum[a] / (double)runs;
            worst = std::max(worst, std::abs(b) / std::sqrt(vbar));
            zsum += std::norm(b) / (vbar / runs);
        }
        zmean = zsum / bias_sum.size();
    }
};

struct Result {
    Tally eiv, plain;
};

Result run_case(const Case &c)
{
    const unsigned n = c.n;
    Rng rng(c.seed);
    std::vector<std::vector<Iir>> P;   // plant P[i][j], strictly proper (b0 = 0) for the loop
    for (unsigned i = 0; i < n; ++i) {
        P.emplace_back();
        for (unsigned j = 0; j < n; ++j) {
            const Iir s = plant(0.25 + 0.35 * i + 0.6 * j, 0.1 * (1 + i + j), 0.5 - 0.3 * j);
            P[i].push_back(Iir({0.0, s.b[0], s.b[1]}, s.a));
        }
    }
    const Iir act({0.8}, {1.0, -0.5});   // actuator of the open loop: var(u0) = 0.64 / 0.75 per unit r
    double var_u0 = 0.64 / 0.75;
    if (c.k > 0) {   // closed loop: the input's variance from a noise-free pilot run
        std::vector<std::vector<Iir>> Pp = P;
        Rng pr(c.seed ^ 0x5eed);
        double s = 0;
        const size_t Np = 20000;
        std::vector<double> y(n);
        for (size_t t = 0; t < Np; ++t) {
            for (unsigned i = 0; i < n; ++i) {
                y[i] = 0;
                for (unsigned j = 0; j < n; ++j) y[i] += Pp[i][j].s[0];
            }
            for (unsigned j = 0; j < n; ++j) {
                const double u = pr.n() - c.k * y[j];
                s += u * u / (n * Np);
                for (unsigned i = 0; i < n; ++i) Pp[i][j].step(u);
            }
        }
        var_u0 = s;
    }
    const double sigma_u = std::sqrt(var_u0 / std::pow(10.0, c.snr_u_db / 10)) * std::sqrt(1 - c.ar * c.ar);
    msidest::LpmConfig cfg;
    Result res;
    std::vector<size_t> test_bins;
    const size_t g = (size_t)n * n, cols = 3 * n;   // rows [r, y, u]
    for (unsigned run = 0; run < c.runs; ++run) {
        auto Pe = P;
        for (auto &row : Pe)
            for (auto &f : row) f.s[0] = 30 * rng.n(), f.s[1] = 30 * rng.n();
        std::vector<Iir> A(n, act);
        for (auto &f : A) f.s[0] = rng.n();
        std::vector<double> vy(n), vu(n);
        for (unsigned i = 0; i < n; ++i) {
            vy[i] = c.ar ? rng.n() * c.sigma_y / std::sqrt(1 - c.ar * c.ar) : 0.0;
            vu[i] = c.ar ? rng.n() * sigma_u / std::sqrt(1 - c.ar * c.ar) : 0.0;
        }
        std::vector<double> rows(c.N * cols);
        for (size_t t = 0; t < c.N; ++t) {
            double *x = &rows[t * cols];
            std::vector<double> ym(n), u(n);
            for (unsigned i = 0; i < n; ++i) {
                double y0 = 0;
                for (unsigned j = 0; j < n; ++j) y0 += Pe[i][j].s[0];   // b0 = 0: y(t) from the past inputs
                vy[i] = c.ar * vy[i] + c.sigma_y * rng.n();
                ym[i] = y0 + vy[i];
            }
            for (unsigned j = 0; j < n; ++j) {
                x[j] = rng.n();
                u[j] = c.k > 0 ? x[j] - c.k * ym[j] : A[j].step(x[j]);
                vu[j] = c.ar * vu[j] + sigma_u * rng.n();
                x[2 * n + j] = u[j] + vu[j];
            }
            for (unsigned i = 0; i < n; ++i) {
                x[n + i] = ym[i];
                for (unsigned j = 0; j < n; ++j) Pe[i][j].step(u[j]);
            }
        }
        // the noisy-input LPM: inputs r, outputs z = [y; u]
        std::vector<msidest::RecordView> vz{{rows.data(), c.N, cols}};
        const auto S = msidest::record_spectra(vz, n, 2 * n);
        const auto E = msidest::lpm_eiv(S, n, cfg);
        // the plain LPM of y on the measured u: inputs u, outputs y (columns reordered)
        std::vector<double> uy(c.N * 2 * n);
        for (size_t t = 0; t < c.N; ++t)
            for (unsigned j = 0; j < n; ++j) {
                uy[t * 2 * n + j] = rows[t * cols + 2 * n + j];
                uy[t * 2 * n + n + j] = rows[t * cols + n + j];
            }
        std::vector<msidest::RecordView> vp{{uy.data(), c.N, 2 * (size_t)n}};
        const auto L = msidest::lpm(msidest::record_spectra(vp, n, n), cfg);
        if (test_bins.empty()) {
            const size_t W = E.zr.W;
            for (size_t k = 2 * W + 1; k + 2 * W + 1 < (c.N - 1) / 2; k += 2 * W + 1) test_bins.push_back(k);
            for (Tally *t : {&res.eiv, &res.plain}) {
                t->bias_sum.assign(test_bins.size() * g, 0.0);
                t->var_sum.assign(test_bins.size() * g, 0.0);
            }
        }
        const double fe = tsim_fquant(1, E.zr.q, 0.05), fp = tsim_fquant(1, L.q, 0.05);
        res.eiv.f50 = tsim_fquant(1, E.zr.q, 0.5);
        res.plain.f50 = tsim_fquant(1, L.q, 0.5);
        for (size_t b = 0; b < test_bins.size(); ++b) {
            const size_t k = test_bins[b];
            const size_t be = k - E.zr.bins[0], bp = k - L.bins[0];
            for (unsigned i = 0; i < n; ++i)
                for (unsigned j = 0; j < n; ++j) {
                    const cd G0 = P[i][j].freq((double)k / c.N);
                    const size_t a = i * n + j, d = (i + n * j) * (g + 1);
                    res.eiv.add(b * g + a, E.G[be * g + a] - G0, E.cov[be * g * g + d].real(), fe);
                    res.plain.add(b * g + a, L.G[bp * g + a] - G0, L.cov[bp * g * g + d].real(), fp);
                }
        }
    }
    return res;
}

void check(const Case &c)
{
    const Result r = run_case(c);
    double we, ze, wp, zp;
    r.eiv.bias(c.runs, we, ze);
    r.plain.bias(c.runs, wp, zp);
    const double ratio = r.eiv.err2 / r.eiv.var, med = (double)r.eiv.in_f50 / r.eiv.n;
    std::printf("%-34s n=%zu  cover F %.4f  in F50 %.4f  |e|^2/var %.3f  max|bias|/std %.3f  mean|bias|^2/(var/runs) %.2f  | "
                "plain LPM: cover %.4f, max|bias|/std %.3f, mean|bias|^2/(var/runs) %.1f\n",
                c.name, r.eiv.n, r.eiv.cover(), med, ratio, we, ze, r.plain.cover(), wp, zp);
    assert_true(std::fabs(r.eiv.cover() - 0.95) <= 0.025);
    // the median region and |e|^2 against the reported variance: the linearisation holds where G_ur is
    // well determined (input SNR 20 dB). At 0 dB G = G_yr / G_ur is a ratio of Gaussians (heavy tails, no
    // variance): the 95% regions still cover, the 50% regions over-cover (conservative; docs/statistics.md)
    if (c.snr_u_db >= 20) {
        assert_true(std::fabs(med - 0.5) <= 0.03);   // MC std ~0.005
        assert_true(std::fabs(ratio - 1.0) <= 0.15);
    }
    assert_true(we < 0.5);   // bias below the reported std (Monte Carlo noise alone: ~0.1-0.15 std)
    assert_true(ze < 2.0);   // unbiased at Monte Carlo resolution (expectation 1)
    // negative control: the plain LPM on the same records is biased far beyond Monte Carlo noise
    // (the statistic is 1 +- ~0.07 if unbiased; at 20 dB its bias is ~1% of G, 0.2-0.4 std per run)
    assert_true(zp > 2.5);
    if (c.snr_u_db < 20 || c.k > 0) assert_true(wp > 0.5);   // and visibly so in single bins
}

Case mk(const char *name, unsigned n, double snr, double ar, double k, unsigned runs, uint64_t seed)
{
    Case c;
    c.name = name;
    c.n = n;
    c.snr_u_db = snr;
    c.ar = ar;
    if (ar) c.sigma_y = 0.1;
    if (snr >= 20 && k == 0) c.sigma_y = 0.001;   // an accurate output: the 1% input-noise bias of plain LPM shows
    c.k = k;
    c.runs = runs;
    c.seed = seed;
    return c;
}

// The limit of the linearised covariance (docs/statistics.md): when the input noise dominates the
// equivalent output error C_e (accurate output, noisy input), G_hat - G ~ -G b / G_ur_hat with b the
// error of G_ur_hat, and the plug-in C_e(G_hat) under-states the error exactly when |b| is large.
// Checked: 10 dB still covers 95% +- 2.5%; 0 dB under-covers (about 0.85), as documented.
void limit_input_noise_dominated(void **)
{
    double cover[2];
    const double snr[2] = {10.0, 0.0};
    for (int i = 0; i < 2; ++i) {
        Case c = mk(i ? "eiv SISO 0 dB, sigma_y 0.001 (limit)" : "eiv SISO 10 dB, sigma_y 0.001", 1, snr[i], 0.0, 0.0, 150,
                    301 + i);
        c.sigma_y = 0.001;
        const Result r = run_case(c);
        double we, ze;
        r.eiv.bias(c.runs, we, ze);
        cover[i] = r.eiv.cover();
        std::printf("%-34s n=%zu  cover F %.4f  in F50 %.4f  max|bias|/std %.3f\n", c.name, r.eiv.n, cover[i],
                    (double)r.eiv.in_f50 / r.eiv.n, we);
    }
    assert_true(std::fabs(cover[0] - 0.95) <= 0.025);
    assert_true(cover[1] < 0.9);
}

void siso_20db_white(void **) { check(mk("eiv SISO 20 dB white", 1, 20, 0.0, 0.0, 150, 201)); }
void siso_0db_white(void **) { check(mk("eiv SISO 0 dB white", 1, 0, 0.0, 0.0, 150, 202)); }
void siso_0db_coloured(void **) { check(mk("eiv SISO 0 dB AR(1) 0.8", 1, 0, 0.8, 0.0, 150, 203)); }
void siso_closed_loop(void **) { check(mk("eiv SISO closed loop 20 dB", 1, 20, 0.0, 0.5, 150, 204)); }
void mimo_20db_white(void **) { check(mk("eiv 2x2 20 dB white", 2, 20, 0.0, 0.0, 80, 205)); }
void mimo_0db_coloured(void **) { check(mk("eiv 2x2 0 dB AR(1) 0.8", 2, 0, 0.8, 0.0, 80, 206)); }
void mimo_closed_loop(void **) { check(mk("eiv 2x2 closed loop 0 dB", 2, 0, 0.0, 0.5, 80, 207)); }

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(siso_20db_white),  cmocka_unit_test(siso_0db_white),   cmocka_unit_test(siso_0db_coloured),
        cmocka_unit_test(siso_closed_loop), cmocka_unit_test(mimo_20db_white),  cmocka_unit_test(mimo_0db_coloured),
        cmocka_unit_test(mimo_closed_loop), cmocka_unit_test(limit_input_noise_dominated),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
