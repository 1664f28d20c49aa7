/* González et al. 2025 §V-B(1), reference case G1 (../shared/reference-cases.md):
 * G0(p) = b0/(a1 p + 1), a1 = 1, b0 = 2; u(t) = cos(w1 t - pi/2), w1 = 1/sqrt(2);
 * white output noise sigma = 0.8; N = 20 and N = 60 samples with N h a
 * multiple of 2 pi / w1. Our choice (the paper leaves h open): P = 10 samples
 * per period, h = 2 pi / (10 w1), so N = 20 is 2 periods and N = 60 is 6.
 * 2e5 Monte Carlo runs, as in the paper's Fig. 3, seed 2025.
 *
 * Checks:
 *  - [Re G, Im G] has covariance exactly 2 sigma^2 / (N alpha^2) I_2 (Theorem 2);
 *  - the reported known-input covariance is unbiased for it;
 *  - a1_hat = -Im G / (w1 Re G) (eq. 56) follows its exact finite-sample law (KS test), and
 *    its bulk follows the normal approximation (eq. 58).
 * The whole estimate goes through the core: CT design -> msid_meas -> msid_frf. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "msid_test_sim.h"

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void run_case(uint32_t N)
{
    const double a1 = 1.0, b0 = 2.0, sigma = 0.8, alpha = 1.0, w1 = 1.0 / sqrt(2.0);
    const uint32_t P = 10, K = N / P, R = 200000;
    const double h = 2.0 * M_PI / (P * w1);
    const double omega[1] = {w1}, amp[1] = {alpha}, ph[1] = {-0.25};   /* cos(w t - pi/2) */
    msid_design_cfg dc = {0};
    dc.period = P; dc.n_lines = 1; dc.omega = omega; dc.sample_time = h;
    dc.amplitudes = amp; dc.phase_mode = MSID_PHASE_USER; dc.phases = ph;
    dc.n_inputs = 1; dc.n_experiments = 1;
    tsim_design t;
    assert_int_equal(tsim_design_make(&t, &dc), MSID_OK);
    assert_int_equal(t.d.bins[0], 1);

    /* noiseless samples at t = n h, straight from the continuous-time formulas */
    const double complex G0 = b0 / (a1 * I * w1 + 1.0);
    double *clean = tsim_alloc(sizeof(double) * 2 * N), *rows = tsim_alloc(sizeof(double) * 2 * N);
    for (uint32_t n = 0; n < N; ++n) {
        const double tt = n * h;
        clean[2 * n] = alpha * cos(w1 * tt - M_PI / 2);
        clean[2 * n + 1] = alpha * cabs(G0) * cos(w1 * tt - M_PI / 2 + carg(G0));
        /* the core's generator produces the same input samples */
        assert_true(fabs(msid_design_sample(&t.d, &t.tw, 0, 0, n) - clean[2 * n]) < 1e-12);
    }
    msid_meas_cfg mc = {0};
    mc.period = P; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = 1;
    mc.n_lines = 1; mc.bins = t.d.bins; mc.twiddle = &t.tw;
    size_t nm = msid_meas_mem_size(&mc);
    void *mm = tsim_alloc(nm);
    msid_frf_cfg fc = {P, 1, 1, 1, 1, 0, t.d.folded};
    size_t nf = msid_frf_mem_size(&fc);
    void *fm = tsim_alloc(nf);
    msid_meas ms;
    msid_frf f;
    msid_rng rng;
    msid_rng_seed(&rng, 2025);
    double sr = 0, si = 0, srr = 0, sii = 0, sri = 0, srep = 0;
    double *a1h = tsim_alloc(sizeof(double) * R);
    double sa = 0, saa = 0, sb = 0;
    for (uint32_t r = 0; r < R; ++r) {
        for (uint32_t n = 0; n < N; ++n) {
            rows[2 * n] = clean[2 * n];
            rows[2 * n + 1] = clean[2 * n + 1] + sigma * msid_rng_normal(&rng);
        }
        msid_meas_init(&ms, &mc, mm, nm);
        msid_meas_begin(&ms, 0);
        msid_meas_push(&ms, rows, N);
        msid_meas_end(&ms, 0);
        msid_frf_init(&f, &fc, fm, nf);
        const msid_pstats *ps[1] = {msid_meas_stats(&ms, 0)};
        assert_int_equal(msid_frf_compute(&f, ps), MSID_OK);
        const msid_cplx G = msid_frf_G(&f, 0)[0];
        const double dr = G.re - creal(G0), di = G.im - cimag(G0);
        sr += dr; si += di; srr += dr * dr; sii += di * di; sri += dr * di;
        srep += msid_frf_cov_known_input(&f, 0)[0].re;
        const double a = -G.im / (w1 * G.re);                     /* eq. (56) */
        a1h[r] = a;
        sa += a; saa += a * a;
        sb += (G.re * G.re + G.im * G.im) / G.re;
    }
    const double vr = srr / R - (sr / R) * (sr / R), vi = sii / R - (si / R) * (si / R);
    const double cri = sri / R - (sr / R) * (si / R);
    const double theory = 2 * sigma * sigma / (N * alpha * alpha);
    const double se_rel = sqrt(2.0 / R);
    printf("G1 N=%u: var Re %.5f, var Im %.5f, cov %.2e, theory %.5f (rel SE %.4f); mean reported cov %.5f vs %.5f\n",
           N, vr, vi, cri, theory, se_rel, srep / R, 2 * theory);
    assert_true(fabs(vr / theory - 1) < 4.5 * se_rel);
    assert_true(fabs(vi / theory - 1) < 4.5 * se_rel);
    assert_true(fabs(cri / theory) < 4.5 / sqrt((double)R));
    assert_true(fabs(sr / R) < 4.5 * sqrt(theory / R));   /* unbiased */
    assert_true(fabs(si / R) < 4.5 * sqrt(theory / R));
    /* reported complex variance E|e|^2 = Var Re + Var Im = 2 * theory; its estimate has
     * 2(K-1) real dof per run, so the mean over R runs has rel SE sqrt(1/((K-1) R)) */
    assert_true(fabs(srep / R / (2 * theory) - 1) < 4.5 / sqrt((double)(K - 1) * R));

    /* Exact finite-sample law of a1_hat (eq. 56): with (Re G, Im G) ~ N((mr, mi), s^2 I),
     * P(a1_hat <= x) = P(Im G + x w1 Re G >= 0 | Re G > 0)
     *               = Phi((mi + x w1 mr) / (s sqrt(1 + x^2 w1^2)))   (P(Re G < 0) ~ 1e-7 here).
     * Kolmogorov-Smirnov test of the 2e5 estimates against it. */
    const double mr = creal(G0), mi = cimag(G0), sd = sqrt(theory);
    qsort(a1h, R, sizeof(double), cmp_double);
    double D = 0.0;
    for (uint32_t k = 0; k < R; ++k) {
        const double x = a1h[k];
        const double F = 0.5 * erfc(-(mi + x * w1 * mr) / (sd * sqrt(1 + x * x * w1 * w1)) / sqrt(2.0));
        const double d1 = fabs((double)k / R - F), d2 = fabs((double)(k + 1) / R - F);
        if (d1 > D) D = d1;
        if (d2 > D) D = d2;
    }
    /* eq. (58): a1_hat ~ N(a1, 2 sigma^2 (1 + a1^2 w1^2)^3 / (N alpha^2 w1^2 b0^2)), a normal
     * approximation of that ratio. The paper's validity criterion (57) is
     * sigma / (alpha |Re G0|) sqrt(2/N) <= 0.1: 0.19 at N = 20, 0.11 at N = 60, so the bulk
     * (median, interquartile range) follows (58) while the sample moments carry heavy tails. */
    const double v58 = 2 * sigma * sigma * pow(1 + a1 * a1 * w1 * w1, 3) / (N * alpha * alpha * w1 * w1 * b0 * b0);
    const double crit57 = sigma / (alpha * fabs(mr)) * sqrt(2.0 / N);
    const double ma = sa / R, va = saa / R - ma * ma;
    const double med = a1h[R / 2], iqr_sd = (a1h[3 * R / 4] - a1h[R / 4]) / 1.3489795;
    printf("G1 N=%u: a1_hat KS vs exact law: sqrt(R) D = %.3f (limit 1.95, p = 0.001)\n", N, sqrt((double)R) * D);
    printf("G1 N=%u: a1_hat median %.4f, (IQR/1.349)^2 %.5f | eq.58: mean %.4f, var %.5f | criterion (57) %.3f | "
           "sample mean %.4f, var %.5f (heavy tails) | b0_hat mean %.4f\n",
           N, med, iqr_sd * iqr_sd, a1, v58, crit57, ma, va, sb / R);
    assert_true(sqrt((double)R) * D < 1.95);
    assert_true(fabs(med - a1) < 0.01);
    assert_true(fabs(iqr_sd * iqr_sd / v58 - 1) < (crit57 > 0.15 ? 0.05 : 0.03));
    tsim_free(a1h); tsim_free(clean); tsim_free(rows); tsim_free(mm); tsim_free(fm);
    tsim_design_free(&t);
}

static void g1_n20(void **s) { (void)s; run_case(20); }
static void g1_n60(void **s) { (void)s; run_case(60); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(g1_n20),
        cmocka_unit_test(g1_n60),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
