/* Plant simulator: msid_plant_frf against the simulated steady-state sinusoid
 * response and a closed-form partial-fraction FRF; D-only plants; errors. */
#include "unit_util.h"
#include "unit_plants.h"

typedef struct {
    msid_plant p;
    void *mem;
} plant;

static msid_status pl_make(plant *o, const msid_plant_cfg *c)
{
    const size_t n = msid_plant_mem_size(c);
    o->mem = tsim_alloc(n);
    return msid_plant_init(&o->p, c, o->mem, n);
}

/* Drive input j with A cos(2 pi f n + phi) from rest; after `warm` samples the
 * outputs must equal |G_ij| A cos(2 pi f n + phi + arg G_ij). */
static void check_sine_response(const msid_plant_cfg *c, double f, uint32_t j, uint32_t warm, double tol)
{
    plant o;
    UT_STATUS(pl_make(&o, c), MSID_OK);
    const uint32_t nu = c->n_inputs, ny = c->n_outputs;
    msid_cplx G[MSID_MAX_CHANNELS * MSID_MAX_CHANNELS];
    UT_STATUS(msid_plant_frf(&o.p, f, G), MSID_OK);
    const double A = 1.7, phi = 0.4;
    double u[MSID_MAX_CHANNELS] = {0}, y[MSID_MAX_CHANNELS];
    double worst = 0.0, scale = 0.0;
    for (uint32_t n = 0; n < warm + 200; ++n) {
        const long double arg = 2.0L * UT_PI_L * fmodl((long double)f * n, 1.0L) + phi;
        u[j] = (double)(A * cosl(arg));
        msid_plant_step(&o.p, u, y);
        if (n < warm) continue;
        for (uint32_t i = 0; i < ny; ++i) {
            const msid_cplx g = G[i * nu + j];
            const long double ref = A * ((long double)g.re * cosl(arg) - (long double)g.im * sinl(arg));  /* Re{G A e^{j arg}} */
            worst = fmax(worst, (double)fabsl(y[i] - ref));
            scale = fmax(scale, A * ut_cabs(g));
        }
    }
    UT_CHECK(worst <= tol * scale, "f=%.5f input %u: steady-state error %.3g of %.3g", f, j, worst, scale);
    tsim_free(o.mem);
}

static void test_frf_vs_simulation(void **state)
{
    (void)state;
    const double fs[] = {0.0, 0.01234, 0.1, 0.25, 0.3711, 0.5, 1.0 / 7.0};
    const msid_plant_cfg s = up_siso(), m = up_mimo();
    for (size_t k = 0; k < sizeof fs / sizeof fs[0]; ++k) {
        check_sine_response(&s, fs[k], 0, 300, 1e-9);
        check_sine_response(&m, fs[k], 0, 300, 1e-9);
        check_sine_response(&m, fs[k], 1, 300, 1e-9);
    }
    /* 3 inputs, 2 outputs, 3 states, a resonance near f = 0.1 */
    const double r = 0.97, th = UT_TWO_PI * 0.1;
    const double A[9] = {r * cos(th), -r * sin(th), 0.0, r * sin(th), r * cos(th), 0.0, 0.0, 0.0, -0.6};
    const double B[9] = {1.0, 0.0, 0.5, 0.0, 1.0, -0.3, 0.2, 0.1, 1.0};
    const double C[6] = {1.0, 0.0, 0.5, 0.0, 1.0, -1.0};
    const double D[6] = {0.0, 0.1, 0.0, 0.3, 0.0, 0.0};
    const msid_plant_cfg c3 = {3, 3, 2, A, B, C, D};
    for (uint32_t j = 0; j < 3; ++j) {
        check_sine_response(&c3, 0.1, j, 1500, 1e-9);
        check_sine_response(&c3, 0.237, j, 1500, 1e-9);
    }
}

