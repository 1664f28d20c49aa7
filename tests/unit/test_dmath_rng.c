/* Deterministic elementary functions (msid_cis_turns, msid_log, msid_sqrt)
 * against long-double libm, and the seeded generator (msid_rng) against an
 * independent xoshiro256** / splitmix64 reference and moment checks. */
#include "unit_util.h"
#include <float.h>

/* ---------- msid_cis_turns ---------- */

/* Reference cos/sin(2 pi t): t reduced exactly in long double (64-bit
 * mantissa holds every fraction of a double with |t| <= 1e6), then cosl/sinl. */
static void ref_cis(double t, long double *c, long double *s)
{
    const long double tl = (long double)t;
    const long double fr = tl - floorl(tl);
    *c = cosl(2.0L * UT_PI_L * fr);
    *s = sinl(2.0L * UT_PI_L * fr);
}

static void check_cis(double t, double tol)
{
    double c = 7.0, s = 7.0;
    long double rc, rs;
    msid_cis_turns(t, &c, &s);
    ref_cis(t, &rc, &rs);
    const double ec = (double)fabsl((long double)c - rc), es = (double)fabsl((long double)s - rs);
    UT_CHECK(ec <= tol && es <= tol, "t=%.17g: c=%.17g (err %.3g) s=%.17g (err %.3g)", t, c, ec, s, es);
}

static void test_cis_random(void **state)
{
    (void)state;
#if LDBL_MANT_DIG <= DBL_MANT_DIG
    /* ref_cis needs a wider long double (see there): where it is double (32-bit ARM) its own rounding
     * exceeds the tolerance (armhf under qemu-arm: 6.34e-16 at t = -0.00022434547143841343).
     * target_linux_bits requires msid_cis_turns's bits to equal the x86-64 build's there. */
    skip();
#endif
    msid_rng r;
    msid_rng_seed(&r, 20240601u);
    for (int i = 0; i < 400000; ++i) {
        const double u = msid_rng_uniform(&r) - 0.5;
        double t;
        switch (i % 6) {
        case 0: t = 8.0 * u; break;                       /* a few turns, both signs */
        case 1: t = 2.0e6 * u; break;                     /* |t| up to 1e6 */
        case 2: t = 2.0e-3 * u; break;                    /* near 0, both signs */
        case 3: t = floor(2000.0 * u) + 1e-9 * u; break;  /* just either side of integers */
        case 4: t = -msid_rng_uniform(&r); break;         /* (-1, 0] */
        default: t = 1.0e6 * u + 0.25 * (double)(i % 4) + 1e-12 * u; break;
        }
        check_cis(t, 4e-16);
    }
    /* n/P for odd and even P, as the twiddle table uses them */
    for (uint32_t n = 0; n < 1023; ++n) check_cis((double)n / 1023.0, 4e-16);
}

static void test_cis_exact_points(void **state)
{
    (void)state;
    /* quarter turns: exact 0 and +-1 */
    const double cq[4] = {1.0, 0.0, -1.0, 0.0}, sq[4] = {0.0, 1.0, 0.0, -1.0};
    const double bases[] = {0.0, 1.0, -1.0, 7.0, -3.0, 1e6, -1e6, 123456.0};
    for (size_t b = 0; b < sizeof bases / sizeof bases[0]; ++b) {
        for (int k = 0; k < 4; ++k) {
            for (int sign = -1; sign <= 1; sign += 2) {
                /* t = base + k/4 and base - (4-k)/4 land on the same point */
                const double t = sign > 0 ? bases[b] + 0.25 * k : bases[b] - 0.25 * (4 - k);
                double c, s;
                msid_cis_turns(t, &c, &s);
                UT_CHECK(c == cq[k] && s == sq[k], "t=%.17g: (%.17g, %.17g) want (%g, %g)", t, c, s, cq[k], sq[k]);
            }
        }
        /* odd eighths: +-sqrt(1/2), correctly rounded, |c| == |s| */
        for (int k = 1; k < 8; k += 2) {
            const double t = bases[b] + 0.125 * k;
            double c, s;
            msid_cis_turns(t, &c, &s);
            const double wc = (k == 1 || k == 7) ? UT_SQRT1_2 : -UT_SQRT1_2;
            const double ws = (k == 1 || k == 3) ? UT_SQRT1_2 : -UT_SQRT1_2;
            UT_CHECK(c == wc && s == ws, "t=%.17g: (%.17g, %.17g) want (%.17g, %.17g)", t, c, s, wc, ws);
        }
    }
    UT_CHECK(UT_SQRT1_2 == sqrt(0.5), "constant %.17g", UT_SQRT1_2);
}

