/* Drift versus start-up transient in the period statistics (msid_pstats):
 * synthetic per-period spectra z_k = mu + (drift or transient) + circular
 * Gaussian noise, fixed seeds.
 *  - stationary spectra: the drift test fires at most alpha per experiment
 *    (complex lines and a real DC line), measured over R trials;
 *  - a linear drift through all periods is called drift (power), and in DROP
 *    mode nothing is dropped (negative control: the same record with the
 *    drift test's periods would have early periods dropped as "transients");
 *  - a start-up transient (first two periods) is not called drift, its
 *    periods are flagged and dropped;
 *  - the period numbers count every offered period (gap and skipped ones too). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "msid/msid.h"

enum { L = 20, Q = 2, K = 12, R = 4000 };
static const double ALPHA = 0.01;

typedef struct {
    msid_pstats ps;
    void *mem;
} pst;

static void make(pst *o, uint32_t skip, msid_transient_mode mode)
{
    msid_pstats_cfg c = {L, Q, skip, 64, mode, ALPHA, 0};
    const size_t n = msid_pstats_mem_size(&c);
    o->mem = aligned_alloc(64, (n + 63) & ~(size_t)63);
    assert_non_null(o->mem);
    assert_int_equal(msid_pstats_init(&o->ps, &c, o->mem, n), MSID_OK);
}

/* One record of K periods: mu (fixed per trial) + drift * (k - (K-1)/2) * d
 * + transient * exp(-2k) * t (k = 0, 1 only) + unit circular noise. Line 0 is
 * real (DC) when dc is set. Returns the drift-test verdict. */
static int trial(pst *o, msid_rng *r, double drift, double transient, int dc, msid_pstats_counts *cnt)
{
    static msid_cplx z[L * Q], mu[L * Q], d[L * Q], t[L * Q];
    msid_pstats_reset(&o->ps);
    for (int i = 0; i < L * Q; ++i) {
        mu[i] = (msid_cplx){3 * msid_rng_normal(r), 3 * msid_rng_normal(r)};
        d[i] = (msid_cplx){msid_rng_normal(r), msid_rng_normal(r)};
        t[i] = (msid_cplx){msid_rng_normal(r), msid_rng_normal(r)};
    }
    for (int k = 0; k < K; ++k) {
        const double s = drift * (k - 0.5 * (K - 1)), e = k < 2 ? transient * exp(-2.0 * k) : 0.0;
        for (int i = 0; i < L * Q; ++i) {
            const double nr = msid_rng_normal(r) * (dc && i < Q ? sqrt(2.0) : 1.0);
            const double ni = dc && i < Q ? 0.0 : msid_rng_normal(r);
            z[i].re = mu[i].re + s * d[i].re + e * t[i].re + nr;
            z[i].im = dc && i < Q ? 0.0 : mu[i].im + s * d[i].im + e * t[i].im + ni;
        }
        assert_int_equal(msid_pstats_add(&o->ps, z, 0), MSID_OK);
    }
    assert_int_equal(msid_pstats_detect(&o->ps), MSID_OK);
    *cnt = msid_pstats_get_counts(&o->ps);
    assert_int_equal(cnt->drift_tested, 1);
    return cnt->drift;
}

static void false_alarm(int dc)
{
    pst o;
    make(&o, 0, MSID_TRANSIENT_DROP);
    msid_rng r;
    msid_rng_seed(&r, dc ? 77 : 76);
    int fired = 0;
    msid_pstats_counts c;
    for (int n = 0; n < R; ++n) fired += trial(&o, &r, 0.0, 0.0, dc, &c);
    const double rate = (double)fired / R, bound = ALPHA + 4.5 * sqrt(ALPHA * (1 - ALPHA) / R);
    printf("drift test on stationary spectra%s: fired %d of %d (%.4f; alpha %.3f, bound %.4f)\n", dc ? " with DC" : "",
           fired, R, rate, ALPHA, bound);
    assert_true(rate <= bound);
    free(o.mem);
}

static void stationary_rarely_called_drift(void **s) { (void)s; false_alarm(0); }
static void stationary_with_dc_rarely_called_drift(void **s) { (void)s; false_alarm(1); }

/* Drift of 0.5 noise sd per period on every line: called drift nearly always;
 * DROP mode then drops nothing. */
