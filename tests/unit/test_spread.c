/* Spread period end (bounded per-sample time): msid_meas with
 * cfg.spread = 1 defers the spectra copy and the period statistics of a
 * completed period to the samples of the next one. The statistics, counters,
 * history and the FRF must be the same bits as without spreading, whatever
 * block sizes are pushed, with gaps, skipped periods, the transient test, both
 * streaming paths and a full history; and the work must really be deferred
 * (one line per sample). The negative control shows the comparison sees a
 * one-ulp change. */
#include "unit_util.h"
#include <stdio.h>

enum { MAXC = MSID_MAX_CHANNELS };

typedef struct scase {
    uint32_t P, K, nu, ny, m, L, D, skip, maxp;
    msid_dft_path path;
    msid_transient_mode transient;
    int gaps;          /* 1: declare a gap and mark one period */
    uint64_t seed;
    int dense;         /* 1: bins 1..L, detection bins L+1..L+D */
} scase;

static void case_bins(const scase *c, uint32_t *bins, uint32_t *det)
{
    for (uint32_t l = 0; l < c->L; ++l) bins[l] = c->dense ? 1u + l : 1u + 3u * l;
    for (uint32_t d = 0; d < c->D; ++d) det[d] = c->dense ? c->L + 1u + d : 2u + 3u * d;
}

typedef struct srun {
    tsim_design t;
    tsim_bench b;
    msid_meas ms;
    void *mem;
    double *rows[MSID_MAX_EXPERIMENTS];
    size_t N;
} srun;

static void make(srun *r, const scase *c)
{
    uint32_t bins[64], det[8];
    case_bins(c, bins, det);
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = c->P; dc.n_lines = c->L; dc.bins = bins; dc.n_inputs = c->nu; dc.n_experiments = c->m;
    dc.seed = c->seed;
    UT_STATUS(tsim_design_make(&r->t, &dc), MSID_OK);
    double A[1] = {0.5}, B[MSID_MAX_INPUTS], C[MSID_MAX_OUTPUTS];
    for (uint32_t j = 0; j < c->nu; ++j) B[j] = 1.0 - 0.25 * (double)j;
    for (uint32_t i = 0; i < c->ny; ++i) C[i] = 1.0 + 0.5 * (double)i;
    msid_plant_cfg pc = {1, c->nu, c->ny, A, B, C, NULL};
    UT_STATUS(tsim_bench_make(&r->b, &pc, c->P), MSID_OK);
    for (uint32_t i = 0; i < c->ny; ++i) r->b.sigma_y[i] = 0.05;
    for (uint32_t j = 0; j < c->nu; ++j) r->b.sigma_u[j] = 0.01;
    r->N = (size_t)c->K * c->P;
    msid_rng g;
    msid_rng_seed(&g, c->seed);
    for (uint32_t e = 0; e < c->m; ++e) {
        r->rows[e] = (double *)malloc(sizeof(double) * r->N * (c->nu + c->ny));
        tsim_run(&r->b, &r->t, e, c->K, &g, r->rows[e]);
    }
    /* a transient in the first period of experiment 0, for the test to find */
    for (uint32_t s = 0; s < c->P / 4u; ++s) r->rows[0][(size_t)s * (c->nu + c->ny) + c->nu] += 0.5;
}

static void make_meas(srun *r, const scase *c, int spread)
{
    uint32_t bins[64], det[8];
    case_bins(c, bins, det);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = c->P; mc.n_inputs = c->nu; mc.n_outputs = c->ny; mc.n_experiments = c->m; mc.n_lines = c->L;
    mc.bins = bins; mc.n_detect = c->D; mc.detect_bins = det; mc.twiddle = &r->t.tw; mc.path = c->path;
    mc.skip_periods = c->skip; mc.max_periods = c->maxp; mc.transient = c->transient; mc.spread = spread;
    const size_t n = msid_meas_mem_size(&mc);
    r->mem = tsim_alloc(n);
    UT_STATUS(msid_meas_init(&r->ms, &mc, r->mem, n), MSID_OK);
}

/* Push every experiment in blocks of `blk` samples (0: random 1..3P from seed). With gaps, samples
 * [2P + 3, 2P + 3 + P/2) of experiment 0 are declared lost and the period holding sample 4P + 5 is
 * marked, at the same samples whatever the blocks. Returns the first error a push gave. */