static void test_cis_null_outputs(void **state)
{
    (void)state;
    double c0, s0, c1 = 0.0, s1 = 0.0;
    msid_cis_turns(0.3, &c0, &s0);
    msid_cis_turns(0.3, &c1, NULL);
    msid_cis_turns(0.3, NULL, &s1);
    msid_cis_turns(0.3, NULL, NULL);
    UT_CHECK(c1 == c0 && s1 == s0, "%.17g %.17g", c1, s1);
}

/* ---------- msid_log ---------- */

/* |got - ref| in units of the last place of the double nearest ref. */
static double ulp_err(double got, long double ref)
{
    const double rd = (double)ref;
    double ulp = nextafter(fabs(rd), HUGE_VAL) - fabs(rd);
    if (fabs(rd) < DBL_MIN) ulp = DBL_TRUE_MIN;
    return (double)(fabsl((long double)got - ref) / (long double)ulp);
}

static void test_log_accuracy(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 77u);
    double worst = 0.0, wx = 0.0;
    for (int i = 0; i < 600000; ++i) {
        double x;
        const uint64_t bits = msid_rng_u64(&r);
        switch (i % 5) {
        case 0: { /* any positive finite double, subnormals included */
            const uint64_t b = bits & 0x7fffffffffffffffull;
            memcpy(&x, &b, sizeof x);
            if (!(x > 0.0) || !isfinite(x)) continue;
            break;
        }
        case 1: x = 1.0 + (msid_rng_uniform(&r) - 0.5) * 0.6; break;                 /* around 1 */
        case 2: x = 1.0 + (msid_rng_uniform(&r) - 0.5) * 1e-8; break;                /* very near 1 */
        case 3: /* ln x = e ln2 + ln m with cancellation: m just below sqrt(1/2), small |e| */
            x = ldexp(0.69 + 0.0171 * msid_rng_uniform(&r), (int)(bits % 8) - 3); break;
        default: x = exp((msid_rng_uniform(&r) - 0.5) * 1400.0); break;             /* 1e-304 .. 1e304 */
        }
        const long double ref = logl((long double)x);
        if (ref == 0.0L) { UT_CHECK(msid_log(x) == 0.0, "log(%.17g)", x); continue; }
        const double e = ulp_err(msid_log(x), ref);
        if (e > worst) { worst = e; wx = x; }
    }
    UT_CHECK(worst <= 2.0, "max error %.4g ulp at x = %.17g", worst, wx);
    /* powers of two are e*ln2 */
    for (int e = -1074; e <= 1023; e += 7) {
        const double x = ldexp(1.0, e);
        const double err = ulp_err(msid_log(x), logl((long double)x));
        UT_CHECK(err <= 2.0, "log(2^%d): %.3g ulp", e, err);
    }
}

static void test_log_special(void **state)
{
    (void)state;
    UT_CHECK(msid_log(1.0) == 0.0, "%.17g", msid_log(1.0));
    UT_CHECK(isinf(msid_log(0.0)) && msid_log(0.0) < 0, "%g", msid_log(0.0));
    UT_CHECK(isinf(msid_log(-0.0)) && msid_log(-0.0) < 0, "%g", msid_log(-0.0));
    UT_CHECK(isnan(msid_log(-1.0)), "%g", msid_log(-1.0));
    UT_CHECK(isnan(msid_log(-DBL_MIN)), "%g", msid_log(-DBL_MIN));
    UT_CHECK(isnan(msid_log(-HUGE_VAL)), "%g", msid_log(-HUGE_VAL));
    UT_CHECK(isnan(msid_log(NAN)), "%g", msid_log(NAN));
    UT_CHECK(isinf(msid_log(HUGE_VAL)) && msid_log(HUGE_VAL) > 0, "%g", msid_log(HUGE_VAL));
    /* ... including points where the first implementation, 2 ln2-split
     * roundings after ln(m), erred by 2.005 - 2.014 ulp (just below sqrt(1/2)) */
    const double xs[] = {DBL_TRUE_MIN, DBL_MIN, DBL_MAX, 2.0, 0.5, 10.0, 0.1, UT_SQRT1_2, 1.0 + DBL_EPSILON, 1.0 - DBL_EPSILON / 2,
                         0x1.69ff5547d72fdp-1, 0x1.684d098502075p-1, 0x1.6870bcd6c14f5p-1, 0x1.69f33cccc5331p-1};
    for (size_t k = 0; k < sizeof xs / sizeof xs[0]; ++k) {
        const double e = ulp_err(msid_log(xs[k]), logl((long double)xs[k]));
        UT_CHECK(e <= 2.0, "log(%.17g): %.3g ulp", xs[k], e);
    }
}

