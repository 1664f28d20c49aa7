/* Measurement pipeline: configuration checks, experiment state machine,
 * period accounting (skip, gaps, leftover samples, segments, capacity) and
 * the statistics it feeds (means equal a naive DFT of the rows). */
#include "unit_util.h"

typedef struct {
    msid_twiddle tw;
    void *mem_tw;
    msid_meas ms;
    void *mem;
} meas;

static msid_meas_cfg cfg(meas *o, uint32_t P, const uint32_t *bins, uint32_t L, const uint32_t *det, uint32_t D)
{
    const size_t nt = msid_twiddle_mem_size(P);
    o->mem_tw = tsim_alloc(nt);
    msid_twiddle_init(&o->tw, P, o->mem_tw, nt);
    msid_meas_cfg c;
    memset(&c, 0, sizeof c);
    c.period = P; c.n_inputs = 1; c.n_outputs = 2; c.n_experiments = 2;
    c.n_lines = L; c.bins = bins; c.n_detect = D; c.detect_bins = det;
    c.twiddle = &o->tw; c.path = MSID_DFT_STREAM;
    return c;
}

static msid_status init(meas *o, const msid_meas_cfg *c)
{
    const size_t n = msid_meas_mem_size(c);
    o->mem = tsim_alloc(n ? n : 64);
    return msid_meas_init(&o->ms, c, o->mem, n);
}

static void done(meas *o)
{
    tsim_free(o->mem);
    tsim_free(o->mem_tw);
}

static void test_config_errors(void **state)
{
    (void)state;
    const uint32_t P = 32, bins[] = {1, 5, 9}, det[] = {15, 3};
    meas o;
    msid_meas_cfg c = cfg(&o, P, bins, 3, det, 2);
    UT_STATUS(init(&o, &c), MSID_OK);
    tsim_free(o.mem);
    const size_t need = msid_meas_mem_size(&c);
    unsigned char *mem = (unsigned char *)tsim_alloc(need + 64);
    msid_meas ms;
    UT_STATUS(msid_meas_init(NULL, &c, mem, need), MSID_E_NULL);
    UT_STATUS(msid_meas_init(&ms, NULL, mem, need), MSID_E_NULL);
    UT_STATUS(msid_meas_init(&ms, &c, NULL, need), MSID_E_NULL);
    UT_STATUS(msid_meas_init(&ms, &c, ut_misalign(mem), need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_meas_init(&ms, &c, mem, need - 1), MSID_E_MEM_SIZE);
    UT_STATUS(msid_meas_init(&ms, &c, mem + 64, need), MSID_OK);
    msid_meas_cfg e = c;
    e.bins = NULL;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_NULL);
    e = c; e.detect_bins = NULL;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_NULL);
    e = c; e.n_lines = 0;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_NO_LINES);
    e = c; e.n_outputs = 0;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_DIMS);
    e = c; e.n_inputs = 3;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_EXPERIMENTS);
    e = c; e.period = 1;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_PERIOD);
    const uint32_t b_nyq[] = {1, 16}, b_dup[] = {5, 1, 5}, d_bad[] = {17}, d_exc[] = {9}, d_dup[] = {3, 3};
    e = c; e.bins = b_nyq; e.n_lines = 2;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_LINE_RANGE);
    e = c; e.bins = b_dup;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_LINE_DUP);
    e = c; e.detect_bins = d_bad; e.n_detect = 1;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_LINE_RANGE);
    const uint32_t d_nyq[] = {16}, d_dc[] = {0};   /* real-valued bins are not detection lines */
    e = c; e.detect_bins = d_nyq; e.n_detect = 1;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_LINE_RANGE);
    e = c; e.detect_bins = d_dc; e.n_detect = 1;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_LINE_RANGE);
    e = c; e.detect_bins = d_exc; e.n_detect = 1;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_LINE_DUP);
    e = c; e.detect_bins = d_dup;
    UT_STATUS(msid_meas_init(&ms, &e, mem, need), MSID_E_LINE_DUP);
    e = c; e.path = MSID_DFT_FFT;   /* no backend (the FFT path needs more memory) */
    const size_t nf = msid_meas_mem_size(&e);
    unsigned char *mf = (unsigned char *)tsim_alloc(nf);
    UT_CHECK(nf > need, "%zu", nf);
    UT_STATUS(msid_meas_init(&ms, &e, mf, nf), MSID_E_BACKEND);
    tsim_free(mf);
    UT_CHECK(msid_meas_mem_size(NULL) == 0, "%d", 0);
    tsim_free(mem);
    tsim_free(o.mem_tw);
}

