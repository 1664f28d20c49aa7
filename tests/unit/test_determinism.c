/* End to end: the same simulated 2x2, 2-experiment data pushed through
 * msid_meas in different block partitions gives bit-identical msid_frf outputs,
 * on the streaming and on the FFTW path. */
#include "unit_util.h"
#include "unit_plants.h"
#ifdef MSID_HAVE_FFTW
#include "msid/msid_fft_fftw.h"
#endif

#define P_ 128u
#define K_ 6u
#define M_ 2u
#define L_ 10u
#define D_ 2u
#define C_ 4u

typedef struct {
    msid_cplx G[L_ * 4], cov[L_ * 16], cov_ki[L_ * 16], noise[L_ * 4], dmean[D_ * M_ * 2];
    double dof[L_], dof_ki[L_], snr[L_ * 2], cond[L_], dvar[D_ * 2], dpval[D_ * 2];
    msid_pstats_counts cnt[M_];
} frf_out;

/* Push every experiment's rows in blocks drawn from blocks[] (cycled; 0 = the rest), solve, copy out. */
static void measure(const tsim_design *t, double *const rows[M_], msid_dft_path path, const msid_fft_backend *be,
                    const size_t *blocks, size_t nb, frf_out *out)
{
    const uint32_t det[D_] = {7, 62};
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P_; mc.n_inputs = 2; mc.n_outputs = 2; mc.n_experiments = M_;
    mc.n_lines = L_; mc.bins = t->d.bins; mc.n_detect = D_; mc.detect_bins = det;
    mc.twiddle = &t->tw; mc.path = path; mc.fft = be;
    mc.skip_periods = 1; mc.max_periods = K_; mc.transient = MSID_TRANSIENT_DROP; mc.alpha = 0.05;
    const size_t n = msid_meas_mem_size(&mc);
    void *mem = tsim_alloc(n);
    msid_meas ms;
    UT_STATUS(msid_meas_init(&ms, &mc, mem, n), MSID_OK);
    UT_CHECK(ms.dft.path == path, "path %d", (int)ms.dft.path);
    const msid_pstats *st[M_];
    for (uint32_t e = 0; e < M_; ++e) {
        UT_STATUS(msid_meas_begin(&ms, e), MSID_OK);
        const size_t N = (size_t)K_ * P_;
        size_t pos = 0, bi = 0;
        while (pos < N) {
            size_t k = blocks[bi++ % nb];
            if (k == 0 || k > N - pos) k = N - pos;
            UT_STATUS(msid_meas_push(&ms, rows[e] + pos * C_, k), MSID_OK);
            pos += k;
        }
        UT_STATUS(msid_meas_end(&ms, NULL), MSID_OK);
        st[e] = msid_meas_stats(&ms, e);
        out->cnt[e] = msid_pstats_get_counts(st[e]);
    }
    msid_frf_cfg fc = {P_, 2, 2, M_, L_, D_, NULL};
    const size_t nf = msid_frf_mem_size(&fc);
    void *fm = tsim_alloc(nf);
    msid_frf f;
    UT_STATUS(msid_frf_init(&f, &fc, fm, nf), MSID_OK);
    UT_STATUS(msid_frf_compute(&f, st), MSID_OK);
    for (uint32_t l = 0; l < L_; ++l) {
        memcpy(out->G + l * 4, msid_frf_G(&f, l), 4 * sizeof(msid_cplx));
        memcpy(out->cov + l * 16, msid_frf_cov(&f, l), 16 * sizeof(msid_cplx));
        memcpy(out->cov_ki + l * 16, msid_frf_cov_known_input(&f, l), 16 * sizeof(msid_cplx));
        memcpy(out->noise + l * 4, msid_frf_noise_cov(&f, l), 4 * sizeof(msid_cplx));
        memcpy(out->snr + l * 2, msid_frf_snr_db(&f, l), 2 * sizeof(double));
        out->dof[l] = msid_frf_dof(&f, l);
        out->dof_ki[l] = msid_frf_dof_known_input(&f, l);
        out->cond[l] = msid_frf_cond(&f, l);
    }
    for (uint32_t d = 0; d < D_; ++d) {
        memcpy(out->dmean + d * M_ * 2, msid_frf_detect_mean(&f, d), M_ * 2 * sizeof(msid_cplx));
        memcpy(out->dvar + d * 2, msid_frf_detect_var(&f, d), 2 * sizeof(double));
        memcpy(out->dpval + d * 2, msid_frf_detect_pvalue(&f, d), 2 * sizeof(double));
    }
    tsim_free(fm);
    tsim_free(mem);
}

