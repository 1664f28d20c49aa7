/* Multisine design: validation and diagnostics, condition numbers against the
 * closed form of the pattern, crest factors, expected input DFT vs a naive
 * long-double DFT, and the continuous-time aliasing map vs an independent fold. */
#include "unit_util.h"
#ifdef MSID_HAVE_FFTW
#include "msid/msid_fft_fftw.h"
#endif

static msid_design_cfg base_cfg(uint32_t P, uint32_t L, const uint32_t *bins, uint32_t nu, uint32_t m)
{
    msid_design_cfg c = ut_design_cfg(P, L, bins, nu, m);
    c.phase_mode = MSID_PHASE_RANDOM;
    c.seed = 1;
    c.pattern = MSID_PATTERN_DFT;
    return c;
}

/* Build, return the status and the diagnostics, free. */
static msid_status try_design(const msid_design_cfg *c, msid_design_diag_t *dg)
{
    tsim_design t;
    const msid_status st = tsim_design_make(&t, c);
    if (dg) *dg = msid_design_diag(&t.d);
    tsim_design_free(&t);
    return st;
}

#define CHECK_DIAG(dg, a, b, bn) \
    UT_CHECK((dg).line_a == (a) && (dg).line_b == (b) && (dg).bin == (bn), \
             "diag (%d, %d, %lld), expected (%d, %d, %lld)", (int)(dg).line_a, (int)(dg).line_b, \
             (long long)(dg).bin, (int)(a), (int)(b), (long long)(bn))

/* Pattern phase tau_{i,e} in turns (header: DFT exp(-j 2 pi i e/m); Sylvester Hadamard). */
static double pattern_turns(msid_pattern p, uint32_t i, uint32_t e, uint32_t m)
{
    if (p == MSID_PATTERN_HADAMARD) {
        uint32_t x = i & e, par = 0;
        while (x) { par ^= x & 1u; x >>= 1; }
        return par ? 0.5 : 0.0;
    }
    return -(double)((i * e) % m) / (double)m;
}

/* ---------------- discrete-time validation ---------------- */

static void test_line_range(void **state)
{
    (void)state;
    msid_design_diag_t dg;
    const uint32_t b1[] = {1, 3, 8};
    msid_design_cfg c = base_cfg(16, 3, b1, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_LINE_RANGE);
    CHECK_DIAG(dg, 2, -1, 8);
    const uint32_t b2[] = {40, 2};
    c = base_cfg(16, 2, b2, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_LINE_RANGE);
    CHECK_DIAG(dg, 0, -1, 40);
    /* odd P: bin 7 < 15/2 is fine, bin 8 is not */
    const uint32_t b3[] = {7, 1}, b4[] = {1, 8};
    c = base_cfg(15, 2, b3, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_OK);
    CHECK_DIAG(dg, -1, -1, -1);
    c = base_cfg(15, 2, b4, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_LINE_RANGE);
    CHECK_DIAG(dg, 1, -1, 8);
    /* largest legal bin for even P */
    const uint32_t b5[] = {0, 7};
    c = base_cfg(16, 2, b5, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_OK);
}

static void test_line_dup(void **state)
{
    (void)state;
    msid_design_diag_t dg;
    const uint32_t b1[] = {1, 5, 3, 5};
    msid_design_cfg c = base_cfg(32, 4, b1, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_LINE_DUP);
    CHECK_DIAG(dg, 1, 3, 5);
    const uint32_t b2[] = {0, 2, 0};
    c = base_cfg(32, 3, b2, 2, 2);
    UT_STATUS(try_design(&c, &dg), MSID_E_LINE_DUP);
    CHECK_DIAG(dg, 0, 2, 0);
}

static void test_dims_and_pattern(void **state)
{
    (void)state;
    const uint32_t b[] = {1, 2, 3};
    msid_design_cfg c = base_cfg(32, 3, b, 3, 2);
    UT_STATUS(try_design(&c, NULL), MSID_E_EXPERIMENTS);
    c = base_cfg(32, 3, b, 2, 3);
    c.pattern = MSID_PATTERN_HADAMARD;
    UT_STATUS(try_design(&c, NULL), MSID_E_PATTERN);
    c.n_experiments = 6;
    UT_STATUS(try_design(&c, NULL), MSID_E_PATTERN);
    c.n_experiments = 4;
    UT_STATUS(try_design(&c, NULL), MSID_OK);
    c.pattern = (msid_pattern)7;
    UT_STATUS(try_design(&c, NULL), MSID_E_PATTERN);
    c = base_cfg(32, 3, b, 0, 1);
    UT_STATUS(try_design(&c, NULL), MSID_E_DIMS);
    c = base_cfg(32, 3, b, MSID_MAX_INPUTS + 1u, MSID_MAX_EXPERIMENTS);
    UT_STATUS(try_design(&c, NULL), MSID_E_DIMS);
    c = base_cfg(32, 3, b, 1, MSID_MAX_EXPERIMENTS + 1u);
    UT_STATUS(try_design(&c, NULL), MSID_E_DIMS);
    c = base_cfg(32, 3, b, 1, 0);
    UT_STATUS(try_design(&c, NULL), MSID_E_DIMS);
    c = base_cfg(32, 0, b, 1, 1);
    UT_STATUS(try_design(&c, NULL), MSID_E_NO_LINES);
    c = base_cfg(32, 3, b, 1, 1);
    c.phase_mode = (msid_phase_mode)9;
    UT_STATUS(try_design(&c, NULL), MSID_E_ARG);
    c.phase_mode = MSID_PHASE_USER;
    c.phases = NULL;
    UT_STATUS(try_design(&c, NULL), MSID_E_NULL);
    c = base_cfg(32, 3, NULL, 1, 1);
    UT_STATUS(try_design(&c, NULL), MSID_E_NULL);
}

