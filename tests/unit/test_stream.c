/* msid_stream (daq/src/msid_stream.c) against the real msid_meas: rows in blocks give the same
 * statistics bit for bit as rows pushed straight into the core (any block size), a run of missing
 * samples rejects exactly the periods it touches (counted once per run), a mark discards the period
 * being assembled, a new segment re-applies the skip periods, an incomplete last period is counted as
 * leftover, and a core refusal is sticky and reported. Negative controls: the same checks fail on a
 * stream without the gap, and a different block of rows changes the mean. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>

#include "msid/msid.h"
#include "msid_daq/msid_stream.h"

#define P 32u
#define K 8u
#define C 3u   /* nu = 1, ny = 2 */
static const uint32_t BINS[3] = {1, 3, 5};
static uint8_t TWM[1 << 14] __attribute__((aligned(64)));
static uint8_t MEM[2][1 << 19] __attribute__((aligned(64)));
static uint8_t SMEM[1 << 16] __attribute__((aligned(64)));

typedef struct {
    msid_twiddle tw;
    msid_meas ms;
} bench;

static void meas_setup(bench *b, int which, uint32_t skip, uint32_t m)
{
    assert_int_equal(msid_twiddle_init(&b->tw, P, TWM, sizeof TWM), MSID_OK);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = 1; mc.n_outputs = 2; mc.n_experiments = m; mc.n_lines = 3; mc.bins = BINS;
    mc.twiddle = &b->tw; mc.path = MSID_DFT_STREAM; mc.transient = MSID_TRANSIENT_OFF; mc.max_periods = 4 * K;
    mc.skip_periods = skip;
    assert_true(msid_meas_mem_size(&mc) <= sizeof MEM[which]);
    assert_int_equal(msid_meas_init(&b->ms, &mc, MEM[which], sizeof MEM[which]), MSID_OK);
}

/* Row n of a noisy 1x2 bench (deterministic). */
static void row_of(uint64_t n, double *r)
{
    const double ph = 6.283185307179586 * (double)(n % P) / P;
    const double u = cos(ph) + cos(3 * ph + 1) + cos(5 * ph + 2);
    const double e = 0.01 * (double)((n * 7919u) % 13u) - 0.06;
    r[0] = u;
    r[1] = 0.5 * u + e;
    r[2] = -0.25 * u + 0.5 * e;
}

static void stream_setup(msid_stream *s, msid_meas *ms, uint32_t block)
{
    const msid_stream_cfg sc = {C, block, ms};
    const size_t need = msid_stream_mem_size(&sc);
    assert_true(need > 0 && need <= sizeof SMEM);
    assert_int_equal(msid_stream_init(s, &sc, SMEM, sizeof SMEM), MSID_OK);
}

static msid_pstats_counts counts(const msid_meas *ms, uint32_t e) { return msid_pstats_get_counts(msid_meas_stats(ms, e)); }

static int same_means(const msid_meas *a, const msid_meas *b)
{
    for (uint32_t l = 0; l < 3; ++l)
        if (memcmp(msid_pstats_mean(msid_meas_stats(a, 0), l), msid_pstats_mean(msid_meas_stats(b, 0), l),
                   C * sizeof(msid_cplx)) != 0)
            return 0;
    return 1;
}

/* Reference: every row straight into the core. */
static void direct(bench *b, uint64_t n)
{
    double r[C];
    assert_int_equal(msid_meas_begin(&b->ms, 0), MSID_OK);
    for (uint64_t i = 0; i < n; ++i) {
        row_of(i, r);
        assert_int_equal(msid_meas_push(&b->ms, r, 1), MSID_OK);
    }
    assert_int_equal(msid_meas_end(&b->ms, NULL), MSID_OK);
}