static void test_sqrt(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 5u);
    for (int i = 0; i < 10000; ++i) {
        const double x = exp((msid_rng_uniform(&r) - 0.5) * 200.0);
        UT_CHECK(msid_sqrt(x) == sqrt(x), "x=%.17g", x);
    }
    UT_CHECK(msid_sqrt(4.0) == 2.0 && msid_sqrt(0.0) == 0.0, "%g", msid_sqrt(4.0));
}

/* ---------- msid_rng ---------- */

/* Independent reference: splitmix64 seeding + xoshiro256** (Blackman & Vigna). */
typedef struct { uint64_t s[4]; } ref_rng;
static uint64_t ref_splitmix(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
static void ref_seed(ref_rng *r, uint64_t seed)
{
    for (int i = 0; i < 4; ++i) r->s[i] = ref_splitmix(&seed);
}
static uint64_t ref_rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
static uint64_t ref_next(ref_rng *r)
{
    uint64_t *s = r->s;
    const uint64_t res = ref_rotl(s[1] * 5, 7) * 9, t = s[1] << 17;
    s[2] ^= s[0]; s[3] ^= s[1]; s[1] ^= s[2]; s[0] ^= s[3]; s[2] ^= t; s[3] = ref_rotl(s[3], 45);
    return res;
}

static void test_rng_known_values(void **state)
{
    (void)state;
    /* Observed first outputs (pinned): any change in seeding or the generator breaks reproducibility. */
    static const uint64_t seeds[3] = {0u, 1u, 12345u};
    static const uint64_t want[3][4] = {
        {0x99ec5f36cb75f2b4ull, 0xbf6e1f784956452aull, 0x1a5f849d4933e6e0ull, 0x6aa594f1262d2d2cull},
        {0xb3f2af6d0fc710c5ull, 0x853b559647364ceaull, 0x92f89756082a4514ull, 0x642e1c7bc266a3a7ull},
        {0xbe6a36374160d49bull, 0x214aaa0637a688c6ull, 0xf69d16de9954d388ull, 0x0c60048c4e96e033ull},
    };
    for (int k = 0; k < 3; ++k) {
        msid_rng r;
        msid_rng_seed(&r, seeds[k]);
        for (int i = 0; i < 4; ++i) {
            const uint64_t v = msid_rng_u64(&r);
            UT_CHECK(v == want[k][i], "seed %d value %d: 0x%016llx", (int)seeds[k], i, (unsigned long long)v);
        }
    }
    /* different seeds differ */
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < a; ++b)
            for (int i = 0; i < 4; ++i) UT_CHECK(want[a][i] != want[b][i], "seeds %d %d", a, b);
}