static void test_init_args_and_memory(void **state)
{
    (void)state;
    const uint32_t b[] = {1, 2, 3};
    msid_design_cfg c = base_cfg(32, 3, b, 2, 2);
    msid_twiddle tw, tw8;
    void *mt = tsim_alloc(msid_twiddle_mem_size(32)), *mt8 = tsim_alloc(msid_twiddle_mem_size(8));
    UT_STATUS(msid_twiddle_init(&tw, 32, mt, msid_twiddle_mem_size(32)), MSID_OK);
    UT_STATUS(msid_twiddle_init(&tw8, 8, mt8, msid_twiddle_mem_size(8)), MSID_OK);
    c.twiddle = &tw;
    const size_t need = msid_design_mem_size(&c);
    UT_CHECK(need > 0, "%zu", need);
    unsigned char *mem = (unsigned char *)tsim_alloc(need + 64);
    msid_design d;
    UT_STATUS(msid_design_init(NULL, &c, mem, need), MSID_E_NULL);
    UT_STATUS(msid_design_init(&d, NULL, mem, need), MSID_E_NULL);
    UT_STATUS(msid_design_init(&d, &c, NULL, need), MSID_E_NULL);
    UT_STATUS(msid_design_init(&d, &c, ut_misalign(mem), need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_design_init(&d, &c, mem, need - 1), MSID_E_MEM_SIZE);
    c.twiddle = &tw8;
    UT_STATUS(msid_design_init(&d, &c, mem, need), MSID_E_PERIOD);
    c.twiddle = NULL;
    UT_STATUS(msid_design_init(&d, &c, mem, need), MSID_E_NULL);
    c.twiddle = &tw;
    c.period = 1;
    UT_STATUS(msid_design_init(&d, &c, mem, need), MSID_E_PERIOD);
    UT_CHECK(msid_design_mem_size(&c) == 0, "%zu", msid_design_mem_size(&c));
    UT_CHECK(msid_design_mem_size(NULL) == 0, "%d", 0);
    c.period = 32;
    UT_STATUS(msid_design_init(&d, &c, mem + 64, need), MSID_OK);
    /* a failure followed by a success leaves no stale diagnostics */
    const uint32_t bad[] = {1, 1, 3};
    c.bins = bad;
    UT_STATUS(msid_design_init(&d, &c, mem, need), MSID_E_LINE_DUP);
    c.bins = b;
    UT_STATUS(msid_design_init(&d, &c, mem, need), MSID_OK);
    const msid_design_diag_t dg = msid_design_diag(&d);
    CHECK_DIAG(dg, -1, -1, -1);
    const msid_design_diag_t dn = msid_design_diag(NULL);
    CHECK_DIAG(dn, -1, -1, -1);
    /* out-of-range accessors */
    UT_CHECK(isnan(msid_design_cond(&d, 3)) && isnan(msid_design_crest_factor(&d, 2, 0)) &&
             isnan(msid_design_crest_factor(&d, 0, 2)) && isnan(msid_design_coef(&d, 0, 0, 3).re) &&
             isnan(msid_design_sample(&d, &tw8, 0, 0, 0)) && isnan(msid_design_sample(&d, &tw, 2, 0, 0)),
             "%d", 0);
    tsim_free(mem);
    tsim_free(mt);
    tsim_free(mt8);
}

static void test_amplitude_and_phase(void **state)
{
    (void)state;
    msid_design_diag_t dg;
    const uint32_t b[] = {2, 5, 9};
    const double a0[] = {1, 0, 1}, a1[] = {1, 1, -2}, a2[] = {NAN, 1, 1}, a3[] = {1, HUGE_VAL, 1};
    /* finite but beyond what the design's squares hold (1e308 was reported as a singular input matrix) */
    const double a4[] = {1, 1, 1e308}, a5[] = {1.01e150, 1, 1}, a6[] = {1, 0.99e-150, 1};
    const double *as[] = {a0, a1, a2, a3, a4, a5, a6};
    const int32_t bad[] = {1, 2, 0, 1, 2, 0, 1};
    for (int k = 0; k < 7; ++k) {
        msid_design_cfg c = base_cfg(32, 3, b, 1, 1);
        c.amplitudes = as[k];
        UT_STATUS(try_design(&c, &dg), MSID_E_AMPLITUDE);
        CHECK_DIAG(dg, bad[k], -1, b[bad[k]]);
    }
    /* per input: the bad value is input 1, line 2 */
    const double ap[] = {1, 2, 3, 1, 2, -1e-300};
    msid_design_cfg c = base_cfg(32, 3, b, 2, 2);
    c.amplitudes = ap;
    c.amp_per_input = 1;
    UT_STATUS(try_design(&c, &dg), MSID_E_AMPLITUDE);
    CHECK_DIAG(dg, 2, -1, 9);
    /* the ends of the range are designs */
    const double ends[] = {MSID_MAX_AMPLITUDE, 1, MSID_MIN_AMPLITUDE};
    c = base_cfg(32, 3, b, 1, 1);
    c.amplitudes = ends;
    UT_STATUS(try_design(&c, &dg), MSID_OK);
    /* user phases: NaN at input 1, line 0; +inf at input 0, line 2 */
    const double p0[] = {0.1, 0.2, 0.3, NAN, 0.5, 0.6}, p1[] = {0.1, 0.2, HUGE_VAL, 0.4, 0.5, 0.6};
    c = base_cfg(32, 3, b, 2, 2);
    c.phase_mode = MSID_PHASE_USER;
    c.phases = p0;
    UT_STATUS(try_design(&c, &dg), MSID_E_PHASE);
    CHECK_DIAG(dg, 0, -1, 2);
    c.phases = p1;
    UT_STATUS(try_design(&c, &dg), MSID_E_PHASE);
    CHECK_DIAG(dg, 2, -1, 9);
}

/* ---------------- condition numbers ---------------- */

/* Gram matrix U U^H of line l from the coefficients must be m diag(A_i^2): an
 * independent check of the pattern's orthogonality. */
static void check_gram(const msid_design *d, uint32_t l, const double *A)
{
    const uint32_t nu = d->n_inputs, m = d->n_experiments;
    for (uint32_t i = 0; i < nu; ++i)
        for (uint32_t j = 0; j < nu; ++j) {
            long double gr = 0.0L, gi = 0.0L;
            for (uint32_t e = 0; e < m; ++e) {
                const msid_cplx a = msid_design_coef(d, e, i, l), b = msid_design_coef(d, e, j, l);
                gr += (long double)a.re * b.re + (long double)a.im * b.im;
                gi += (long double)a.im * b.re - (long double)a.re * b.im;
            }
            const double want = i == j ? (double)m * A[i] * A[i] : 0.0;
            UT_CHECK(fabsl(gr - want) <= 1e-12 * m * A[i] * A[j] && fabsl(gi) <= 1e-12 * m * A[i] * A[j],
                     "nu=%u m=%u line %u (%u,%u): (%.3Lg, %.3Lg) want %g", nu, m, l, i, j, gr, gi, want);
        }
}

static void test_cond_equal_amplitudes(void **state)
{
    (void)state;
    const uint32_t b[] = {1, 2, 5, 7, 11, 15};
    const double ones[MSID_MAX_INPUTS] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};
    for (uint32_t nu = 2; nu <= 3; ++nu)
        for (int pat = 0; pat < 2; ++pat)
            for (uint32_t m = nu; m <= 8; ++m) {
                if (pat == 1 && (m & (m - 1u))) continue;
                msid_design_cfg c = base_cfg(32, 6, b, nu, m);
                c.pattern = pat ? MSID_PATTERN_HADAMARD : MSID_PATTERN_DFT;
                c.seed = 100u + m;
                tsim_design t;
                UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
                for (uint32_t l = 0; l < 6; ++l) {
                    const double k = msid_design_cond(&t.d, l);
                    UT_CHECK(k >= 1.0 && k - 1.0 <= 1e-12, "nu=%u m=%u pat=%d line %u cond-1=%.3g", nu, m, pat, l, k - 1.0);
                    check_gram(&t.d, l, ones);
                }
                UT_CHECK(t.d.cond_max - 1.0 <= 1e-12, "cond_max %.17g", t.d.cond_max);
                tsim_design_free(&t);
            }
}