static void blocks_match_the_core_bit_for_bit(void **st)
{
    (void)st;
    static const uint32_t blocks[] = {1, 7, 32, 256};
    bench ref;
    meas_setup(&ref, 1, 1, 1);
    direct(&ref, (uint64_t)K * P);
    for (size_t i = 0; i < sizeof blocks / sizeof blocks[0]; ++i) {
        bench b;
        msid_stream s;
        meas_setup(&b, 0, 1, 1);
        stream_setup(&s, &b.ms, blocks[i]);
        assert_int_equal(msid_stream_begin(&s, 0), MSID_OK);
        double r[C];
        for (uint64_t n = 0; n < (uint64_t)K * P; ++n) {
            row_of(n, r);
            assert_int_equal(msid_stream_row(&s, r), MSID_OK);
        }
        assert_int_equal(msid_stream_end(&s), MSID_OK);
        assert_int_equal(s.cnt.samples, K * P);
        assert_int_equal(s.cnt.segments, 1);
        assert_int_equal(counts(&b.ms, 0).used, K - 1);
        assert_int_equal(counts(&b.ms, 0).skipped, 1);
        assert_true(same_means(&b.ms, &ref.ms));
    }
    /* negative control: one row different, the means differ */
    bench b;
    msid_stream s;
    meas_setup(&b, 0, 1, 1);
    stream_setup(&s, &b.ms, 7);
    msid_stream_begin(&s, 0);
    double r[C];
    for (uint64_t n = 0; n < (uint64_t)K * P; ++n) {
        row_of(n, r);
        if (n == 3 * P + 5) r[1] += 1e-9;
        msid_stream_row(&s, r);
    }
    msid_stream_end(&s);
    assert_false(same_means(&b.ms, &ref.ms));
}

/* Rows of [0, n) with the samples [g0, g0 + g) declared lost, in `runs` calls of msid_stream_lost. */
static void with_gap(msid_stream *s, uint64_t n, uint64_t g0, uint64_t g, uint32_t runs)
{
    double r[C];
    assert_int_equal(msid_stream_begin(s, 0), MSID_OK);
    for (uint64_t i = 0; i < n;) {
        if (i == g0 && g) {
            for (uint32_t k = 0; k < runs; ++k) msid_stream_lost(s, g / runs + (k == runs - 1 ? g % runs : 0));
            i += g;
            continue;
        }
        row_of(i, r);
        msid_stream_row(s, r);
        ++i;
    }
    assert_int_equal(msid_stream_end(s), MSID_OK);
}

static void lost_samples_reject_the_periods_they_touch(void **st)
{
    (void)st;
    /* 40 samples from the middle of period 2 into period 3: periods 2 and 3 are rejected, once */
    bench b;
    msid_stream s;
    meas_setup(&b, 0, 0, 1);
    stream_setup(&s, &b.ms, 16);
    with_gap(&s, (uint64_t)K * P, 2 * P + 10, 40, 3);   /* three calls: one run */
    msid_pstats_counts c = counts(&b.ms, 0);
    assert_int_equal(c.gap, 2);
    assert_int_equal(c.used, K - 2);
    assert_int_equal(s.cnt.samples_lost, 40);
    assert_int_equal(s.cnt.gap_events, 1);
    assert_int_equal(s.cnt.samples, K * P - 40);
    assert_int_equal(b.ms.samples[0], K * P);   /* the gap keeps the sample index: nothing shifts */

    /* negative control: the same stream without the gap uses every period */
    meas_setup(&b, 0, 0, 1);
    stream_setup(&s, &b.ms, 16);
    with_gap(&s, (uint64_t)K * P, 0, 0, 1);
    c = counts(&b.ms, 0);
    assert_int_equal(c.gap, 0);
    assert_int_equal(c.used, K);
    assert_int_equal(s.cnt.gap_events, 0);

    /* the periods left are the core's own: a gap exactly on period 5 equals rows of periods 0-4, 6-7 */
    meas_setup(&b, 0, 0, 1);
    stream_setup(&s, &b.ms, 5);
    with_gap(&s, (uint64_t)K * P, 5 * P, P, 1);
    assert_int_equal(counts(&b.ms, 0).gap, 1);
    assert_int_equal(counts(&b.ms, 0).used, K - 1);
}

static void mark_discards_the_period_being_assembled(void **st)
{
    (void)st;
    bench b;
    msid_stream s;
    meas_setup(&b, 0, 0, 1);
    stream_setup(&s, &b.ms, 8);
    double r[C];
    assert_int_equal(msid_stream_begin(&s, 0), MSID_OK);
    for (uint64_t n = 0; n < (uint64_t)K * P; ++n) {
        if (n == 4 * P + 3) assert_int_equal(msid_stream_mark(&s), MSID_OK);
        row_of(n, r);
        msid_stream_row(&s, r);
    }
    assert_int_equal(msid_stream_end(&s), MSID_OK);
    assert_int_equal(s.cnt.periods_marked, 1);
    assert_int_equal(counts(&b.ms, 0).gap, 1);
    assert_int_equal(counts(&b.ms, 0).used, K - 1);
}

