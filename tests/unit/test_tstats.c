/* msid_tstats: moments against direct sums, extremes exact, quantiles within the histogram's 1/64 of the exact
 * order statistic, for several distributions and sizes. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "msid_daq/msid_tstats.h"

static int cmp_i64(const void *a, const void *b)
{
    const int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return x < y ? -1 : x > y;
}

static uint64_t lcg(uint64_t *s)
{
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return *s >> 11;
}

static void check_against_exact(int64_t *v, size_t n)
{
    static msid_tstats s;
    msid_tstats_reset(&s);
    double sum = 0;
    for (size_t i = 0; i < n; ++i) {
        msid_tstats_add(&s, v[i]);
        sum += (double)v[i];
    }
    const double mean = sum / (double)n;
    double ss = 0;
    for (size_t i = 0; i < n; ++i) ss += ((double)v[i] - mean) * ((double)v[i] - mean);
    assert_int_equal(s.n, n);
    assert_true(fabs(s.mean - mean) <= 1e-9 * (fabs(mean) + 1));
    if (n > 1) assert_true(fabs(msid_tstats_sd(&s) - sqrt(ss / (double)(n - 1))) <= 1e-6 * (sqrt(ss / (double)(n - 1)) + 1));
    qsort(v, n, sizeof *v, cmp_i64);
    assert_true(s.min == v[0] && s.max == v[n - 1]);
    const double qs[] = {0.01, 0.1, 0.5, 0.9, 0.99, 0.999};
    for (size_t k = 0; k < sizeof qs / sizeof *qs; ++k) {
        size_t rank = (size_t)ceil(qs[k] * (double)n);
        if (rank < 1) rank = 1;
        const double exact = (double)(v[rank - 1] < 0 ? 0 : v[rank - 1]);
        const double got = msid_tstats_quantile(&s, qs[k]);
        /* the middle of the bucket holding the exact value: within half a bucket (1/128 relative, 0.5 ns below 64) */
        const double tol = exact < 64 ? 0.5 : exact / 128.0 + 1e-9;
        if (fabs(got - exact) > tol) fail_msg("q %g: %g against the exact %g (n %zu)", qs[k], got, exact, n);
    }
}

static void test_distributions(void **state)
{
    (void)state;
    static int64_t v[200000];
    uint64_t seed = 7;
    for (int dist = 0; dist < 4; ++dist)
        for (size_t n = 1; n <= 200000; n *= 7) {
            for (size_t i = 0; i < n; ++i) {
                const double u = (double)(lcg(&seed) & 0xFFFFFFFFFFull) / 1099511627776.0;
                switch (dist) {
                case 0: v[i] = (int64_t)(u * 1000); break;                      /* 0..1 us, fine buckets */
                case 1: v[i] = (int64_t)(50000 + 20000 * sin(6.283 * u)); break; /* around 50 us */
                case 2: v[i] = (int64_t)(-log(1 - u + 1e-300) * 2e5); break;    /* exponential, long tail */
                default: v[i] = (int64_t)(u * 4e11); break;                      /* up to 400 s */
                }
            }
            check_against_exact(v, n);
        }
}

static void test_empty_and_negative(void **state)
{
    (void)state;
    msid_tstats s;
    msid_tstats_reset(&s);
    assert_true(msid_tstats_quantile(&s, 0.5) == 0.0);
    assert_true(msid_tstats_sd(&s) == 0.0);
    msid_tstats_add(&s, -5);   /* a clock that stepped back: counted, the histogram at 0, min exact */
    msid_tstats_add(&s, 10);
    assert_true(s.min == -5 && s.max == 10);
    assert_true(msid_tstats_quantile(&s, 0.0) == -5.0);
    assert_true(msid_tstats_quantile(&s, 1.0) == 10.0);
    const double huge = (double)((int64_t)1 << 50);
    msid_tstats_add(&s, (int64_t)1 << 50);   /* beyond the last octave: the last bucket, max exact */
    assert_true(msid_tstats_quantile(&s, 1.0) == huge);
    assert_true(msid_tstats_quantile(&s, 0.99) <= huge);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_distributions), cmocka_unit_test(test_empty_and_negative)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