static msid_status feed(srun *r, const scase *c, int blk, uint64_t seed)
{
    msid_rng g;
    msid_rng_seed(&g, seed);
    const size_t C = (size_t)c->nu + c->ny, g0 = 2u * c->P + 3u, g1 = g0 + c->P / 2u, mk = 4u * c->P + 5u;
    msid_status first = MSID_OK;
    for (uint32_t e = 0; e < c->m; ++e) {
        UT_STATUS(msid_meas_begin(&r->ms, e), MSID_OK);
        size_t done = 0;
        while (done < r->N) {
            size_t n = blk ? (size_t)blk : 1u + (size_t)(msid_rng_uniform(&g) * 3.0 * c->P);
            if (n > r->N - done) n = r->N - done;
            msid_status st;
            if (c->gaps && e == 0 && done == g0) {
                st = msid_meas_push_gap(&r->ms, g1 - g0);   /* a lost block */
                n = g1 - g0;
            } else {
                if (c->gaps && done == mk) (void)msid_meas_mark_gap(&r->ms);
                if (c->gaps && e == 0 && done < g0 && done + n > g0) n = g0 - done;
                if (c->gaps && done < mk && done + n > mk) n = mk - done;
                st = msid_meas_push(&r->ms, r->rows[e] + done * C, n);
            }
            if (st != MSID_OK && first == MSID_OK) first = st;
            done += n;
        }
        (void)msid_meas_end(&r->ms, NULL);
    }
    return first;
}

static void free_run(srun *r, const scase *c)
{
    for (uint32_t e = 0; e < c->m; ++e) free(r->rows[e]);
    tsim_free(r->mem);
    tsim_bench_free(&r->b);
    tsim_design_free(&r->t);
}

/* The same bench twice: a measures without spreading, b with. */
static void make_pair(srun *a, srun *b, const scase *c)
{
    make(a, c);
    make_meas(a, c, 0);
    make(b, c);
    make_meas(b, c, 1);
}

/* 0 if the statistics of a and b are the same bits. */
static int stats_differ(const msid_meas *a, const msid_meas *b, const char *what)
{
    for (uint32_t e = 0; e < a->n_experiments; ++e) {
        const msid_pstats *p = msid_meas_stats(a, e), *q = msid_meas_stats(b, e);
        const size_t n = (size_t)p->n_lines * p->n_channels;
        const msid_pstats_counts cp = msid_pstats_get_counts(p), cq = msid_pstats_get_counts(q);
        int bad = p->K != q->K || memcmp(&cp, &cq, sizeof cp) != 0 || p->nhist != q->nhist ||
                  memcmp(p->mean, q->mean, n * sizeof(msid_cplx)) != 0 ||
                  memcmp(p->m2, q->m2, n * p->n_channels * sizeof(msid_cplx)) != 0 ||
                  memcmp(&p->drift_pval, &q->drift_pval, sizeof(double)) != 0 ||
                  msid_meas_leftover(a, e) != msid_meas_leftover(b, e) || a->samples[e] != b->samples[e];
        if (!bad && p->max_periods)
            bad = memcmp(p->hist, q->hist, (size_t)p->nhist * n * sizeof(msid_cplx)) != 0 ||
                  memcmp(p->hflag, q->hflag, p->nhist) != 0 || memcmp(p->hdrop, q->hdrop, p->nhist) != 0 ||
                  memcmp(p->hpval, q->hpval, p->nhist * sizeof(double)) != 0;
        if (bad) {
            print_message("%s: experiment %u differs (K %u vs %u)\n", what, (unsigned)e, (unsigned)p->K, (unsigned)q->K);
            return 1;
        }
    }
    return 0;
}