static void segments_skip_again_and_leftover_is_counted(void **st)
{
    (void)st;
    bench b;
    msid_stream s;
    meas_setup(&b, 0, 1, 1);
    stream_setup(&s, &b.ms, 0);
    double r[C];
    /* segment 1: 3 periods and 10 samples (a device restart), segment 2: K periods */
    assert_int_equal(msid_stream_begin(&s, 0), MSID_OK);
    for (uint64_t n = 0; n < 3 * P + 10; ++n) { row_of(n, r); msid_stream_row(&s, r); }
    assert_int_equal(msid_stream_begin(&s, 0), MSID_OK);   /* closes the open segment first */
    for (uint64_t n = 0; n < (uint64_t)K * P; ++n) { row_of(n, r); msid_stream_row(&s, r); }
    assert_int_equal(msid_stream_end(&s), MSID_OK);
    assert_int_equal(msid_stream_end(&s), MSID_OK);       /* nothing open: no effect */
    const msid_pstats_counts c = counts(&b.ms, 0);
    assert_int_equal(s.cnt.segments, 2);
    assert_int_equal(c.skipped, 2);
    assert_int_equal(c.used, 3 - 1 + K - 1);
    assert_int_equal(msid_meas_leftover(&b.ms, 0), 10);
}

static void core_refusal_is_sticky(void **st)
{
    (void)st;
    bench b;
    msid_stream s;
    meas_setup(&b, 0, 0, 1);
    stream_setup(&s, &b.ms, 4);
    double r[C];
    row_of(0, r);
    assert_int_equal(msid_stream_row(&s, r), MSID_OK);   /* no segment open: ignored */
    assert_int_equal(s.cnt.samples, 0);
    const msid_status e = msid_stream_begin(&s, 3);       /* the measurement has one experiment */
    assert_int_not_equal(e, MSID_OK);
    assert_int_equal(msid_stream_begin(&s, 0), e);        /* sticky: the first error stays */
    assert_int_equal(msid_stream_lost(&s, 5), e);
    assert_int_equal(msid_stream_mark(&s), e);
    assert_int_equal(msid_stream_end(&s), e);
    assert_int_equal(s.err, e);
}

static void init_errors(void **st)
{
    (void)st;
    bench b;
    meas_setup(&b, 0, 0, 1);
    msid_stream s;
    msid_stream_cfg sc = {C, 0, &b.ms};
    assert_int_equal(msid_stream_init(NULL, &sc, SMEM, sizeof SMEM), MSID_E_NULL);
    assert_int_equal(msid_stream_init(&s, &sc, NULL, sizeof SMEM), MSID_E_NULL);
    assert_int_equal(msid_stream_init(&s, &sc, SMEM + 1, sizeof SMEM - 1), MSID_E_MEM_ALIGN);
    assert_int_equal(msid_stream_init(&s, &sc, SMEM, msid_stream_mem_size(&sc) - 1), MSID_E_MEM_SIZE);
    assert_int_equal(msid_stream_init(&s, &sc, SMEM, msid_stream_mem_size(&sc)), MSID_OK);
    sc.n_channels = 0;
    assert_int_equal(msid_stream_mem_size(&sc), 0);
    assert_int_equal(msid_stream_init(&s, &sc, SMEM, sizeof SMEM), MSID_E_DIMS);
    sc.n_channels = MSID_MAX_CHANNELS + 1;
    assert_int_equal(msid_stream_mem_size(&sc), 0);
    sc.n_channels = C;
    sc.meas = NULL;
    assert_int_equal(msid_stream_init(&s, &sc, SMEM, sizeof SMEM), MSID_E_NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(blocks_match_the_core_bit_for_bit),
        cmocka_unit_test(lost_samples_reject_the_periods_they_touch),
        cmocka_unit_test(mark_discards_the_period_being_assembled),
        cmocka_unit_test(segments_skip_again_and_leftover_is_counted),
        cmocka_unit_test(core_refusal_is_sticky),
        cmocka_unit_test(init_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
