// Monte Carlo tests (fixed seeds) of the multiple-experiment ML's order selection, coloured-noise
// weighting and validation on records (tools/fit/multi_order.cpp, multi_noise.cpp):
//  - the AR whitening factor W satisfies W^T W = Sigma^-1 for the Toeplitz covariance computed by
//    an independent route (the impulse response of 1/c(q^-1));
//  - --order auto (MDL with the initial conditions counted) picks the true order 6 of case M1 in
//    >= 90% of runs; negative control: the same rule counting only the poles over-selects;
//  - coloured (AR(2), band-pass) noise: the weighted estimator's 95% intervals of frequency and
//    damping cover ~95% with the AR model given and estimated from the residuals; negative control:
//    the unweighted estimator's intervals under-cover;
//  - multi_check (msid validate on records): p-values of the true model reject ~5% on fresh data;
//    negative controls: a wrong model (cost test) and a white-noise model on coloured noise (whiteness).
#include "multi_sim.hpp"

#include <cmath>
#include <cstdio>
#include <cstdarg>
#include <cstddef>
#include <csetjmp>
#include <cstdint>
extern "C" {
#include <cmocka.h>
}

using namespace msidfit;

// AR(2) noise c(q^-1) v = e with poles r e^{+-j w0}, started in its stationary state (burn-in)
static VecR ar2(double r, double w0) { VecR c(2); c << -2 * r * std::cos(w0), r * r; return c; }

static void test_whitening_exact(void **)
{
    const VecR c = ar2(0.8, 2 * M_PI * 0.13);
    const int T = 12;
    // Sigma(k) = sum_m h_m h_m+k, h the impulse response of 1 / c(q^-1) (independent of Levinson)
    const int H = 4000;
    VecR h = VecR::Zero(H);
    for (int t = 0; t < H; ++t) {
        double acc = t == 0 ? 1.0 : 0.0;
        for (int k = 1; k <= 2 && t - k >= 0; ++k) acc -= c(k - 1) * h(t - k);
        h(t) = acc;
    }
    MatR S(T, T);
    for (int a = 0; a < T; ++a)
        for (int b = 0; b < T; ++b) S(a, b) = h.head(H - std::abs(a - b)).dot(h.tail(H - std::abs(a - b)));
    const MultiNoise W = multi_noise_from_ar(c);
    MatR Wm(T, T);
    for (int k = 0; k < T; ++k) {
        VecR e = VecR::Zero(T), o(T);
        e(k) = 1.0;
        W.apply(e.data(), o.data(), T);
        Wm.col(k) = o;
    }
    const double err = (Wm * S * Wm.transpose() - MatR::Identity(T, T)).norm();
    const double ld = std::abs(W.logdet(T) - std::log(S.determinant()));
    std::printf("AR(2) whitening: |W Sigma W^T - I| = %.2g, |logdet - ln det Sigma| = %.2g\n", err, ld);
    assert_true(err < 1e-9);
    assert_true(ld < 1e-9);
    // bad noise models are refused
    VecR bad(1);
    bad << -1.01;
    bool threw = false;
    try { multi_noise_from_ar(bad); } catch (const FitError &e) { threw = std::string(e.what()).find("not stationary") != std::string::npos; }
    assert_true(threw);
}

static void test_order_selection(void **)
{
    M1Case c;
    msid_rng r;
    msid_rng_seed(&r, 70);
    const int N = 4, K = 40;
    const std::vector<int> orders = {2, 3, 4, 5, 6, 7, 8, 9};
    int right = 0, right_noic = 0, right_aic = 0, gap = 0;
    MultiOptions o;
    o.h = c.ts;
    for (int k = 0; k < K; ++k) {
        const MultiData d = m1_data(c, r, N);
        const auto y = multi_add_noise(d.clean, r, multi_noise_sd(d.clean, 100.0));
        const MultiOrderSelection s = multi_select_order(y, o, orders, "mdl", true);
        right += s.chosen == 6;
        gap += s.hankel_gap_order == 6;
        // the AIC and the poles-only count from the same rows (no refits)
        int ca = -1, cn = -1;
        double ba = INFINITY, bn = INFINITY, S = 0;
        for (const auto &x : y) S += (double)x.y.size();
        for (const auto &row : s.rows) {
            if (!row.ok) continue;
            if (row.aic < ba) { ba = row.aic; ca = row.order; }
            const double mn = row.m2logl + (double)row.order * std::log(S);   // k = n: the initial conditions left out
            if (mn < bn) { bn = mn; cn = row.order; }
        }
        right_aic += ca == 6;
        right_noic += cn == 6;
    }
    std::printf("M1 N = %d, SNR 100, %d runs, orders 2..9: MDL picks 6 in %.3f, AIC %.3f, largest Hankel gap %.3f; "
                "MDL counting only the poles (negative control) %.3f\n", N, K, (double)right / K, (double)right_aic / K,
                (double)gap / K, (double)right_noic / K);
    assert_true((double)right / K >= 0.9);
    assert_true((double)right_noic / K < 0.9);
}