static void compare(const frf_out *a, const frf_out *b, const char *what)
{
#define SAME(field) UT_CHECK(memcmp(a->field, b->field, sizeof a->field) == 0, "%s: " #field " differs", what)
    SAME(G); SAME(cov); SAME(cov_ki); SAME(dof); SAME(dof_ki);
    SAME(noise); SAME(snr); SAME(cond); SAME(dmean); SAME(dvar); SAME(dpval);
#undef SAME
    for (uint32_t e = 0; e < M_; ++e)
        UT_CHECK(a->cnt[e].used == b->cnt[e].used && a->cnt[e].transient_dropped == b->cnt[e].transient_dropped &&
                 a->cnt[e].skipped == b->cnt[e].skipped, "%s: counts of experiment %u", what, e);
}

static void make_data(tsim_design *t, double *rows[M_])
{
    const uint32_t bins[L_] = {1, 2, 3, 5, 8, 13, 21, 34, 55, 63};
    msid_design_cfg c = ut_design_cfg(P_, L_, bins, 2, M_);
    c.phase_mode = MSID_PHASE_RANDOM; c.seed = 2024; c.pattern = MSID_PATTERN_DFT;
    UT_STATUS(tsim_design_make(t, &c), MSID_OK);
    const msid_plant_cfg pc = up_mimo();
    tsim_bench b;
    UT_STATUS(tsim_bench_make(&b, &pc, 500), MSID_OK);
    UT_STATUS(tsim_bench_color(&b, 0.6), MSID_OK);
    b.sigma_y[0] = 0.1; b.sigma_y[1] = 0.05;
    b.sigma_u[0] = 0.02; b.sigma_u[1] = 0.01;
    msid_rng r;
    msid_rng_seed(&r, 31415u);
    for (uint32_t e = 0; e < M_; ++e) {
        rows[e] = (double *)malloc(sizeof(double) * K_ * P_ * C_);
        tsim_run(&b, t, e, K_, &r, rows[e]);
    }
    tsim_bench_free(&b);
}

static void run_partitions(msid_dft_path path, const msid_fft_backend *be, double *rows[M_], const tsim_design *t, frf_out *whole)
{
    msid_rng r;
    msid_rng_seed(&r, 99u);
    size_t rnd[97];
    for (int k = 0; k < 97; ++k) rnd[k] = 1 + msid_rng_u64(&r) % 300;
    const size_t one[] = {1}, thirteen[] = {13}, all[] = {0};
    frf_out *o = (frf_out *)calloc(1, sizeof *o);
    measure(t, rows, path, be, all, 1, whole);
    measure(t, rows, path, be, one, 1, o);
    compare(whole, o, path == MSID_DFT_FFT ? "fft, blocks of 1" : "stream, blocks of 1");
    measure(t, rows, path, be, thirteen, 1, o);
    compare(whole, o, path == MSID_DFT_FFT ? "fft, blocks of 13" : "stream, blocks of 13");
    measure(t, rows, path, be, rnd, 97, o);
    compare(whole, o, path == MSID_DFT_FFT ? "fft, random blocks" : "stream, random blocks");
    free(o);
    /* sanity: the estimate is a real one (finite, used K-1 periods after the skip) */
    for (uint32_t l = 0; l < L_ * 4; ++l) UT_CHECK(isfinite(whole->G[l].re) && isfinite(whole->G[l].im), "G %u", l);
    UT_CHECK(whole->cnt[0].skipped == 1 && whole->cnt[0].used + whole->cnt[0].transient_dropped == K_ - 1, "used %u", whole->cnt[0].used);
}

static void test_stream_partitions(void **state)
{
    (void)state;
    tsim_design t;
    double *rows[M_];
    make_data(&t, rows);
    frf_out *w = (frf_out *)calloc(1, sizeof *w);
    run_partitions(MSID_DFT_STREAM, NULL, rows, &t, w);
    free(w);
    for (uint32_t e = 0; e < M_; ++e) free(rows[e]);
    tsim_design_free(&t);
}

static void test_fftw_partitions(void **state)
{
    (void)state;
#ifdef MSID_HAVE_FFTW
    tsim_design t;
    double *rows[M_];
    make_data(&t, rows);
    msid_fft_fftw f;
    UT_STATUS(msid_fft_fftw_create(&f, P_, MSID_FFTW_ESTIMATE), MSID_OK);
    frf_out *wf = (frf_out *)calloc(1, sizeof *wf), *ws = (frf_out *)calloc(1, sizeof *ws);
    run_partitions(MSID_DFT_FFT, &f.be, rows, &t, wf);
    /* the two paths agree closely (not bitwise) */
    measure(&t, rows, MSID_DFT_STREAM, NULL, (const size_t[]){0}, 1, ws);
    for (uint32_t k = 0; k < L_ * 4; ++k)
        UT_CHECK(ut_cdist(wf->G[k], ws->G[k]) <= 1e-10 * ut_cabs(ws->G[k]), "G[%u] fft vs stream", k);
    msid_fft_fftw_destroy(&f);
    free(wf);
    free(ws);
    for (uint32_t e = 0; e < M_; ++e) free(rows[e]);
    tsim_design_free(&t);
#else
    skip();
#endif
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stream_partitions),
        cmocka_unit_test(test_fftw_partitions),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