static void test_cond_per_input_amplitudes(void **state)
{
    (void)state;
    const uint32_t b[] = {3, 4, 9, 10};
    const uint32_t L = 4, nu = 3;
    msid_rng r;
    msid_rng_seed(&r, 4242u);
    for (int trial = 0; trial < 6; ++trial) {
        double amp[3 * 4];
        for (int k = 0; k < 12; ++k) amp[k] = 0.2 + 4.8 * msid_rng_uniform(&r);
        msid_design_cfg c = base_cfg(64, L, b, nu, trial < 3 ? 3u + (uint32_t)trial : 4u);
        if (trial >= 3) c.pattern = MSID_PATTERN_HADAMARD;
        c.amplitudes = amp;
        c.amp_per_input = 1;
        c.seed = (uint64_t)trial;
        tsim_design t;
        UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
        double kmax = 0.0;
        for (uint32_t l = 0; l < L; ++l) {
            double lo = HUGE_VAL, hi = 0.0, A[3];
            for (uint32_t i = 0; i < nu; ++i) {
                A[i] = amp[i * L + l];
                lo = fmin(lo, A[i]);
                hi = fmax(hi, A[i]);
            }
            const double want = hi / lo, got = msid_design_cond(&t.d, l);
            UT_CHECK(fabs(got - want) <= 1e-12 * want, "trial %d line %u: cond %.17g want %.17g", trial, l, got, want);
            kmax = fmax(kmax, want);
            check_gram(&t.d, l, A);
            /* amplitudes are peak values: |c| = A */
            for (uint32_t e = 0; e < c.n_experiments; ++e)
                for (uint32_t i = 0; i < nu; ++i)
                    UT_CHECK(fabs(ut_cabs(msid_design_coef(&t.d, e, i, l)) - A[i]) <= 1e-15 * A[i], "|c| e=%u i=%u", e, i);
        }
        UT_CHECK(fabs(t.d.cond_max - kmax) <= 1e-12 * kmax, "cond_max %.17g want %.17g", t.d.cond_max, kmax);
        tsim_design_free(&t);
    }
}

/* The DC line carries Re(T) (a real input cannot take the complex DFT pattern):
 * its Gram matrix is diag(m, m/2) for the DFT pattern with nu = 2, m >= 3, so
 * cond = sqrt(2); with nu = 3, m = 3 rows 1 and 2 of Re(T) coincide and the
 * design is refused. The Hadamard pattern is real, so DC keeps cond = 1. */