// coverage of the 95% intervals of the 6 modal quantities (fn, zeta of 3 modes)
static int covered(const MultiResult &f, const M1Case &c)
{
    int in = 0;
    if (f.modes.size() != 3) return 0;
    for (int m = 0; m < 3; ++m) {
        const auto &md = f.modes[(size_t)m];
        in += std::abs(md.fn - c.fn[m]) < 1.96 * md.sd_fn;
        in += std::abs(md.zeta - c.zeta[m]) < 1.96 * md.sd_zeta;
    }
    return in;
}

static void test_coloured_coverage(void **)
{
    M1Case c;
    msid_rng r;
    msid_rng_seed(&r, 80);
    const int N = 5, K = 100;
    const VecR car = ar2(0.8, 2 * M_PI * 0.13);   // band-pass noise peaked at 130 Hz (fs 1 kHz)
    MultiOptions ow, og, oe;
    ow.order = og.order = oe.order = 6;
    ow.h = og.h = oe.h = c.ts;
    og.noise_ar = car;
    oe.noise_ar_order = 2;
    int in_w = 0, in_g = 0, in_e = 0, tot = 0;
    double mse_w = 0, mse_g = 0, cest = 0;
    const VecR a0 = c.alpha();
    for (int k = 0; k < K; ++k) {
        const MultiData d = m1_data(c, r, N);
        const auto y = multi_add_ar_noise(d.clean, r, car, multi_noise_sd(d.clean, 100.0));
        const MultiResult fw = multi_fit(y, ow), fg = multi_fit(y, og), fe = multi_fit(y, oe);
        in_w += covered(fw, c);
        in_g += covered(fg, c);
        in_e += covered(fe, c);
        tot += 6;
        mse_w += (fw.alpha - a0).squaredNorm() / K;
        mse_g += (fg.alpha - a0).squaredNorm() / K;
        cest += (fe.noise_ar - car).norm() / K;
    }
    const double cw = (double)in_w / tot, cg = (double)in_g / tot, ce = (double)in_e / tot;
    std::printf("M1 N = %d, AR(2) noise (poles 0.8 e^{+-j 2pi 0.13}), SNR 100, %d runs: 95%% intervals of fn, zeta cover "
                "%.3f (AR given), %.3f (AR(2) estimated, mean |c_hat - c| %.3f), %.3f (unweighted, negative control); "
                "rms alpha error weighted %.3g, unweighted %.3g\n",
                N, K, cg, ce, cest, cw, std::sqrt(mse_g), std::sqrt(mse_w));
    assert_true(cg > 0.92 && cg < 0.98);
    assert_true(ce > 0.90 && ce < 0.98);
    assert_true(cw < 0.85);
    assert_true(mse_g < mse_w);
}