static void test_state_machine(void **state)
{
    (void)state;
    const uint32_t P = 16, bins[] = {1, 3};
    meas o;
    msid_meas_cfg c = cfg(&o, P, bins, 2, NULL, 0);
    UT_STATUS(init(&o, &c), MSID_OK);
    double rows[3 * 16 * 3] = {0};
    UT_STATUS(msid_meas_push(&o.ms, rows, 1), MSID_E_STATE);
    UT_STATUS(msid_meas_push_gap(&o.ms, 1), MSID_E_STATE);
    UT_STATUS(msid_meas_mark_gap(&o.ms), MSID_E_STATE);
    UT_STATUS(msid_meas_end(&o.ms, NULL), MSID_E_STATE);
    UT_STATUS(msid_meas_begin(&o.ms, 2), MSID_E_ARG);
    UT_STATUS(msid_meas_begin(&o.ms, 1), MSID_OK);
    UT_STATUS(msid_meas_begin(&o.ms, 0), MSID_E_STATE);
    UT_STATUS(msid_meas_push(&o.ms, NULL, 3), MSID_E_NULL);
    UT_STATUS(msid_meas_push(&o.ms, NULL, 0), MSID_OK);
    UT_STATUS(msid_meas_end(&o.ms, NULL), MSID_OK);
    UT_CHECK(msid_meas_stats(&o.ms, 2) == NULL && msid_meas_stats(&o.ms, 1) != NULL && msid_meas_leftover(&o.ms, 5) == 0, "%d", 0);
    done(&o);
}

static void test_accounting(void **state)
{
    (void)state;
    const uint32_t P = 20, bins[] = {0, 3, 7}, det[] = {9};
    meas o;
    msid_meas_cfg c = cfg(&o, P, bins, 3, det, 1);
    c.skip_periods = 1;
    UT_STATUS(init(&o, &c), MSID_OK);
    msid_rng r;
    msid_rng_seed(&r, 6u);
    const uint32_t C = 3;
    double rows[10 * 20 * 3];
    for (size_t k = 0; k < sizeof rows / sizeof rows[0]; ++k) rows[k] = msid_rng_normal(&r) + (k % 3 == 0 ? 2.0 : 0.0);
    /* experiment 0, segment 1: 4.5 periods, a 5-sample gap inside period 2, period 3 marked */
    UT_STATUS(msid_meas_begin(&o.ms, 0), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows, 2 * P + 4), MSID_OK);
    UT_STATUS(msid_meas_push_gap(&o.ms, 5), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows + (2 * P + 9) * C, P - 9), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows + 3 * P * C, 3), MSID_OK);
    UT_STATUS(msid_meas_mark_gap(&o.ms), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows + (3 * P + 3) * C, P - 3 + P + P / 2), MSID_OK);
    uint64_t left = 99;
    UT_STATUS(msid_meas_end(&o.ms, &left), MSID_OK);
    UT_CHECK(left == P / 2 && msid_meas_leftover(&o.ms, 0) == P / 2, "leftover %llu", (unsigned long long)left);
    msid_pstats_counts n = msid_pstats_get_counts(msid_meas_stats(&o.ms, 0));
    /* periods: 0 skipped, 1 used, 2 gap, 3 gap, 4 used */
    UT_CHECK(n.offered == 5 && n.skipped == 1 && n.gap == 2 && n.used == 2, "offered %u skipped %u gap %u used %u", n.offered, n.skipped, n.gap, n.used);
    /* the mean equals the average naive DFT of periods 1 and 4 */
    long double *tw = ut_tw_table(P);
    const msid_pstats *st = msid_meas_stats(&o.ms, 0);
    const uint32_t allb[] = {0, 3, 7, 9};
    for (uint32_t l = 0; l < 4; ++l)
        for (uint32_t ch = 0; ch < C; ++ch) {
            long double r1, i1, r4, i4;
            ut_dft_ld(rows + 1 * P * C + ch, C, P, allb[l], tw, &r1, &i1);
            ut_dft_ld(rows + 4 * P * C + ch, C, P, allb[l], tw, &r4, &i4);
            const msid_cplx mu = msid_pstats_mean(st, l)[ch];
            const long double er = mu.re - (r1 + r4) / 2, ei = mu.im - (i1 + i4) / 2;
            UT_CHECK(sqrtl(er * er + ei * ei) <= 1e-12L * P * 3, "line %u ch %u", l, ch);
        }
    free(tw);
    /* experiment 1 in between, then experiment 0 again as a new segment: skip re-applied */
    UT_STATUS(msid_meas_begin(&o.ms, 1), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows, 3 * P), MSID_OK);
    UT_STATUS(msid_meas_end(&o.ms, &left), MSID_OK);
    UT_CHECK(left == 0 && msid_pstats_count(msid_meas_stats(&o.ms, 1)) == 2, "%u", msid_pstats_count(msid_meas_stats(&o.ms, 1)));
    UT_STATUS(msid_meas_begin(&o.ms, 0), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows, 3 * P + 7), MSID_OK);
    UT_STATUS(msid_meas_end(&o.ms, NULL), MSID_OK);
    n = msid_pstats_get_counts(msid_meas_stats(&o.ms, 0));
    UT_CHECK(n.skipped == 2 && n.used == 4 && msid_meas_leftover(&o.ms, 0) == P / 2 + 7, "skipped %u used %u leftover %llu",
             n.skipped, n.used, (unsigned long long)msid_meas_leftover(&o.ms, 0));
    UT_CHECK(o.ms.samples[0] == (uint64_t)(5 * P + P / 2) + 3 * P + 7, "samples %llu", (unsigned long long)o.ms.samples[0]);
    done(&o);
}

