/* Helpers shared by the unit tests: checks with messages, independent
 * long-double references (naive DFT, exact twiddles), small utilities.
 * Header-only so each test stays one executable. */
#ifndef MSID_UNIT_UTIL_H
#define MSID_UNIT_UTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>
#include <stdlib.h>

#include "msid_test_sim.h"

#define UT_PI_L 3.141592653589793238462643383279502884L
#define UT_TWO_PI 6.283185307179586476925286766559005768
#define UT_SQRT1_2 0.70710678118654752440

/* Fail with a formatted message when cond is false. fmt needs >= 1 argument. */
#define UT_CHECK(cond, fmt, ...)                                                        \
    do {                                                                                \
        if (!(cond)) {                                                                  \
            print_error("%s:%d: check failed: %s: " fmt "\n", __FILE__, __LINE__, #cond, \
                        __VA_ARGS__);                                                   \
            fail();                                                                     \
        }                                                                               \
    } while (0)

#define UT_STATUS(expr, want)                                                          \
    do {                                                                               \
        const msid_status ut_st_ = (expr);                                             \
        if (ut_st_ != (want)) {                                                        \
            print_error("%s:%d: %s returned %d (%s), expected %d (%s)\n", __FILE__,    \
                        __LINE__, #expr, (int)ut_st_, msid_strerror(ut_st_), (int)(want), \
                        msid_strerror(want));                                          \
            fail();                                                                    \
        }                                                                              \
    } while (0)

/* A deliberately misaligned pointer inside an aligned block. */
static inline void *ut_misalign(void *p) { return (unsigned char *)p + 8; }

static inline size_t ut_round64(size_t n) { return (n + 63u) & ~(size_t)63u; }

/* exp(-j 2 pi k / P) in long double, k reduced in integers first. */
static inline void ut_tw_ld(uint64_t k, uint32_t P, long double *re, long double *im)
{
    const long double a = 2.0L * UT_PI_L * (long double)(k % P) / (long double)P;
    *re = cosl(a);
    *im = -sinl(a);
}

/* Long-double twiddle table of period P (caller frees): [2*P] re, im interleaved. */
static inline long double *ut_tw_table(uint32_t P)
{
    long double *t = (long double *)malloc(sizeof(long double) * 2u * P);
    for (uint32_t k = 0; k < P; ++k) ut_tw_ld(k, P, &t[2 * k], &t[2 * k + 1]);
    return t;
}

/* Naive DFT of one period at bin b: X = sum_n x[n*stride] exp(-j 2 pi b n / P). */
static inline void ut_dft_ld(const double *x, size_t stride, uint32_t P, uint32_t b,
                             const long double *tw, long double *re, long double *im)
{
    long double r = 0.0L, q = 0.0L;
    uint64_t k = 0;
    for (uint32_t n = 0; n < P; ++n) {
        const long double v = (long double)x[(size_t)n * stride];
        r += v * tw[2 * k];
        q += v * tw[2 * k + 1];
        k += b;
        if (k >= P) k -= P;
    }
    *re = r;
    *im = q;
}

/* Design config with P, L lines at bins, nu inputs, m experiments; every other
 * field zero: MSID_PHASE_RANDOM with seed 0, MSID_PATTERN_DFT, twiddle set by
 * tsim_design_make. */
static inline msid_design_cfg ut_design_cfg(uint32_t P, uint32_t L, const uint32_t *bins, uint32_t nu, uint32_t m)
{
    msid_design_cfg c;
    memset(&c, 0, sizeof c);
    c.period = P;
    c.n_lines = L;
    c.bins = bins;
    c.n_inputs = nu;
    c.n_experiments = m;
    return c;
}

static inline double ut_cabs(msid_cplx z) { return hypot(z.re, z.im); }
static inline double ut_cdist(msid_cplx a, msid_cplx b) { return hypot(a.re - b.re, a.im - b.im); }
static inline msid_cplx ut_c(double re, double im) { msid_cplx z; z.re = re; z.im = im; return z; }
static inline msid_cplx ut_cmul(msid_cplx a, msid_cplx b)
{
    return ut_c(a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re);
}

/* Draw k distinct values from [lo, hi] into out (hi - lo + 1 >= k). */
static inline void ut_distinct(msid_rng *r, uint32_t k, uint32_t lo, uint32_t hi, uint32_t *out)
{
    for (uint32_t i = 0; i < k;) {
        const uint32_t v = lo + (uint32_t)(msid_rng_u64(r) % ((uint64_t)hi - lo + 1u));
        int dup = 0;
        for (uint32_t j = 0; j < i; ++j) dup |= out[j] == v;
        if (!dup) out[i++] = v;
    }
}

/* Uniform integer in [lo, hi]. */
static inline uint32_t ut_randint(msid_rng *r, uint32_t lo, uint32_t hi)
{
    return lo + (uint32_t)(msid_rng_u64(r) % ((uint64_t)hi - lo + 1u));
}

#endif