static void test_rng_matches_reference(void **state)
{
    (void)state;
    const uint64_t seeds[] = {0u, 1u, 2u, 12345u, 0xdeadbeefcafef00dull, ~0ull};
    for (size_t k = 0; k < sizeof seeds / sizeof seeds[0]; ++k) {
        msid_rng r, r2;
        ref_rng q;
        msid_rng_seed(&r, seeds[k]);
        msid_rng_seed(&r2, seeds[k]);
        ref_seed(&q, seeds[k]);
        for (int i = 0; i < 10000; ++i) {
            const uint64_t v = msid_rng_u64(&r), w = ref_next(&q);
            UT_CHECK(v == w, "seed idx %zu step %d", k, i);
            /* uniform = top 53 bits / 2^53 on an identical stream */
            const double u = msid_rng_uniform(&r2);
            UT_CHECK(u == (double)(w >> 11) * 0x1.0p-53, "step %d u=%.17g", i, u);
        }
    }
    /* the same seed reproduces the same normals; a copied state forks the stream */
    msid_rng a, b;
    msid_rng_seed(&a, 99u);
    msid_rng_seed(&b, 99u);
    for (int i = 0; i < 1001; ++i) {
        const double x = msid_rng_normal(&a), y = msid_rng_normal(&b);
        UT_CHECK(memcmp(&x, &y, sizeof x) == 0, "step %d", i);
    }
    msid_rng c = a;
    for (int i = 0; i < 11; ++i) {
        const double x = msid_rng_normal(&a), y = msid_rng_normal(&c);
        UT_CHECK(memcmp(&x, &y, sizeof x) == 0, "fork step %d", i);
    }
    /* seeding resets the cached spare normal */
    msid_rng d;
    msid_rng_seed(&d, 7u);
    const double d0 = msid_rng_normal(&d);
    msid_rng_seed(&d, 7u);
    UT_CHECK(msid_rng_normal(&d) == d0, "%.17g", d0);
}

static void test_rng_uniform_moments(void **state)
{
    (void)state;
    const int n = 1000000;
    msid_rng r;
    msid_rng_seed(&r, 2024u);
    long double s = 0.0L, s2 = 0.0L;
    double lo = 1.0, hi = 0.0;
    for (int i = 0; i < n; ++i) {
        const double u = msid_rng_uniform(&r);
        UT_CHECK(u >= 0.0 && u < 1.0, "u=%.17g", u);
        if (u < lo) lo = u;
        if (u > hi) hi = u;
        s += u;
        s2 += (long double)(u - 0.5) * (u - 0.5);
    }
    const double mean = (double)(s / n), var = (double)(s2 / n);
    /* 5 sigma: sd(mean) = sqrt(1/12/n); sd(var) = sqrt((1/80 - 1/144)/n) */
    UT_CHECK(fabs(mean - 0.5) < 5.0 * sqrt(1.0 / 12.0 / n), "mean %.6f", mean);
    UT_CHECK(fabs(var - 1.0 / 12.0) < 5.0 * sqrt((1.0 / 80.0 - 1.0 / 144.0) / n), "var %.6f", var);
    UT_CHECK(lo < 1e-4 && hi > 1.0 - 1e-4, "range [%g, %g]", lo, hi);
}

static void test_rng_normal_moments(void **state)
{
    (void)state;
    const int n = 1000000;
    msid_rng r;
    msid_rng_seed(&r, 31337u);
    long double s = 0.0L, s2 = 0.0L, s4 = 0.0L;
    int tail = 0;
    for (int i = 0; i < n; ++i) {
        const double z = msid_rng_normal(&r);
        UT_CHECK(isfinite(z), "z=%g", z);
        s += z;
        s2 += (long double)z * z;
        s4 += (long double)z * z * z * z;
        tail += fabs(z) > 1.959963984540054;
    }
    const double mean = (double)(s / n), m2 = (double)(s2 / n), m4 = (double)(s4 / n);
    const double ft = (double)tail / n;
    UT_CHECK(fabs(mean) < 5.0 / sqrt(n), "mean %.6f", mean);
    UT_CHECK(fabs(m2 - 1.0) < 5.0 * sqrt(2.0 / n), "var %.6f", m2);
    UT_CHECK(fabs(m4 - 3.0) < 5.0 * sqrt(96.0 / n), "4th moment %.5f", m4);  /* Var(z^4) = 105 - 9 */
    UT_CHECK(fabs(ft - 0.05) < 5.0 * sqrt(0.05 * 0.95 / n), "P(|z|>1.96) = %.5f", ft);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cis_random),
        cmocka_unit_test(test_cis_exact_points),
        cmocka_unit_test(test_cis_null_outputs),
        cmocka_unit_test(test_log_accuracy),
        cmocka_unit_test(test_log_special),
        cmocka_unit_test(test_sqrt),
        cmocka_unit_test(test_rng_known_values),
        cmocka_unit_test(test_rng_matches_reference),
        cmocka_unit_test(test_rng_uniform_moments),
        cmocka_unit_test(test_rng_normal_moments),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