/* Diagonal A: G(z) = sum_k C_k B_k / (z - a_k) + D, computed independently. */
static void test_frf_closed_form(void **state)
{
    (void)state;
    const double a[3] = {0.5, -0.8, 0.95};
    const double A[9] = {0.5, 0, 0, 0, -0.8, 0, 0, 0, 0.95};
    const double B[6] = {1.0, 2.0, -0.5, 0.3, 0.7, 0.0};   /* 3 x 2 */
    const double C[3] = {0.4, 1.1, -0.2};                  /* 1 x 3 */
    const double D[2] = {0.25, 0.0};
    const msid_plant_cfg c = {3, 2, 1, A, B, C, D};
    plant o;
    UT_STATUS(pl_make(&o, &c), MSID_OK);
    for (int k = 0; k <= 100; ++k) {
        const double f = -0.5 + k / 100.0 * 1.5;   /* beyond [0, 1/2): periodic in f */
        msid_cplx G[2];
        UT_STATUS(msid_plant_frf(&o.p, f, G), MSID_OK);
        const long double zr = cosl(2.0L * UT_PI_L * f), zi = sinl(2.0L * UT_PI_L * f);
        for (int j = 0; j < 2; ++j) {
            long double gr = D[j], gi = 0.0L;
            for (int s = 0; s < 3; ++s) {
                const long double den = (zr - a[s]) * (zr - a[s]) + zi * zi;
                const long double num = C[s] * B[s * 2 + j];
                gr += num * (zr - a[s]) / den;
                gi -= num * zi / den;
            }
            const long double mag = sqrtl(gr * gr + gi * gi);
            UT_CHECK(fabsl(G[j].re - gr) <= 1e-13L * (mag + 1) && fabsl(G[j].im - gi) <= 1e-13L * (mag + 1),
                     "f=%.3f j=%d: (%.17g, %.17g) vs (%.17Lg, %.17Lg)", f, j, G[j].re, G[j].im, gr, gi);
        }
    }
    /* real plant: G(-f) = conj G(f) */
    msid_cplx Gp[2], Gm[2];
    msid_plant_frf(&o.p, 0.123, Gp);
    msid_plant_frf(&o.p, -0.123, Gm);
    for (int j = 0; j < 2; ++j) UT_CHECK(fabs(Gp[j].re - Gm[j].re) < 1e-15 && fabs(Gp[j].im + Gm[j].im) < 1e-15, "j=%d", j);
    /* the state: zero input, x0 -> y(n) = sum_k C_k a_k^n x0_k */
    const double x0[3] = {1.0, -2.0, 0.5};
    msid_plant_set_state(&o.p, x0);
    const double u0[2] = {0.0, 0.0};
    for (int n = 0; n < 20; ++n) {
        double y;
        msid_plant_step(&o.p, u0, &y);
        long double ref = 0.0L;
        for (int s = 0; s < 3; ++s) ref += C[s] * powl(a[s], n) * x0[s];
        UT_CHECK(fabsl(y - ref) <= 1e-14L, "n=%d y=%.17g ref=%.17Lg", n, y, ref);
    }
    msid_plant_set_state(&o.p, NULL);
    double y;
    msid_plant_step(&o.p, u0, &y);
    UT_CHECK(y == 0.0, "%g", y);
    tsim_free(o.mem);
}

static void test_d_only(void **state)
{
    (void)state;
    const double D[6] = {1.5, -2.0, 0.25, 0.0, 3.0, -0.125};
    const msid_plant_cfg c = {0, 3, 2, NULL, NULL, NULL, D};
    plant o;
    UT_STATUS(pl_make(&o, &c), MSID_OK);
    const double fs[] = {0.0, 0.1, 0.25, 0.5, 0.77};
    for (int k = 0; k < 5; ++k) {
        msid_cplx G[6];
        UT_STATUS(msid_plant_frf(&o.p, fs[k], G), MSID_OK);
        for (int i = 0; i < 6; ++i) UT_CHECK(G[i].re == D[i] && G[i].im == 0.0, "f=%g G[%d]=(%g,%g)", fs[k], i, G[i].re, G[i].im);
    }
    msid_rng r;
    msid_rng_seed(&r, 3u);
    for (int n = 0; n < 50; ++n) {
        double u[3], y[2];
        for (int j = 0; j < 3; ++j) u[j] = msid_rng_normal(&r);
        msid_plant_step(&o.p, u, y);
        for (int i = 0; i < 2; ++i) {
            const double want = (D[i * 3] * u[0] + D[i * 3 + 1] * u[1]) + D[i * 3 + 2] * u[2];
            UT_CHECK(y[i] == want, "n=%d y[%d]=%.17g want %.17g", n, i, y[i], want);
        }
    }
    tsim_free(o.mem);
    /* D == NULL means zero */
    const msid_plant_cfg z = {0, 1, 1, NULL, NULL, NULL, NULL};
    UT_STATUS(pl_make(&o, &z), MSID_OK);
    double u = 3.0, y = 1.0;
    msid_plant_step(&o.p, &u, &y);
    UT_CHECK(y == 0.0, "%g", y);
    tsim_free(o.mem);
}