static void test_dc_line_pattern(void **state)
{
    (void)state;
    msid_design_diag_t dg;
    const uint32_t b[] = {3, 0, 5};
    for (uint32_t m = 2; m <= 6; ++m) {
        msid_design_cfg c = base_cfg(32, 3, b, 2, m);
        tsim_design t;
        UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
        const double want = m == 2 ? 1.0 : sqrt(2.0);
        UT_CHECK(fabs(msid_design_cond(&t.d, 1) - want) <= 1e-12, "m=%u DC cond %.17g", m, msid_design_cond(&t.d, 1));
        UT_CHECK(fabs(msid_design_cond(&t.d, 0) - 1.0) <= 1e-12, "m=%u", m);
        for (uint32_t e = 0; e < m; ++e)
            for (uint32_t i = 0; i < 2; ++i) {
                const msid_cplx z = msid_design_coef(&t.d, e, i, 1);
                UT_CHECK(z.im == 0.0 && fabs(z.re - cos(UT_TWO_PI * pattern_turns(MSID_PATTERN_DFT, i, e, m))) <= 1e-15,
                         "DC coef e=%u i=%u (%.17g, %.17g)", e, i, z.re, z.im);
            }
        tsim_design_free(&t);
    }
    /* nu = m = 3: the real DFT basis 1, cos, sin keeps the DC matrix non-singular */
    msid_design_cfg c = base_cfg(32, 3, b, 3, 3);
    {
        tsim_design t3;
        UT_STATUS(tsim_design_make(&t3, &c), MSID_OK);
        UT_CHECK(fabs(msid_design_cond(&t3.d, 1) - sqrt(2.0)) <= 1e-12, "%.17g", msid_design_cond(&t3.d, 1));
        for (uint32_t e = 0; e < 3; ++e) {
            const msid_cplx z2 = msid_design_coef(&t3.d, e, 2, 1);
            UT_CHECK(z2.im == 0.0 && fabs(z2.re - sin(UT_TWO_PI * e / 3.0)) <= 1e-15, "e=%u sin row %.17g", e, z2.re);
        }
        tsim_design_free(&t3);
    }
    (void)dg;
    c = base_cfg(32, 3, b, 3, 4);
    c.pattern = MSID_PATTERN_HADAMARD;
    tsim_design t;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    UT_CHECK(fabs(msid_design_cond(&t.d, 1) - 1.0) <= 1e-12, "%.17g", msid_design_cond(&t.d, 1));
    tsim_design_free(&t);
}

/* ---------------- phases, crest factors, samples, DFT ---------------- */

/* Independent sample: sum_l A cos(2 pi (b n / P + phi + tau)) (DC: A cos(2 pi tau)). */
static long double indep_sample(const msid_design *d, uint32_t e, uint32_t i, uint32_t n, const double *amp, const double *ph)
{
    const uint32_t L = d->n_lines, P = d->period;
    long double u = 0.0L;
    for (uint32_t l = 0; l < L; ++l) {
        const double tau = pattern_turns(d->pattern, i, e, d->n_experiments);
        const uint64_t k = (uint64_t)d->bins[l] * n % P;
        const long double turns = d->bins[l] == 0 ? (long double)tau : (long double)k / P + ph[i * L + l] + tau;
        u += amp[i * L + l] * cosl(2.0L * UT_PI_L * turns);
    }
    return u;
}

/* Amplitudes whose squares overflow (1e200): before, sum A^2 = inf made every Schroeder p_j NaN and
 * the NaN phase was cast to int (undefined behaviour, found by fuzz_can_config; this test fails under
 * the UBSan build of scripts/sanitize.sh without the fix). Such a design is refused as singular;
 * amplitudes that only look large (1e150: squares 1e300) keep the unit case's crest factor. */
static void test_schroeder_huge_amplitudes(void **state)
{
    (void)state;
    uint32_t b[16];
    double amp[16];
    double cf[2];
    const double scale[3] = {1.0, 1e149, 1e200};   /* 1e149 x (1 + 0.1 l) <= MSID_MAX_AMPLITUDE */
    for (int k = 0; k < 3; ++k) {
        for (uint32_t l = 0; l < 16; ++l) { b[l] = 1 + l; amp[l] = scale[k] * (1.0 + 0.1 * l); }
        msid_design_cfg c = base_cfg(256, 16, b, 1, 1);
        c.phase_mode = MSID_PHASE_SCHROEDER;
        c.amplitudes = amp;
        tsim_design t = {0};
        if (k == 2) {   /* beyond MSID_MAX_AMPLITUDE: named as the amplitude, not as a singular matrix */
            UT_STATUS(tsim_design_make(&t, &c), MSID_E_AMPLITUDE);
            tsim_design_free(&t);
            continue;
        }
        UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
        cf[k] = msid_design_crest_factor(&t.d, 0, 0);
        tsim_design_free(&t);
    }
    UT_CHECK(isfinite(cf[1]) && fabs(cf[1] - cf[0]) < 1e-9 * cf[0], "crest %.17g against %.17g", cf[1], cf[0]);
}

static void test_schroeder_crest(void **state)
{
    (void)state;
    uint32_t b[64];
    for (uint32_t l = 0; l < 64; ++l) b[l] = 1 + l;
    msid_design_cfg c = base_cfg(1024, 64, b, 1, 1);
    c.phase_mode = MSID_PHASE_SCHROEDER;
    tsim_design t;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    const double cs = msid_design_crest_factor(&t.d, 0, 0);
    UT_CHECK(cs >= 1.0 && cs < 2.0, "Schroeder crest %.4f", cs);
    tsim_design_free(&t);
    /* a second block of consecutive lines, 2 inputs */
    for (uint32_t l = 0; l < 64; ++l) b[l] = 40 + l;
    c = base_cfg(1000, 64, b, 2, 2);
    c.phase_mode = MSID_PHASE_SCHROEDER;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    for (uint32_t e = 0; e < 2; ++e)
        for (uint32_t i = 0; i < 2; ++i)
            UT_CHECK(msid_design_crest_factor(&t.d, e, i) < 2.0, "e=%u i=%u crest %.4f", e, i, msid_design_crest_factor(&t.d, e, i));
    tsim_design_free(&t);
    for (uint32_t l = 0; l < 64; ++l) b[l] = 1 + l;
    double sum = 0.0;
    const int N = 20;
    for (int s = 0; s < N; ++s) {
        c = base_cfg(1024, 64, b, 1, 1);
        c.phase_mode = MSID_PHASE_RANDOM;
        c.seed = 1000u + (uint64_t)s;
        UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
        sum += msid_design_crest_factor(&t.d, 0, 0);
        tsim_design_free(&t);
    }
    UT_CHECK(sum / N > cs + 0.5 && sum / N > 2.0, "random-phase mean crest %.4f vs Schroeder %.4f", sum / N, cs);
}

