/* Continuous-time multisines sampled slower than Nyquist (González et al. 2025,
 * Assumption 2, Theorems 1-2): lines above pi/h fold, the LS FRF stays
 * unbiased at the continuous-time frequencies, and its covariance is right.
 * The noiseless records are built from the continuous-time formulas
 * u(t) = sum A cos(w t + phi), y(t) = sum A |G(jw)| cos(w t + phi + arg G(jw))
 * evaluated with libm at t = n h, independently of the core's aliasing map. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>
#include <complex.h>
#include <math.h>
#include <stdio.h>
#include "mc.h"

#define P_CT 64
#define H_CT 0.9                         /* Nyquist pi/h = 3.49 rad/s */
static const uint32_t KS[8] = {3, 10, 25, 40, 50, 70, 90, 100};   /* lines k * 2 pi/(P h) */
static double OMEGA[8];

/* 2x2 continuous-time plant; the SISO case uses entry (0,0). */
static double complex Gct(int i, int j, double w)
{
    const double complex s = I * w;
    if (i == 0 && j == 0) return 9.0 / (s * s + 1.8 * s + 9.0);    /* wn = 3, zeta = 0.3 */
    if (i == 0 && j == 1) return 0.5 / (s + 2.0);
    if (i == 1 && j == 0) return 2.0 / (s * s + s + 4.0);
    return 1.0 / (0.5 * s + 1.0);
}

/* pattern phase of input i in experiment e, in turns (DFT pattern) */
static double tau(uint32_t i, uint32_t e, uint32_t m) { return -(double)((i * e) % m) / m; }

static void clean_ct(const mc_case *c, const tsim_design *t, uint32_t e, double *rows)
{
    const uint32_t nu = t->d.n_inputs, ny = c->ny, C = nu + ny, L = t->d.n_lines, m = t->d.n_experiments;
    for (uint32_t n = 0; n < c->K * P_CT; ++n) {
        const double tt = n * H_CT;
        for (uint32_t j = 0; j < nu; ++j) rows[n * C + j] = 0.0;
        for (uint32_t i = 0; i < ny; ++i) rows[n * C + nu + i] = 0.0;
        for (uint32_t j = 0; j < nu; ++j)
            for (uint32_t l = 0; l < L; ++l) {
                const double A = t->d.amp[j * L + l];
                const double ph = 2 * M_PI * (t->d.phase[j * L + l] + tau(j, e, m));
                rows[n * C + j] += A * cos(OMEGA[l] * tt + ph);
                for (uint32_t i = 0; i < ny; ++i) {
                    const double complex G = Gct((int)i, (int)j, OMEGA[l]);
                    rows[n * C + nu + i] += A * cabs(G) * cos(OMEGA[l] * tt + ph + carg(G));
                }
            }
        /* the core's generator reproduces the sampled continuous-time input */
        for (uint32_t j = 0; j < nu; ++j)
            assert_true(fabs(msid_design_sample(&t->d, &t->tw, e, j, n % P_CT) - rows[n * C + j]) < 1e-10);
    }
}

static void truth_ct(const mc_case *c, const tsim_design *t, uint32_t l, msid_cplx *G)
{
    for (uint32_t i = 0; i < c->ny; ++i)
        for (uint32_t j = 0; j < t->d.n_inputs; ++j) {
            const double complex g = Gct((int)i, (int)j, OMEGA[l]);
            G[i * t->d.n_inputs + j].re = creal(g);
            G[i * t->d.n_inputs + j].im = cimag(g);
        }
}

static mc_case ct_case(const char *name, uint32_t nu, uint32_t ny)
{
    for (int l = 0; l < 8; ++l) OMEGA[l] = KS[l] * 2 * M_PI / (P_CT * H_CT);
    mc_case c = {0};
    c.name = name;
    c.design.period = P_CT;
    c.design.n_lines = 8;
    c.design.omega = OMEGA;
    c.design.sample_time = H_CT;
    c.design.n_inputs = nu;
    c.design.n_experiments = nu;
    c.design.seed = 5;
    c.ny = ny;
    c.K = 6;
    c.R = 3000;
    c.seed = 77;
    c.sigma_y = 0.3;
    c.clean = clean_ct;
    c.truth = truth_ct;
    return c;
}

static void aliased_map_is_used(void **s)
{
    (void)s;
    mc_case c = ct_case("map", 1, 1);
    tsim_design t;
    assert_int_equal(tsim_design_make(&t, &c.design), MSID_OK);
    int folded = 0, above = 0;
    for (int l = 0; l < 8; ++l) {
        above += OMEGA[l] > M_PI / H_CT;
        const uint32_t k = KS[l] % P_CT, b = k > P_CT / 2 ? P_CT - k : k;
        assert_int_equal(t.d.bins[l], b);
        assert_int_equal(t.d.folded[l], k > P_CT / 2);
        folded += t.d.folded[l];
        assert_true(OMEGA[l] > 0);
    }
    assert_int_equal(above, 5);                             /* 5 of 8 lines above Nyquist */
    assert_int_equal(folded, 3);                            /* 3 of them fold (conjugate) */
    tsim_design_free(&t);
}

static void check(const mc_case *c)
{
    static mc_result r;
    assert_int_equal(mc_run(c, &r), 0);
    mc_print(c->name, &r);
    assert_int_equal(r.n_fail + r.n_singular, 0);
    assert_int_equal(mc_check_bias(&r, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 0, 4.5), 0);
    assert_int_equal(mc_check_cov(&r, 1, 4.5), 0);
    assert_true(fabs(r.cov_elem_a - 0.95) <= 0.025);
    assert_true(fabs(r.cov_row_b - 0.95) <= 0.025);
}

static void siso_aliased(void **s) { (void)s; mc_case c = ct_case("ct-siso-aliased", 1, 1); check(&c); }
static void mimo_aliased(void **s) { (void)s; mc_case c = ct_case("ct-2x2-aliased", 2, 2); check(&c); }

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(aliased_map_is_used),
        cmocka_unit_test(siso_aliased),
        cmocka_unit_test(mimo_aliased),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