static void test_errors(void **state)
{
    (void)state;
    msid_plant p;
    msid_plant_cfg c = up_siso();
    const size_t need = msid_plant_mem_size(&c);
    unsigned char *mem = (unsigned char *)tsim_alloc(need + 64);
    UT_STATUS(msid_plant_init(NULL, &c, mem, need), MSID_E_NULL);
    UT_STATUS(msid_plant_init(&p, NULL, mem, need), MSID_E_NULL);
    UT_STATUS(msid_plant_init(&p, &c, NULL, need), MSID_E_NULL);
    UT_STATUS(msid_plant_init(&p, &c, ut_misalign(mem), need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_plant_init(&p, &c, mem, need - 1), MSID_E_MEM_SIZE);
    UT_STATUS(msid_plant_init(&p, &c, mem + 64, need), MSID_OK);
    msid_plant_cfg e = c;
    e.A = NULL;
    UT_STATUS(msid_plant_init(&p, &e, mem, need), MSID_E_NULL);
    e = c; e.n_states = MSID_MAX_STATES + 1u;
    UT_STATUS(msid_plant_init(&p, &e, mem, need), MSID_E_DIMS);
    UT_CHECK(msid_plant_mem_size(&e) == 0 && msid_plant_mem_size(NULL) == 0, "%d", 0);
    e = c; e.n_inputs = 0;
    UT_STATUS(msid_plant_init(&p, &e, mem, need), MSID_E_DIMS);
    e = c; e.n_outputs = MSID_MAX_CHANNELS + 1u;
    UT_STATUS(msid_plant_init(&p, &e, mem, need), MSID_E_DIMS);
    const double An[4] = {1.2, NAN, 1.0, 0.0}, Dn[1] = {HUGE_VAL};
    e = c; e.A = An;
    UT_STATUS(msid_plant_init(&p, &e, mem, need), MSID_E_NOT_FINITE);
    e = c; e.D = Dn;
    UT_STATUS(msid_plant_init(&p, &e, mem, need), MSID_E_NOT_FINITE);
    /* z on an eigenvalue of A: poles at +1 (f = 0) and -1 (f = 1/2) */
    const double A1[1] = {1.0}, Am[1] = {-1.0}, B1[1] = {1.0}, C1[1] = {1.0};
    const msid_plant_cfg c1 = {1, 1, 1, A1, B1, C1, NULL}, cm = {1, 1, 1, Am, B1, C1, NULL};
    msid_cplx G;
    UT_STATUS(msid_plant_init(&p, &c1, mem, need), MSID_OK);
    UT_STATUS(msid_plant_frf(&p, 0.0, &G), MSID_E_SINGULAR);
    UT_STATUS(msid_plant_frf(&p, 0.25, &G), MSID_OK);
    UT_CHECK(fabs(G.re + 0.5) < 1e-15 && fabs(G.im + 0.5) < 1e-15, "1/(j-1) = (%.17g, %.17g)", G.re, G.im);
    UT_STATUS(msid_plant_init(&p, &cm, mem, need), MSID_OK);
    UT_STATUS(msid_plant_frf(&p, 0.5, &G), MSID_E_SINGULAR);
    tsim_free(mem);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frf_vs_simulation),
        cmocka_unit_test(test_frf_closed_form),
        cmocka_unit_test(test_d_only),
        cmocka_unit_test(test_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
