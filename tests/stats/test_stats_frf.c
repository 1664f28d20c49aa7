/* Monte Carlo tests of the FRF estimator and its two covariances (fixed seeds).
 * Bias: every element of mean(Ghat) - G0 within 4.5 standard errors.
 * Covariance: empirical covariance over runs vs the average reported one,
 *   each element within 4.5 Monte Carlo standard errors, pooled ratio likewise.
 * Coverage: 95% regions from the reported covariance and dof cover 95% +- 2.5%. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include "mc.h"

/* SISO plant: poles 0.6 +- 0.59j (|z| = 0.84), a zero, feedthrough. */
static const double A1[4] = {1.2, -0.7, 1.0, 0.0}, B1[2] = {1.0, 0.0}, C1[2] = {0.5, 0.3}, D1[1] = {0.1};
static const msid_plant_cfg SISO = {2, 1, 1, A1, B1, C1, D1};
/* 2x2 plant, 4 states. */
static const double A2[16] = {0.8, -0.4, 0, 0, 0.4, 0.8, 0, 0, 0, 0, 0.3, -0.6, 0, 0, 0.6, 0.3};
static const double B2[8] = {1.0, 0.2, 0.0, 0.5, 0.4, 1.0, 0.6, 0.0};
static const double C2[8] = {1.0, 0.0, 0.5, 0.3, 0.2, 0.7, 0.0, 1.0};
static const double D2[4] = {0.2, 0.0, 0.1, 0.3};
static const msid_plant_cfg MIMO = {4, 2, 2, A2, B2, C2, D2};

static const uint32_t BINS[9] = {1, 2, 3, 5, 8, 13, 21, 34, 55};

static mc_case base(const char *name, uint32_t nu, uint32_t m, uint32_t K, const msid_plant_cfg *pl)
{
    mc_case c = {0};
    c.name = name;
    c.design.period = 128;
    c.design.n_lines = 9;
    c.design.bins = BINS;
    c.design.n_inputs = nu;
    c.design.n_experiments = m;
    c.design.seed = 11;
    c.design.pattern = MSID_PATTERN_DFT;
    c.ny = pl->n_outputs;
    c.K = K;
    c.R = 3000;
    c.seed = 1234;
    c.sigma_y = 0.5;
    c.clean = mc_clean_dt;
    c.truth = mc_truth_dt;
    c.plant = pl;
    return c;
}

static void expect_good(const mc_case *c, int check_b, int check_row)
{
    static mc_result r;
    assert_int_equal(mc_run(c, &r), 0);
    mc_print(c->name, &r);
    assert_int_equal(r.n_fail, 0);
    assert_int_equal(r.n_singular, 0);
    assert_int_equal(mc_check_bias(&r, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 0, 4.5), 0);
    if (check_b) assert_int_equal(mc_check_cov(&r, 1, 4.5), 0);
    assert_true(fabs(r.cov_elem_a - 0.95) <= 0.025);
    if (check_b) assert_true(fabs(r.cov_elem_b - 0.95) <= 0.025);
    if (check_row) assert_true(fabs(r.cov_row_b - 0.95) <= 0.025);
}

static void siso_white(void **s)
{
    (void)s;
    mc_case c = base("siso-white", 1, 1, 8, &SISO);
    expect_good(&c, 1, 1);
}

static void mimo_2x2_two_experiments(void **s)
{
    (void)s;
    mc_case c = base("2x2-m2-dft", 2, 2, 8, &MIMO);
    expect_good(&c, 1, 1);
}

static void mimo_2x2_three_experiments(void **s)
{
    (void)s;
    mc_case c = base("2x2-m3-dft", 2, 3, 6, &MIMO);
    expect_good(&c, 1, 1);
}

static void mimo_2x2_hadamard_coloured(void **s)
{
    (void)s;
    mc_case c = base("2x2-m2-hadamard-ar0.8", 2, 2, 8, &MIMO);
    c.design.pattern = MSID_PATTERN_HADAMARD;
    c.ar = 0.8;
    c.sigma_y = 0.2;
    expect_good(&c, 1, 1);
}

static const uint32_t BINS4[9] = {4, 8, 12, 20, 32, 52, 84, 136, 220};

/* Strongly coloured noise (AR(1) pole 0.9, correlation time ~10 samples).
 * Periods are then not exactly independent (Pintelon 2002, Assumption 11):
 * the covariance from period-to-period spread errs by O(tau/P). With P = 512
 * the error is below the Monte Carlo resolution; with P = 64 it shows (the
 * reported covariance is conservative where the noise spectrum is low). */
static void siso_coloured(void **s)
{
    (void)s;
    mc_case c = base("siso-ar0.9-P512", 1, 1, 8, &SISO);
    c.design.period = 512;
    c.design.bins = BINS4;
    c.ar = 0.9;
    c.sigma_y = 0.3;
    expect_good(&c, 1, 1);
}