static void test_phase_modes(void **state)
{
    (void)state;
    const uint32_t b[] = {1, 2, 3, 4, 6};
    /* user phases are stored reduced to [0,1) turns, DC gets none */
    const double ph[] = {0.25, -0.125, 3.5, 0.75, 1.0, 0.0, 0.5, -7.25, 0.1, 0.9};
    msid_design_cfg c = base_cfg(32, 5, b, 2, 2);
    c.phase_mode = MSID_PHASE_USER;
    c.phases = ph;
    tsim_design t;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    for (int k = 0; k < 10; ++k) {
        const double want = ph[k] - floor(ph[k]);
        UT_CHECK(t.d.phase[k] == want, "phase[%d] %.17g want %.17g", k, t.d.phase[k], want);
    }
    tsim_design_free(&t);
    /* random phases: reproducible per seed, different between seeds, in [0,1) */
    c = base_cfg(32, 5, b, 2, 2);
    tsim_design t2, t3;
    c.seed = 5;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    UT_STATUS(tsim_design_make(&t2, &c), MSID_OK);
    c.seed = 6;
    UT_STATUS(tsim_design_make(&t3, &c), MSID_OK);
    UT_CHECK(memcmp(t.d.phase, t2.d.phase, 10 * sizeof(double)) == 0, "%d", 0);
    int differ = 0;
    for (int k = 0; k < 10; ++k) {
        differ += t.d.phase[k] != t3.d.phase[k];
        UT_CHECK(t.d.phase[k] >= 0.0 && t.d.phase[k] < 1.0, "%g", t.d.phase[k]);
    }
    UT_CHECK(differ == 10, "%d phases equal across seeds", 10 - differ);
    tsim_design_free(&t);
    tsim_design_free(&t2);
    tsim_design_free(&t3);
}

static void test_crest_and_samples(void **state)
{
    (void)state;
    const uint32_t b[] = {0, 1, 4, 7, 13, 20};
    const uint32_t L = 6, P = 60, nu = 2, m = 3;
    double amp[12];
    for (int k = 0; k < 12; ++k) amp[k] = 0.5 + 0.1 * k;
    for (int pm = 0; pm < 2; ++pm) {
        msid_design_cfg c = base_cfg(P, L, b, nu, m);
        c.amplitudes = amp;
        c.amp_per_input = 1;
        c.phase_mode = pm ? MSID_PHASE_SCHROEDER : MSID_PHASE_RANDOM;
        c.seed = 77;
        tsim_design t;
        UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
        for (uint32_t e = 0; e < m; ++e)
            for (uint32_t i = 0; i < nu; ++i) {
                long double peak = 0.0L, ss = 0.0L, asum = 0.0L;
                for (uint32_t l = 0; l < L; ++l) asum += amp[i * L + l];
                for (uint32_t n = 0; n < P; ++n) {
                    const double u = msid_design_sample(&t.d, &t.tw, e, i, n);
                    const long double ref = indep_sample(&t.d, e, i, n, amp, t.d.phase);
                    UT_CHECK(fabsl(u - ref) <= 1e-12L * asum, "e=%u i=%u n=%u: %.17g vs %.17Lg", e, i, n, u, ref);
                    /* n is taken mod P */
                    const double u2 = msid_design_sample(&t.d, &t.tw, e, i, n + 5 * P);
                    UT_CHECK(memcmp(&u, &u2, sizeof u) == 0, "n=%u", n);
                    peak = fmaxl(peak, fabsl((long double)u));
                    ss += (long double)u * u;
                }
                const double want = (double)(peak / sqrtl(ss / P)), got = msid_design_crest_factor(&t.d, e, i);
                UT_CHECK(fabs(got - want) <= 1e-12 * want, "e=%u i=%u crest %.17g want %.17g", e, i, got, want);
            }
        tsim_design_free(&t);
    }
}

/* Crest factors by two real DFTs (MSID_CREST_FFT, O(m nu P log P)) equal direct synthesis
 * up to rounding, for odd and even P with a DC line; MSID_CREST_NONE leaves them NaN; an FFT of the
 * wrong length or none is refused. Deterministic: two inits give the same bits. */
static void test_crest_fft_equals_direct(void **state)
{
    (void)state;
#ifdef MSID_HAVE_FFTW
    const uint32_t b[] = {0, 1, 4, 7, 13, 20};
    const uint32_t Ps[] = {60, 61, 4096};
    for (int k = 0; k < 3; ++k) {
        const uint32_t P = Ps[k];
        msid_design_cfg c = base_cfg(P, 6, b, 2, 3);
        c.phase_mode = MSID_PHASE_RANDOM;
        c.seed = 77;
        tsim_design direct, fft, fft2, none;
        UT_STATUS(tsim_design_make(&direct, &c), MSID_OK);
        msid_fft_fftw fw;
        UT_STATUS(msid_fft_fftw_create(&fw, P, MSID_FFTW_ESTIMATE), MSID_OK);
        c.crest = MSID_CREST_FFT;
        c.fft = &fw.be;
        UT_STATUS(tsim_design_make(&fft, &c), MSID_OK);
        UT_STATUS(tsim_design_make(&fft2, &c), MSID_OK);
        for (uint32_t e = 0; e < 3; ++e)
            for (uint32_t i = 0; i < 2; ++i) {
                const double x = msid_design_crest_factor(&direct.d, e, i), y = msid_design_crest_factor(&fft.d, e, i);
                const double y2 = msid_design_crest_factor(&fft2.d, e, i);
                UT_CHECK(fabs(x - y) <= 1e-13 * x && memcmp(&y, &y2, sizeof y) == 0, "P=%u e=%u i=%u: %.17g vs %.17g", P,
                         e, i, x, y);
            }
        c.crest = MSID_CREST_NONE;
        UT_STATUS(tsim_design_make(&none, &c), MSID_OK);
        UT_CHECK(isnan(msid_design_crest_factor(&none.d, 0, 0)), "NONE at P=%u", P);
        tsim_design_free(&none);
        c.crest = MSID_CREST_FFT;
        c.fft = NULL;
        UT_STATUS(tsim_design_make(&none, &c), MSID_E_NULL);
        tsim_design_free(&none);
        tsim_design_free(&direct);
        tsim_design_free(&fft);
        tsim_design_free(&fft2);
        msid_fft_fftw_destroy(&fw);
    }
    msid_fft_fftw wrong;
    UT_STATUS(msid_fft_fftw_create(&wrong, 64, MSID_FFTW_ESTIMATE), MSID_OK);
    msid_design_cfg c = base_cfg(60, 6, b, 2, 3);
    c.crest = MSID_CREST_FFT;
    c.fft = &wrong.be;
    tsim_design t;
    UT_STATUS(tsim_design_make(&t, &c), MSID_E_BACKEND);
    tsim_design_free(&t);
    msid_fft_fftw_destroy(&wrong);
#endif
}