static void test_validate_records(void **)
{
    M1Case c;
    msid_rng r;
    msid_rng_seed(&r, 90);
    const int N = 5, K = 200;
    const VecR a0 = c.alpha();
    // a wrong model: the 130 Hz mode 1% higher
    M1Case cw = c;
    cw.fn[1] *= 1.01;
    const VecR aw = cw.alpha();
    const VecR car = ar2(0.8, 2 * M_PI * 0.13);
    int rej_cost = 0, rej_white = 0, rej_wrong = 0, rej_col_white = 0, rej_col_ar = 0, rej_col_ar_cost = 0;
    for (int k = 0; k < K; ++k) {
        const MultiData d = m1_data(c, r, N);
        const double sd = multi_noise_sd(d.clean, 100.0);
        const auto y = multi_add_noise(d.clean, r, sd);
        const MultiCheck t = multi_check(y, a0, {}, 1, VecR(), sd * sd, 1e12, 10);
        rej_cost += t.p_cost < 0.05;
        rej_white += t.p_white < 0.05;
        rej_wrong += multi_check(y, aw, {}, 1, VecR(), sd * sd, 1e12, 10).p_cost < 0.05;
        if (k < 100) {
            const auto yc = multi_add_ar_noise(d.clean, r, car, sd);
            rej_col_white += multi_check(yc, a0, {}, 1, VecR(), sd * sd, 1e12, 10).p_white < 0.05;
            const double se2 = sd * sd / multi_ar_autocov(car, 0)(0);   // innovations variance
            const MultiCheck tc = multi_check(yc, a0, {}, 1, car, se2, 1e12, 10);
            rej_col_ar += tc.p_white < 0.05;
            rej_col_ar_cost += tc.p_cost < 0.05;
        }
    }
    std::printf("validation on fresh M1 records (N = %d, %d runs), rejection rates at 5%%: true model cost %.3f, "
                "whiteness %.3f; AR noise with the AR model: cost %.3f, whiteness %.3f; negative controls: 130 Hz "
                "mode 1%% off (cost) %.3f, AR noise validated as white (whiteness) %.3f\n",
                N, K, (double)rej_cost / K, (double)rej_white / K, rej_col_ar_cost / 100.0, rej_col_ar / 100.0,
                (double)rej_wrong / K, rej_col_white / 100.0);
    // binomial sd at 5%: 1.5% (200 runs), 2.2% (100 runs)
    assert_true(rej_cost >= 3 && rej_cost <= 20);
    assert_true(rej_white >= 3 && rej_white <= 20);
    assert_true(rej_col_ar <= 12 && rej_col_ar_cost <= 12);
    assert_true((double)rej_wrong / K > 0.8);
    assert_true(rej_col_white > 80);
}

// noisy inputs: the errors-in-variables estimator against the output-error one (negative control)
static void test_eiv(void **)
{
    static const double CHI2_95_8 = 15.507;
    IoCase c;
    msid_rng r;
    msid_rng_seed(&r, 100);
    const int N = 10, K = 100;
    const MultiData d = io_data(c, r, N);
    VecR th0(8);
    th0.head(4) = c.alpha();
    for (int k = 0; k < 4; ++k) th0(4 + k) = c.beta()[(size_t)k](0, 0);
    const double sd = multi_noise_sd(d.clean, 20.0);
    MultiOptions o;
    o.order = 4;
    // lambda = 0: the EIV cost is the output-error cost with the initial conditions projected out
    {
        const auto y = multi_add_noise(d.clean, r, sd);
        const MultiResult f = multi_fit(y, o);
        const double ce = multi_eiv_cost(y, f.theta, 4, 1, 0.0);
        std::printf("EIV cost at lambda = 0: %.12g, output-error cost %.12g\n", ce, f.cost);
        assert_true(std::abs(ce - f.cost) < 1e-9 * f.cost);
    }
    int in_eiv = 0, in_oe = 0, marg = 0;
    double b_eiv = 0, b_oe = 0;
    VecR mean_eiv = VecR::Zero(8), mean_oe = VecR::Zero(8);
    for (int k = 0; k < K; ++k) {
        auto y = multi_add_noise(d.clean, r, sd);
        for (auto &rec : y)
            for (Eigen::Index t = 0; t < rec.u.rows(); ++t) rec.u(t, 0) += sd * msid_rng_normal(&r);   // sigma_u = sigma_y
        const MultiEivResult fe = multi_fit_eiv(y, o, 1.0);
        const VecR e = fe.theta - th0, eo = fe.oe_theta - th0;
        in_eiv += e.dot(fe.cov.ldlt().solve(e)) < CHI2_95_8;
        for (int i = 0; i < 8; ++i) marg += std::abs(e(i)) < 1.96 * std::sqrt(fe.cov(i, i));
        const MultiResult fo = multi_fit(y, o);
        in_oe += eo.dot(fo.cov.ldlt().solve(eo)) < CHI2_95_8;
        mean_eiv += e / K;
        mean_oe += eo / K;
    }
    b_eiv = mean_eiv.norm();
    b_oe = mean_oe.norm();
    std::printf("noisy inputs (I/O case, %d records, sigma_u = sigma_y, 26 dB on y), %d runs: joint 95%% region covers "
                "%.3f (EIV), marginal %.3f; output-error fit (negative control) %.3f; |mean error| EIV %.3g, OE %.3g\n",
                N, K, (double)in_eiv / K, marg / (8.0 * K), (double)in_oe / K, b_eiv, b_oe);
    assert_true((double)in_eiv / K > 0.9 && (double)in_eiv / K < 0.99);
    assert_true((double)in_oe / K < 0.85);
    assert_true(b_eiv < b_oe);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_whitening_exact),
        cmocka_unit_test(test_order_selection),
        cmocka_unit_test(test_coloured_coverage),
        cmocka_unit_test(test_validate_records),
        cmocka_unit_test(test_eiv),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