static void check_case(const scase *c)
{
    srun ref, sp;
    make(&ref, c);
    make_meas(&ref, c, 0);
    UT_STATUS(feed(&ref, c, 1, 1u), MSID_OK);
    if (c->gaps) {   /* the lost block and the marked period were seen (and not used) */
        const msid_pstats_counts n0 = msid_pstats_get_counts(msid_meas_stats(&ref.ms, 0));
        UT_CHECK(n0.gap >= 2u, "%u gap periods in experiment 0, expected at least 2", (unsigned)n0.gap);
    }
    const int blocks[6] = {1, 2, 7, (int)c->P - 1, (int)c->P, 0};
    for (int b = 0; b < 6; ++b)
        for (uint64_t seed = 1; seed <= (blocks[b] ? 1u : 4u); ++seed) {
            make(&sp, c);
            make_meas(&sp, c, 1);
            UT_STATUS(feed(&sp, c, blocks[b], seed), MSID_OK);
            char what[64];
            snprintf(what, sizeof what, "block %d seed %u", blocks[b], (unsigned)seed);
            UT_CHECK(!stats_differ(&ref.ms, &sp.ms, what), "spread statistics differ: %s", what);
            free_run(&sp, c);
        }
    /* the FRF from both is the same bits too */
    make(&sp, c);
    make_meas(&sp, c, 1);
    UT_STATUS(feed(&sp, c, 0, 9u), MSID_OK);
    msid_frf_cfg fc = {c->P, c->nu, c->ny, c->m, c->L, c->D, NULL};
    const size_t nf = msid_frf_mem_size(&fc);
    void *m1 = tsim_alloc(nf), *m2 = tsim_alloc(nf);
    msid_frf f1, f2;
    UT_STATUS(msid_frf_init(&f1, &fc, m1, nf), MSID_OK);
    UT_STATUS(msid_frf_init(&f2, &fc, m2, nf), MSID_OK);
    const msid_pstats *p1[MSID_MAX_EXPERIMENTS], *p2[MSID_MAX_EXPERIMENTS];
    for (uint32_t e = 0; e < c->m; ++e) { p1[e] = msid_meas_stats(&ref.ms, e); p2[e] = msid_meas_stats(&sp.ms, e); }
    UT_STATUS(msid_frf_compute(&f1, p1), MSID_OK);
    UT_STATUS(msid_frf_compute(&f2, p2), MSID_OK);
    const size_t g = (size_t)c->nu * c->ny;
    UT_CHECK(memcmp(f1.G, f2.G, c->L * g * sizeof(msid_cplx)) == 0, "%s", "G differs");
    UT_CHECK(memcmp(f1.cov, f2.cov, c->L * g * g * sizeof(msid_cplx)) == 0, "%s", "cov differs");
    UT_CHECK(memcmp(f1.cov_ki, f2.cov_ki, c->L * g * g * sizeof(msid_cplx)) == 0, "%s", "cov_ki differs");
    tsim_free(m1);
    tsim_free(m2);
    free_run(&sp, c);
    free_run(&ref, c);
}

/* SISO; 2x2 with 2 experiments, detection lines, a skipped period, transient DROP and gaps;
 * the float32 path with transient FLAG; and lines + detection lines = P/2 - 1, where the
 * deferred work (2 (L + D) units, one per sample) just fits a period. */
static const scase CASES[4] = {
    {64, 10, 1, 1, 1, 10, 0, 0, 0, MSID_DFT_STREAM, MSID_TRANSIENT_OFF, 0, 3u, 0},
    {96, 12, 2, 2, 2, 10, 3, 1, 12, MSID_DFT_STREAM, MSID_TRANSIENT_DROP, 1, 5u, 0},
    {64, 8, 1, 2, 1, 9, 2, 0, 8, MSID_DFT_STREAM_F32, MSID_TRANSIENT_FLAG, 1, 7u, 0},
    {32, 6, 1, 1, 1, 12, 3, 0, 0, MSID_DFT_STREAM, MSID_TRANSIENT_OFF, 0, 8u, 1},
};

static void test_spread_bit_identical(void **state)
{
    (void)state;
    for (int k = 0; k < 4; ++k) check_case(&CASES[k]);
}