static void test_input_dft_vs_naive(void **state)
{
    (void)state;
    const uint32_t b[] = {0, 1, 4, 7, 14};
    const uint32_t L = 5, P = 30, nu = 2, m = 3;
    const double amp[] = {1.0, 0.3, 2.0, 0.7, 1.1};
    long double *tw = ut_tw_table(P);
    for (int pat = 0; pat < 2; ++pat) {
        msid_design_cfg c = base_cfg(P, L, b, nu, pat ? 4u : m);
        c.pattern = pat ? MSID_PATTERN_HADAMARD : MSID_PATTERN_DFT;
        c.amplitudes = amp;
        c.seed = 9;
        tsim_design t;
        UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
        for (uint32_t e = 0; e < c.n_experiments; ++e)
            for (uint32_t i = 0; i < nu; ++i) {
                double x[30];
                for (uint32_t n = 0; n < P; ++n) x[n] = msid_design_sample(&t.d, &t.tw, e, i, n);
                for (uint32_t l = 0; l < L; ++l) {
                    long double re, im;
                    ut_dft_ld(x, 1, P, b[l], tw, &re, &im);
                    const msid_cplx X = msid_design_input_dft(&t.d, e, i, l);
                    const long double mag = sqrtl(re * re + im * im);
                    const double err = (double)sqrtl((X.re - re) * (X.re - re) + (X.im - im) * (X.im - im));
                    UT_CHECK(mag > 0.1L && err <= 1e-9 * (double)mag, "pat %d e=%u i=%u l=%u: (%.12g,%.12g) vs (%.12Lg,%.12Lg)",
                             pat, e, i, l, X.re, X.im, re, im);
                    if (b[l] == 0) UT_CHECK(X.im == 0.0, "DC imag %.3g", X.im);
                }
                /* no energy off the lines */
                for (uint32_t k = 0; k <= P / 2; ++k) {
                    int excited = 0;
                    for (uint32_t l = 0; l < L; ++l) excited |= b[l] == k;
                    if (excited) continue;
                    long double re, im;
                    ut_dft_ld(x, 1, P, k, tw, &re, &im);
                    UT_CHECK(sqrtl(re * re + im * im) <= 1e-12L * P, "bin %u leaks %.3Lg", k, sqrtl(re * re + im * im));
                }
            }
        tsim_design_free(&t);
    }
    free(tw);
}

/* ---------------- continuous-time designs ---------------- */

static msid_design_cfg ct_cfg(uint32_t P, double h, uint32_t L, const double *omega, uint32_t nu, uint32_t m)
{
    msid_design_cfg c = base_cfg(P, L, NULL, nu, m);
    c.omega = omega;
    c.sample_time = h;
    return c;
}

/* Expected outcome of the aliasing map, computed independently from the
 * integer number of cycles k_l = omega_l P h / (2 pi) of every line. */
static msid_status expect_alias(const uint64_t *k, uint32_t L, uint32_t P, uint32_t *bins, uint8_t *fold, msid_design_diag_t *dg)
{
    dg->line_a = dg->line_b = -1;
    dg->bin = -1;
    for (uint32_t l = 0; l < L; ++l) {
        const uint64_t d = k[l] % P;
        if (k[l] != 0 && d == 0) { dg->line_a = (int32_t)l; dg->bin = 0; return MSID_E_ALIAS_EDGE; }
        if (2 * d == P) { dg->line_a = (int32_t)l; dg->bin = (int64_t)d; return MSID_E_ALIAS_EDGE; }
        bins[l] = (uint32_t)(2 * d < P ? d : P - d);
        fold[l] = 2 * d > P;
        for (uint32_t j = 0; j < l; ++j)
            if (bins[j] == bins[l]) { dg->line_a = (int32_t)j; dg->line_b = (int32_t)l; dg->bin = bins[l]; return MSID_E_ALIAS_COLLISION; }
    }
    return MSID_OK;
}