static void test_capacity_sticky(void **state)
{
    (void)state;
    const uint32_t P = 8, bins[] = {1};
    meas o;
    msid_meas_cfg c = cfg(&o, P, bins, 1, NULL, 0);
    c.max_periods = 3;
    UT_STATUS(init(&o, &c), MSID_OK);
    double rows[5 * 8 * 3] = {0};
    UT_STATUS(msid_meas_begin(&o.ms, 0), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows, 3 * P), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows, 2 * P), MSID_E_CAPACITY);
    UT_STATUS(msid_meas_push(&o.ms, rows, 1), MSID_E_CAPACITY);      /* sticky */
    UT_STATUS(msid_meas_push_gap(&o.ms, 1), MSID_E_CAPACITY);
    UT_CHECK(msid_pstats_count(msid_meas_stats(&o.ms, 0)) == 3, "%u", msid_pstats_count(msid_meas_stats(&o.ms, 0)));
    done(&o);
}

/* Regression: a gap of 2^32 - 1 samples is accounted in O(1) (whole periods are counted,
 * not walked), with the same counts as a short gap walked period by period, and a mark pending before a
 * run of whole gap periods does not leak into the next real period. */
static void test_huge_gap_is_o1(void **state)
{
    (void)state;
    const uint32_t P = 16, bins[] = {1, 3};
    meas o;
    msid_meas_cfg c = cfg(&o, P, bins, 2, NULL, 0);
    UT_STATUS(init(&o, &c), MSID_OK);
    double rows[4 * 16 * 3];
    for (size_t k = 0; k < sizeof rows / sizeof rows[0]; ++k) rows[k] = (double)(k % 7) - 3.0;
    const uint64_t big = 0xFFFFFFFFull;   /* would be 2^28 period walks */
    UT_STATUS(msid_meas_begin(&o.ms, 0), MSID_OK);
    UT_STATUS(msid_meas_push(&o.ms, rows, 3), MSID_OK);          /* a partial period, then the gap */
    UT_STATUS(msid_meas_push_gap(&o.ms, (size_t)big), MSID_OK);
    const uint64_t pos = (3 + big) % P;
    UT_STATUS(msid_meas_push(&o.ms, rows, (size_t)(P - pos)), MSID_OK);   /* rest of the gap's last period */
    UT_STATUS(msid_meas_mark_gap(&o.ms), MSID_OK);               /* a mark at a period start ... */
    UT_STATUS(msid_meas_push_gap(&o.ms, 2 * P), MSID_OK);        /* ... then whole gap periods */
    UT_STATUS(msid_meas_push(&o.ms, rows, 2 * P), MSID_OK);      /* two clean periods: both used */
    UT_STATUS(msid_meas_end(&o.ms, NULL), MSID_OK);
    const msid_pstats_counts n = msid_pstats_get_counts(msid_meas_stats(&o.ms, 0));
    const uint64_t gap_periods = (3 + big + (P - pos)) / P;
    UT_CHECK(n.gap == gap_periods + 2 && n.used == 2 && n.offered == gap_periods + 4,
             "gap %u (want %llu) used %u offered %u", n.gap, (unsigned long long)gap_periods + 2, n.used, n.offered);
    UT_CHECK(o.ms.samples[0] == 3 + big + (P - pos) + 4 * P, "samples %llu", (unsigned long long)o.ms.samples[0]);
    done(&o);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_errors),
        cmocka_unit_test(test_state_machine),
        cmocka_unit_test(test_accounting),
        cmocka_unit_test(test_capacity_sticky),
        cmocka_unit_test(test_huge_gap_is_o1),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