static void drift_is_drift_and_not_dropped(void **s)
{
    (void)s;
    pst o;
    make(&o, 0, MSID_TRANSIENT_DROP);
    msid_rng r;
    msid_rng_seed(&r, 5);
    int fired = 0, dropped = 0;
    msid_pstats_counts c;
    for (int n = 0; n < 500; ++n) {
        fired += trial(&o, &r, 0.5, 0.0, 0, &c);
        if (c.drift) dropped += c.transient_dropped != 0;
    }
    printf("linear drift: called drift in %d of 500; periods dropped in %d of those\n", fired, dropped);
    assert_true(fired >= 495);
    assert_int_equal(dropped, 0);
    free(o.mem);
}

/* Negative control: on the same drifting records the leave-one-out transient
 * test alone flags the first period (the old behaviour: early periods of a
 * drifting record dropped one by one as "transients"), so it is the drift
 * verdict that stops the drops above. */
static void drift_flags_end_periods_as_transients(void **s)
{
    (void)s;
    pst o;
    make(&o, 0, MSID_TRANSIENT_FLAG);
    msid_rng r;
    msid_rng_seed(&r, 6);
    int flagged_first = 0;
    msid_pstats_counts c;
    for (int n = 0; n < 200; ++n) {
        trial(&o, &r, 0.5, 0.0, 0, &c);
        double pv;
        flagged_first += msid_pstats_period_state(&o.ps, 0, &pv) >= 1;
    }
    printf("linear drift: period 1 departs from the rest (transient test) in %d of 200\n", flagged_first);
    assert_true(flagged_first >= 150);
    free(o.mem);
}

/* A start-up transient (10 noise sd in period 1, 1.4 in period 2): not drift;
 * period 1 is dropped. */
static void transient_is_not_drift(void **s)
{
    (void)s;
    pst o;
    make(&o, 0, MSID_TRANSIENT_DROP);
    msid_rng r;
    msid_rng_seed(&r, 8);
    int fired = 0, first_dropped = 0;
    msid_pstats_counts c;
    for (int n = 0; n < 1000; ++n) {
        fired += trial(&o, &r, 0.0, 10.0, 0, &c);
        first_dropped += msid_pstats_period_state(&o.ps, 0, NULL) == 2;
    }
    const double bound = ALPHA + 4.5 * sqrt(ALPHA * (1 - ALPHA) / 1000);
    printf("start-up transient: called drift in %d of 1000 (bound %.1f); period 1 dropped in %d\n", fired,
           bound * 1000, first_dropped);
    assert_true(fired <= bound * 1000);
    assert_true(first_dropped >= 990);
    free(o.mem);
}

/* Period numbers count skipped and gap periods: the report names the period as
 * it sits in the record. */
static void period_numbers(void **s)
{
    (void)s;
    pst o;
    make(&o, 1, MSID_TRANSIENT_FLAG);
    static msid_cplx z[L * Q];
    for (int i = 0; i < L * Q; ++i) z[i] = (msid_cplx){1.0 + i, 0.5};
    /* offered: 0 skipped, 1 kept, 2 gap, 3 kept, 4 kept */
    assert_int_equal(msid_pstats_add(&o.ps, z, 0), MSID_OK);
    assert_int_equal(msid_pstats_add(&o.ps, z, 0), MSID_OK);
    assert_int_equal(msid_pstats_add(&o.ps, z, MSID_PERIOD_GAP), MSID_OK);
    assert_int_equal(msid_pstats_add(&o.ps, z, 0), MSID_OK);
    assert_int_equal(msid_pstats_add(&o.ps, z, 0), MSID_OK);
    assert_int_equal(msid_pstats_history(&o.ps), 3);
    assert_int_equal(msid_pstats_period_number(&o.ps, 0), 1);
    assert_int_equal(msid_pstats_period_number(&o.ps, 1), 3);
    assert_int_equal(msid_pstats_period_number(&o.ps, 2), 4);
    assert_int_equal(msid_pstats_period_number(&o.ps, 3), UINT32_MAX);
    free(o.mem);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(stationary_rarely_called_drift),
        cmocka_unit_test(stationary_with_dc_rarely_called_drift),
        cmocka_unit_test(drift_is_drift_and_not_dropped),
        cmocka_unit_test(drift_flags_end_periods_as_transients),
        cmocka_unit_test(transient_is_not_drift),
        cmocka_unit_test(period_numbers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