static void test_ct_alias_map_random(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 8675309u);
    int n_ok = 0, n_coll = 0, n_edge = 0, n_fold = 0;
    for (int trial = 0; trial < 400; ++trial) {
        const uint32_t P = ut_randint(&r, 4, 64);
        const uint32_t L = ut_randint(&r, 1, P / 2 < 6 ? P / 2 : 6);
        const double h = 1e-4 * pow(10.0, 4.0 * msid_rng_uniform(&r));
        uint64_t k[6];
        double omega[6];
        for (uint32_t l = 0; l < L; ++l) {
            /* up to 5 sample rates: aliasing well beyond Nyquist; sometimes DC */
            k[l] = (msid_rng_u64(&r) % 16 == 0) ? 0u : 1u + msid_rng_u64(&r) % (5u * P);
            omega[l] = UT_TWO_PI * (double)k[l] / ((double)P * h);
        }
        uint32_t bins[6];
        uint8_t fold[6];
        msid_design_diag_t want, got;
        const msid_status ws = expect_alias(k, L, P, bins, fold, &want);
        msid_design_cfg c = ct_cfg(P, h, L, omega, 1, 1);
        tsim_design t;
        const msid_status st = tsim_design_make(&t, &c);
        got = msid_design_diag(&t.d);
        UT_CHECK(st == ws, "trial %d P=%u: status %d want %d", trial, P, (int)st, (int)ws);
        CHECK_DIAG(got, want.line_a, want.line_b, want.bin);
        if (st == MSID_OK) {
            ++n_ok;
            UT_CHECK(t.d.is_ct == 1 && t.d.sample_time == h, "trial %d", trial);
            for (uint32_t l = 0; l < L; ++l) {
                UT_CHECK(t.d.bins[l] == bins[l] && t.d.folded[l] == fold[l] && t.d.omega[l] == omega[l],
                         "trial %d line %u: bin %u fold %u, want %u %u", trial, l, t.d.bins[l], t.d.folded[l], bins[l], fold[l]);
                n_fold += fold[l];
            }
        } else if (st == MSID_E_ALIAS_COLLISION) {
            ++n_coll;
        } else {
            ++n_edge;
        }
        tsim_design_free(&t);
    }
    /* the random cases exercised every branch */
    UT_CHECK(n_ok > 50 && n_coll > 10 && n_edge > 10 && n_fold > 50, "ok %d coll %d edge %d folds %d", n_ok, n_coll, n_edge, n_fold);
}

/* Every sample of a CT design equals A cos(omega n h + 2 pi (phi + tau)) with libm. */
static void check_ct_samples(const tsim_design *t, const double *omega, const double *amp, const double *ph)
{
    const msid_design *d = &t->d;
    const uint32_t L = d->n_lines, P = d->period, nu = d->n_inputs, m = d->n_experiments;
    const double h = d->sample_time;
    for (uint32_t e = 0; e < m; ++e) {
        msid_gen g;
        msid_gen_cfg gc = {d, &t->tw, e, 0};
        void *mem = tsim_alloc(msid_gen_mem_size(&gc));
        UT_STATUS(msid_gen_init(&g, &gc, mem, msid_gen_mem_size(&gc)), MSID_OK);
        for (uint32_t n = 0; n < 3 * P; ++n) {
            double u[MSID_MAX_INPUTS];
            msid_gen_next(&g, u);
            for (uint32_t i = 0; i < nu; ++i) {
                long double ref = 0.0L, asum = 0.0L;
                const double tau = pattern_turns(d->pattern, i, e, m);
                for (uint32_t l = 0; l < L; ++l) {
                    const double phi = omega[l] == 0.0 ? 0.0 : ph[i * L + l];
                    const double A = amp[i * L + l];
                    ref += A * cosl((long double)omega[l] * n * h + 2.0L * UT_PI_L * (phi + tau));
                    asum += A;
                }
                UT_CHECK(fabsl(u[i] - ref) <= 1e-12L * asum, "e=%u i=%u n=%u: %.15g vs %.15Lg", e, i, n, u[i], ref);
            }
        }
        tsim_free(mem);
    }
}

static void test_ct_gonzalez_fig1(void **state)
{
    (void)state;
    const double PI = UT_TWO_PI / 2.0;
    /* h = 4/7, P = 7: P h = 4 s, the lines make 0, 2 and 10 cycles: bins 0, 2, 3.
     * 5 pi rad/s is above the Nyquist rate pi/h = 7 pi/4 and aliases to
     * 10/7 -> +3/7 cycle/sample: same sign, so it is NOT conjugated.
     * 3 pi rad/s makes 6 cycles -> 6/7 -> -1/7: folds to bin 1, conjugated. */
    const double w4[] = {0.0, PI, 5.0 * PI, 3.0 * PI};
    const double ph[] = {0.0, 0.1, 0.35, 0.8};
    const double amp[] = {0.5, 1.0, 0.7, 1.3};
    msid_design_cfg c = ct_cfg(7, 4.0 / 7.0, 3, w4, 1, 1);
    c.phase_mode = MSID_PHASE_USER;
    c.phases = ph;
    c.amplitudes = amp;
    tsim_design t;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    UT_CHECK(t.d.bins[0] == 0 && t.d.bins[1] == 2 && t.d.bins[2] == 3, "bins %u %u %u", t.d.bins[0], t.d.bins[1], t.d.bins[2]);
    UT_CHECK(t.d.folded[0] == 0 && t.d.folded[1] == 0 && t.d.folded[2] == 0, "folded %u %u %u", t.d.folded[0], t.d.folded[1], t.d.folded[2]);
    check_ct_samples(&t, w4, amp, ph);
    tsim_design_free(&t);
    c.n_lines = 4;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    UT_CHECK(t.d.bins[3] == 1 && t.d.folded[3] == 1, "bin %u folded %u", t.d.bins[3], t.d.folded[3]);
    check_ct_samples(&t, w4, amp, ph);
    tsim_design_free(&t);
    /* h = 1/2, P = 4: pi h = pi/2 and 5 pi h = 5 pi/2 are both 1/4 cycle/sample:
     * bin 1 twice, a collision (neither is at DC or Nyquist) between lines 1 and 2. */
    msid_design_diag_t dg;
    c = ct_cfg(4, 0.5, 3, w4, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_ALIAS_COLLISION);
    CHECK_DIAG(dg, 1, 2, 1);
}