/* The same noise with a short period (P = 64, tau/P ~ 0.16): the documented
 * O(tau/P) error of period-to-period covariance estimates appears, on the
 * conservative side (reported > actual). This also shows the harness detects
 * a few-percent covariance error. */
static const uint32_t BINSQ[5] = {1, 2, 3, 5, 8};
static void siso_coloured_short_period(void **s)
{
    (void)s;
    static mc_result r;
    mc_case c = base("siso-ar0.9-P64", 1, 1, 8, &SISO);
    c.design.period = 64;
    c.design.n_lines = 5;
    c.design.bins = BINSQ;
    c.ar = 0.9;
    c.sigma_y = 0.3;
    c.R = 6000;
    assert_int_equal(mc_run(&c, &r), 0);
    mc_print(c.name, &r);
    double pooled = 0;
    for (uint32_t l = 0; l < r.L; ++l) pooled += r.line[l].emp[0].re / r.line[l].rep_a[0].re / r.L;
    printf("  pooled emp/reported = %.4f (expect < 1: conservative)\n", pooled);
    assert_true(pooled < 1.0 - 4.5 / sqrt((double)c.R * r.L));
    assert_true(pooled > 0.85);
    assert_true(r.cov_elem_a >= 0.95 - 0.005);
}

/* Errors-in-variables: noisy input measurement, input and output noise
 * correlated (as in a loop). The nonparametric covariance must stay right;
 * the known-input one must visibly under-cover (negative control). */
static void siso_noisy_input(void **s)
{
    (void)s;
    static mc_result r;
    mc_case c = base("siso-eiv", 1, 1, 8, &SISO);
    c.sigma_u = 0.15;
    c.sigma_y = 0.3;
    c.rho_uy = 0.5;
    assert_int_equal(mc_run(&c, &r), 0);
    mc_print(c.name, &r);
    assert_int_equal(mc_check_bias(&r, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 0, 4.5), 0);
    assert_true(fabs(r.cov_elem_a - 0.95) <= 0.025);
    assert_true(r.cov_elem_b < 0.93);      /* ignoring input noise is wrong here */
}

static void mimo_noisy_input(void **s)
{
    (void)s;
    static mc_result r;
    mc_case c = base("2x2-eiv", 2, 2, 8, &MIMO);
    c.sigma_u = 0.1;
    c.sigma_y = 0.3;
    assert_int_equal(mc_run(&c, &r), 0);
    mc_print(c.name, &r);
    assert_int_equal(mc_check_bias(&r, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 0, 4.5), 0);
    assert_true(fabs(r.cov_elem_a - 0.95) <= 0.025);
}

/* Four periods: dof = 3 per experiment. The F-based regions stay at 95%;
 * asymptotic chi-square regions from the same covariance do not. */
static void siso_four_periods(void **s)
{
    (void)s;
    static mc_result r;
    mc_case c = base("siso-K4", 1, 1, 4, &SISO);
    c.R = 5000;
    assert_int_equal(mc_run(&c, &r), 0);
    mc_print(c.name, &r);
    assert_true(fabs(r.line[0].dof_a - 3.0) < 1e-12);
    assert_int_equal(mc_check_bias(&r, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 0, 4.5), 0);
    assert_true(fabs(r.cov_elem_a - 0.95) <= 0.01);
    assert_true(fabs(r.cov_row_b - 0.95) <= 0.01);
    assert_true(r.cov_naive_a < 0.90);     /* ~0.875 in theory */
}

static void mimo_four_periods(void **s)
{
    (void)s;
    static mc_result r;
    mc_case c = base("2x2-K4", 2, 2, 4, &MIMO);
    assert_int_equal(mc_run(&c, &r), 0);
    mc_print(c.name, &r);
    assert_true(fabs(r.line[0].dof_b - 6.0) < 1e-12);
    assert_int_equal(mc_check_bias(&r, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 0, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 1, 4.5), 0);
    assert_true(fabs(r.cov_elem_a - 0.95) <= 0.025);
    assert_true(fabs(r.cov_elem_b - 0.95) <= 0.025);
    assert_true(fabs(r.cov_row_b - 0.95) <= 0.025);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(siso_white),
        cmocka_unit_test(mimo_2x2_two_experiments),
        cmocka_unit_test(mimo_2x2_three_experiments),
        cmocka_unit_test(mimo_2x2_hadamard_coloured),
        cmocka_unit_test(siso_coloured),
        cmocka_unit_test(siso_coloured_short_period),
        cmocka_unit_test(siso_noisy_input),
        cmocka_unit_test(mimo_noisy_input),
        cmocka_unit_test(siso_four_periods),
        cmocka_unit_test(mimo_four_periods),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