/* A full history: E_CAPACITY in both modes, the same statistics. */
static void test_spread_capacity(void **state)
{
    (void)state;
    const scase c = {64, 10, 1, 1, 1, 6, 0, 0, 4, MSID_DFT_STREAM, MSID_TRANSIENT_OFF, 0, 4u};
    srun a, b;
    make_pair(&a, &b, &c);
    UT_STATUS(feed(&a, &c, 1, 1u), MSID_E_CAPACITY);
    UT_STATUS(feed(&b, &c, 1, 1u), MSID_E_CAPACITY);
    const msid_pstats *p = msid_meas_stats(&a.ms, 0), *q = msid_meas_stats(&b.ms, 0);
    UT_CHECK(p->K == 4u && q->K == 4u, "K %u and %u, expected 4", (unsigned)p->K, (unsigned)q->K);
    const size_t n = (size_t)p->n_lines * p->n_channels;
    UT_CHECK(memcmp(p->mean, q->mean, n * sizeof(msid_cplx)) == 0 && memcmp(p->m2, q->m2, n * p->n_channels * sizeof(msid_cplx)) == 0,
             "%s", "statistics differ after E_CAPACITY");
    free_run(&a, &c);
    free_run(&b, &c);
}

/* The work is deferred: the sample that ends a period leaves the statistics
 * alone; one line per sample follows, and after 2 (L + D) samples it is done. */
static void test_spread_is_deferred(void **state)
{
    (void)state;
    const scase c = {64, 4, 1, 1, 1, 12, 2, 0, 0, MSID_DFT_STREAM, MSID_TRANSIENT_OFF, 0, 3u, 1};
    srun r;
    make(&r, &c);
    make_meas(&r, &c, 1);
    UT_STATUS(msid_meas_begin(&r.ms, 0), MSID_OK);
    const double *x = r.rows[0];
    const size_t C = 2u;
    for (uint32_t s = 0; s < c.P; ++s) UT_STATUS(msid_meas_push(&r.ms, x + (size_t)s * C, 1), MSID_OK);
    const msid_pstats *ps = msid_meas_stats(&r.ms, 0);
    UT_CHECK(ps->K == 0 && msid_linedft_pending(&r.ms.dft), "K %u pending %d after the period's last sample",
             (unsigned)ps->K, msid_linedft_pending(&r.ms.dft));
    const uint32_t units = 2u * (c.L + c.D);
    for (uint32_t s = 1; s <= units; ++s) {
        UT_STATUS(msid_meas_push(&r.ms, x + (size_t)(c.P + s - 1u) * C, 1), MSID_OK);
        if (s < units)
            UT_CHECK(r.ms.pend && r.ms.pend_unit == s, "sample %u of the next period: %u units done (pending %d)",
                     (unsigned)s, (unsigned)r.ms.pend_unit, r.ms.pend);
    }
    UT_CHECK(!r.ms.pend && ps->K == 1u, "after %u samples: pending %d, K %u", (unsigned)units, r.ms.pend, (unsigned)ps->K);
    free_run(&r, &c);
}

/* Negative control: the comparison sees a one-ulp change of one sample. */
static void test_spread_compare_detects_one_ulp(void **state)
{
    (void)state;
    const scase c = {64, 6, 1, 1, 1, 5, 0, 0, 0, MSID_DFT_STREAM, MSID_TRANSIENT_OFF, 0, 3u};
    srun a, b;
    make_pair(&a, &b, &c);
    b.rows[0][(size_t)(3u * c.P + 9u) * 2u + 1u] = nextafter(b.rows[0][(size_t)(3u * c.P + 9u) * 2u + 1u], 1e300);
    UT_STATUS(feed(&a, &c, 1, 1u), MSID_OK);
    UT_STATUS(feed(&b, &c, 5, 1u), MSID_OK);
    UT_CHECK(stats_differ(&a.ms, &b.ms, "negative control"), "%s", "a one-ulp change went unnoticed");
    free_run(&a, &c);
    free_run(&b, &c);
}

static void test_spread_fft_refused(void **state)
{
    (void)state;
    const uint32_t bins[2] = {1, 3};
    msid_linedft_cfg c = {64, 1, 2, bins, NULL, MSID_DFT_FFT, NULL, 1};
    UT_CHECK(msid_linedft_mem_size(&c) == 0, "%s", "spread with the FFT path has a memory size");
    msid_linedft d;
    static unsigned char mem[4096] __attribute__((aligned(64)));
    UT_STATUS(msid_linedft_init(&d, &c, mem, sizeof mem), MSID_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spread_bit_identical),
        cmocka_unit_test(test_spread_capacity),
        cmocka_unit_test(test_spread_is_deferred),
        cmocka_unit_test(test_spread_compare_detects_one_ulp),
        cmocka_unit_test(test_spread_fft_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