static void test_ct_edges_and_periodicity(void **state)
{
    (void)state;
    const double PI = UT_TWO_PI / 2.0;
    msid_design_diag_t dg;
    /* P = 8, h = 1: 2 pi makes 8 cycles -> DC; pi and 3 pi make 4 and 12 -> Nyquist */
    const double wdc[] = {UT_TWO_PI / 8.0, UT_TWO_PI}, wny[] = {PI}, wny3[] = {UT_TWO_PI / 8.0, 0.0, 3.0 * PI};
    msid_design_cfg c = ct_cfg(8, 1.0, 2, wdc, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_ALIAS_EDGE);
    CHECK_DIAG(dg, 1, -1, 0);
    c = ct_cfg(8, 1.0, 1, wny, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_ALIAS_EDGE);
    CHECK_DIAG(dg, 0, -1, 4);
    c = ct_cfg(8, 1.0, 3, wny3, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_ALIAS_EDGE);
    CHECK_DIAG(dg, 2, -1, 4);
    /* two DC lines collide */
    const double w00[] = {0.0, UT_TWO_PI / 8.0, 0.0};
    c = ct_cfg(8, 1.0, 3, w00, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_ALIAS_COLLISION);
    CHECK_DIAG(dg, 0, 2, 0);
    /* P h overflows (h = 1e308): a DC line would make 0 * inf = NaN cycles, cast to an integer (UBSan,
       fuzz_core_cfg seed regress-ct-span-overflow); the sample time is refused first. A NaN cycle count is
       never periodic either (the comparisons are NaN-safe). */
    const double wdc0[] = {0.0};
    c = ct_cfg(8, 1e308, 1, wdc0, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_SAMPLE_TIME);
    /* not a whole number of cycles in P h */
    const double wnp[] = {UT_TWO_PI / 8.0, 1.0};
    c = ct_cfg(8, 1.0, 2, wnp, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_CT_NOT_PERIODIC);
    CHECK_DIAG(dg, 1, -1, -1);
    /* tolerance: 1e-8 cycles off passes the default 1e-6, fails ct_tol = 1e-9 */
    const double woff[] = {UT_TWO_PI * (3.0 + 1e-8) / 8.0};
    c = ct_cfg(8, 1.0, 1, woff, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_OK);
    c.ct_tol = 1e-9;
    UT_STATUS(try_design(&c, &dg), MSID_E_CT_NOT_PERIODIC);
    CHECK_DIAG(dg, 0, -1, -1);
    /* sample time and omega validity */
    const double w1[] = {UT_TWO_PI / 8.0, -1.0}, wn[] = {NAN};
    const double hs[] = {0.0, -1.0, NAN, HUGE_VAL};
    for (int k = 0; k < 4; ++k) {
        c = ct_cfg(8, hs[k], 1, w1, 1, 1);
        UT_STATUS(try_design(&c, NULL), MSID_E_SAMPLE_TIME);
    }
    c = ct_cfg(8, 1.0, 2, w1, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_ARG);
    CHECK_DIAG(dg, 1, -1, -1);
    c = ct_cfg(8, 1.0, 1, wn, 1, 1);
    UT_STATUS(try_design(&c, &dg), MSID_E_ARG);
}

static void test_ct_folded_samples_mimo(void **state)
{
    (void)state;
    /* P = 16, h = 0.01: k = 3, 21, 30, 44 cycles -> bins 3, 5, 2 (folded), 4 (folded) */
    const uint32_t P = 16, L = 4;
    const double h = 0.01;
    const double kc[] = {3, 21, 30, 44};
    double omega[4];
    for (int l = 0; l < 4; ++l) omega[l] = UT_TWO_PI * kc[l] / (P * h);
    const double ph[] = {0.1, 0.2, 0.3, 0.45, 0.6, 0.05, 0.9, 0.33};
    const double amp[] = {1.0, 0.5, 0.8, 1.2, 0.9, 1.1, 0.4, 0.6};
    for (int pat = 0; pat < 2; ++pat) {
        msid_design_cfg c = ct_cfg(P, h, L, omega, 2, pat ? 2u : 3u);
        c.pattern = pat ? MSID_PATTERN_HADAMARD : MSID_PATTERN_DFT;
        c.phase_mode = MSID_PHASE_USER;
        c.phases = ph;
        c.amplitudes = amp;
        c.amp_per_input = 1;
        tsim_design t;
        UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
        const uint32_t wb[] = {3, 5, 2, 4};
        const uint8_t wf[] = {0, 0, 1, 1};
        for (uint32_t l = 0; l < L; ++l)
            UT_CHECK(t.d.bins[l] == wb[l] && t.d.folded[l] == wf[l], "line %u bin %u folded %u", l, t.d.bins[l], t.d.folded[l]);
        check_ct_samples(&t, omega, amp, ph);
        /* cond stays 1-like with folding (conjugation keeps rows orthogonal) */
        for (uint32_t l = 0; l < L; ++l) {
            const double want = fmax(amp[l], amp[L + l]) / fmin(amp[l], amp[L + l]);
            UT_CHECK(fabs(msid_design_cond(&t.d, l) - want) <= 1e-12 * want, "line %u", l);
        }
        tsim_design_free(&t);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_line_range),
        cmocka_unit_test(test_line_dup),
        cmocka_unit_test(test_dims_and_pattern),
        cmocka_unit_test(test_init_args_and_memory),
        cmocka_unit_test(test_amplitude_and_phase),
        cmocka_unit_test(test_cond_equal_amplitudes),
        cmocka_unit_test(test_cond_per_input_amplitudes),
        cmocka_unit_test(test_dc_line_pattern),
        cmocka_unit_test(test_schroeder_crest),
        cmocka_unit_test(test_phase_modes),
        cmocka_unit_test(test_crest_and_samples),
        cmocka_unit_test(test_crest_fft_equals_direct),
        cmocka_unit_test(test_input_dft_vs_naive),
        cmocka_unit_test(test_ct_alias_map_random),
        cmocka_unit_test(test_schroeder_huge_amplitudes),
        cmocka_unit_test(test_ct_gonzalez_fig1),
        cmocka_unit_test(test_ct_edges_and_periodicity),
        cmocka_unit_test(test_ct_folded_samples_mimo),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
