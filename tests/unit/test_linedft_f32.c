/* MSID_DFT_STREAM_F32, the single-precision streaming line DFT for FPUs without
 * double (Cortex-M4F): its documented accuracy over 10^6 samples.
 *
 * Error analysis (docs/target.md): per period and line, X = sum_n x(n) w(n) is
 * accumulated in float from x rounded to float (relative error <= u = 2^-24)
 * and w rounded to float (<= u). Each product adds one rounding, and the
 * running sum of n terms at most n roundings of the partial sums (Higham,
 * Accuracy and Stability, eq. 3.5: |fl(sum) - sum| <= gamma_{n-1} sum |t_k|).
 * So |X_f32 - X| <= (P + 3) u sum_n |x(n)| to first order, for the re and im
 * parts alike. Every period restarts from zero and the twiddle index is an
 * exact integer, so the error does not grow with the run length. */
#include "unit_util.h"

#define P_ 1000u
#define L_ 3u
#define C_ 2u
#ifndef NPER
#define NPER 1000u   /* 10^6 samples (the emulated targets run 2*10^5: tests/target/cross) */
#endif

typedef struct { msid_linedft d; void *mem; } ld;

static void ld_make(ld *o, const msid_twiddle *tw, const uint32_t *bins, msid_dft_path path)
{
    msid_linedft_cfg c = {P_, C_, L_, bins, tw, path, NULL};
    const size_t n = msid_linedft_mem_size(&c);
    UT_CHECK(n > 0, "mem_size %d", (int)path);
    o->mem = tsim_alloc(n);
    UT_STATUS(msid_linedft_init(&o->d, &c, o->mem, n), MSID_OK);
    UT_CHECK(o->d.path == path, "path %d", (int)o->d.path);
}

static void test_f32_error_bound_1e6_samples(void **state)
{
    (void)state;
    const uint32_t bins[L_] = {3, 50, 499};
    tsim_design t;
    msid_design_cfg dc = ut_design_cfg(P_, L_, bins, 1, 1);
    UT_STATUS(tsim_design_make(&t, &dc), MSID_OK);
    msid_gen_cfg gc = {&t.d, &t.tw, 0, 1};
    const size_t ng = msid_gen_mem_size(&gc);
    void *mg = tsim_alloc(ng);
    msid_gen g;
    UT_STATUS(msid_gen_init(&g, &gc, mg, ng), MSID_OK);
    ld a, b;
    ld_make(&a, &t.tw, bins, MSID_DFT_STREAM);
    ld_make(&b, &t.tw, bins, MSID_DFT_STREAM_F32);
    msid_rng r;
    msid_rng_seed(&r, 99u);
    const double u = 1.0 / 16777216.0;   /* 2^-24 */
    double worst = 0.0, worst_first = 0.0, worst_last = 0.0, mean_ratio = 0.0, sumabs[C_] = {0, 0};
    double row[C_];
    uint32_t per = 0;
    for (uint64_t s = 0; s < (uint64_t)NPER * P_; ++s) {
        msid_gen_next(&g, &row[0]);
        row[0] += 10.0;                                    /* an offset: large sum |x| */
        row[1] = 0.3 * row[0] + 0.05 * msid_rng_normal(&r);
        for (uint32_t c = 0; c < C_; ++c) sumabs[c] += fabs(row[c]);
        UT_CHECK(msid_linedft_push(&a.d, row, 1) == 1 && msid_linedft_push(&b.d, row, 1) == 1, "push %u", (unsigned)s);
        if (msid_linedft_ready(&a.d)) {
            UT_CHECK(msid_linedft_ready(&b.d), "period %u", per);
            const msid_cplx *xa = msid_linedft_spectra(&a.d), *xb = msid_linedft_spectra(&b.d);
            for (uint32_t l = 0; l < L_; ++l)
                for (uint32_t c = 0; c < C_; ++c) {
                    const double bound = (P_ + 3.0) * u * sumabs[c];
                    const double e = fmax(fabs(xb[l * C_ + c].re - xa[l * C_ + c].re),
                                          fabs(xb[l * C_ + c].im - xa[l * C_ + c].im));
                    UT_CHECK(e <= bound, "period %u line %u channel %u: error %.3g above the bound %.3g", per, l, c, e, bound);
                    const double ratio = e / bound;
                    worst = fmax(worst, ratio);
                    mean_ratio += ratio / (NPER * L_ * C_);
                    if (per < 100u) worst_first = fmax(worst_first, ratio);
                    if (per >= NPER - 100u) worst_last = fmax(worst_last, ratio);
                }
            msid_linedft_release(&a.d);
            msid_linedft_release(&b.d);
            sumabs[0] = sumabs[1] = 0.0;
            per++;
        }
    }
    UT_CHECK(per == NPER, "periods %u", per);
    print_message("f32 error / bound over %u periods of %u samples: max %.3g, mean %.3g; max in the first 100 periods %.3g, "
                  "last 100 %.3g\n", NPER, P_, worst, mean_ratio, worst_first, worst_last);
    /* negative control: the path really computes in single precision (errors far
     * above double rounding) and the bound is not vacuous (within 100x of what
     * is seen) */
    UT_CHECK(worst > 1e-4, "f32 errors implausibly small (double rounding is ~2e-9 of the bound): max ratio %.3g", worst);
    /* no growth with run length: the last periods are no worse than the first */
    UT_CHECK(worst_last <= 3.0 * worst_first, "error grew: first %.3g last %.3g", worst_first, worst_last);
    tsim_free(a.mem);
    tsim_free(b.mem);
    tsim_free(mg);
    tsim_design_free(&t);
}

/* The FRF from the float path equals the double path's within the bound
 * carried through: for a SISO line |dG/G| <= |dY|/|Y| + |dU|/|U|. */
static void test_f32_frf_close_to_double(void **state)
{
    (void)state;
    const uint32_t bins[L_] = {3, 50, 499};
    tsim_design t;
    msid_design_cfg dc = ut_design_cfg(P_, L_, bins, 1, 1);
    UT_STATUS(tsim_design_make(&t, &dc), MSID_OK);
    static const double A[1] = {0.9}, B[1] = {1.0}, Cm[1] = {0.1}, D[1] = {0.0};
    msid_plant_cfg pc = {1, 1, 1, A, B, Cm, D};
    tsim_bench bench;
    UT_STATUS(tsim_bench_make(&bench, &pc, 2 * P_), MSID_OK);
    bench.sigma_y[0] = 1e-3;
    const uint32_t K = 6;
    double *rows = (double *)malloc(sizeof(double) * K * P_ * 2);
    msid_rng r;
    msid_rng_seed(&r, 5u);
    tsim_run(&bench, &t, 0, K, &r, rows);
    msid_cplx G[2][L_];
    double var[2][L_];
    for (int k = 0; k < 2; ++k) {
        msid_meas_cfg mc;
        memset(&mc, 0, sizeof mc);
        mc.period = P_; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = 1; mc.n_lines = L_;
        mc.bins = bins; mc.twiddle = &t.tw; mc.path = k ? MSID_DFT_STREAM_F32 : MSID_DFT_STREAM;
        const size_t nm = msid_meas_mem_size(&mc);
        void *mm = tsim_alloc(nm);
        msid_meas ms;
        UT_STATUS(msid_meas_init(&ms, &mc, mm, nm), MSID_OK);
        UT_STATUS(msid_meas_begin(&ms, 0), MSID_OK);
        UT_STATUS(msid_meas_push(&ms, rows, (size_t)K * P_), MSID_OK);
        UT_STATUS(msid_meas_end(&ms, NULL), MSID_OK);
        msid_frf_cfg fc = {P_, 1, 1, 1, L_, 0, NULL};
        const size_t nf = msid_frf_mem_size(&fc);
        void *fm = tsim_alloc(nf);
        msid_frf f;
        UT_STATUS(msid_frf_init(&f, &fc, fm, nf), MSID_OK);
        const msid_pstats *ps = msid_meas_stats(&ms, 0);
        UT_STATUS(msid_frf_compute(&f, &ps), MSID_OK);
        for (uint32_t l = 0; l < L_; ++l) { G[k][l] = msid_frf_G(&f, l)[0]; var[k][l] = msid_frf_cov(&f, l)[0].re; }
        tsim_free(fm);
        tsim_free(mm);
    }
    int differs = 0;
    for (uint32_t l = 0; l < L_; ++l) {
        differs |= G[0][l].re != G[1][l].re || G[0][l].im != G[1][l].im;
        const double rel = ut_cdist(G[0][l], G[1][l]) / ut_cabs(G[0][l]);
        /* float rounding of P-term sums: a few 1e-7 relative; far below the noise (sqrt(var)/|G|) */
        print_message("line %u: |G_f32 - G_f64| / |G| = %.3g, / std(G) = %.3g\n", l, rel, ut_cdist(G[0][l], G[1][l]) / sqrt(var[0][l]));
        UT_CHECK(rel < 1e-5, "line %u: f32 G differs by %.3g relative", l, rel);
        UT_CHECK(ut_cdist(G[0][l], G[1][l]) < 0.1 * sqrt(var[0][l]), "line %u: f32 error not small against the noise (line SNR ~110 dB here)", l);
    }
    UT_CHECK(differs, "f32 FRF identical to double: the float path was not used (%d)", differs);
    free(rows);
    tsim_bench_free(&bench);
    tsim_design_free(&t);
}

/* As on the double path, the spectra do not depend on how samples are split
 * into pushes (the float kernel converts and blocks samples internally). */
/* Push K periods of rows (doubles x, or floats xf) into a fresh line DFT of `path`, one sample per
 * call (blocks = 0) or in uneven blocks, and collect the spectra of every period into out [K*L*C]. */
static void run_periods(const msid_twiddle *tw, const uint32_t *bins, uint32_t L, uint32_t C, uint32_t K,
                        msid_dft_path path, const double *x, const float *xf, int blocks, msid_cplx *out)
{
    msid_linedft_cfg c = {P_, C, L, bins, tw, path, NULL};
    const size_t n = msid_linedft_mem_size(&c);
    void *m = tsim_alloc(n);
    msid_linedft d;
    UT_STATUS(msid_linedft_init(&d, &c, m, n), MSID_OK);
    size_t done = 0, blk = 1, per = 0;
    while (done < (size_t)K * P_) {
        size_t want = blocks ? blk : 1u;
        if (want > K * P_ - done) want = K * P_ - done;
        done += xf ? msid_linedft_push_f32(&d, xf + done * C, want) : msid_linedft_push(&d, x + done * C, want);
        blk = blk * 7 % 61 + 1;
        if (msid_linedft_ready(&d)) {
            memcpy(out + per * L * C, msid_linedft_spectra(&d), sizeof(msid_cplx) * L * C);
            msid_linedft_release(&d);
            per++;
        }
    }
    UT_CHECK(per == K, "periods %u", (unsigned)per);
    tsim_free(m);
}

static void test_f32_blocks_bit_identical(void **state)
{
    (void)state;
    const uint32_t bins[5] = {1, 2, 7, 100, 500};
    const uint32_t C = 3, K = 3;
    msid_twiddle tw;
    void *mt = tsim_alloc(msid_twiddle_mem_size(P_));
    UT_STATUS(msid_twiddle_init(&tw, P_, mt, msid_twiddle_mem_size(P_)), MSID_OK);
    double *x = (double *)malloc(sizeof(double) * K * P_ * C);
    msid_rng r;
    msid_rng_seed(&r, 3u);
    for (uint32_t k = 0; k < K * P_ * C; ++k) x[k] = msid_rng_normal(&r);
    msid_cplx *out[2];
    for (int mode = 0; mode < 2; ++mode) {
        out[mode] = (msid_cplx *)malloc(sizeof(msid_cplx) * K * 5 * C);
        run_periods(&tw, bins, 5, C, K, MSID_DFT_STREAM_F32, x, NULL, mode, out[mode]);
    }
    assert_memory_equal(out[0], out[1], sizeof(msid_cplx) * K * 5 * C);
    free(out[0]);
    free(out[1]);
    free(x);
    tsim_free(mt);
}

/* Float samples in (msid_linedft_push_f32, msid_meas_push_f32): the same bits as pushing the same
 * values as double, on the float and the double streaming path, one sample per call or in blocks;
 * so the documented accuracy of the float path is the one tested above, and it holds here against a
 * long-double DFT of the float data: |X - X_exact| <= (P + 3) 2^-24 sum |x|. Changing one float
 * sample by 1e-3 changes the spectra (negative control; a one-ulp change may vanish in a float sum). */
/* n float samples offset + N(0, 1) (ADC-like data, already float) and the same values as double. */
static void float_samples(size_t n, uint64_t seed, double offset, float **xf, double **x)
{
    *xf = (float *)malloc(sizeof(float) * n);
    *x = (double *)malloc(sizeof(double) * n);
    msid_rng r;
    msid_rng_seed(&r, seed);
    for (size_t k = 0; k < n; ++k) {
        (*xf)[k] = (float)(offset + msid_rng_normal(&r));
        (*x)[k] = (double)(*xf)[k];
    }
}

static void test_f32_float_samples(void **state)
{
    (void)state;
    const uint32_t bins[3] = {1, 40, 499}, C = 2, K = 3, L = 3;
    msid_twiddle tw;
    void *mt = tsim_alloc(msid_twiddle_mem_size(P_));
    UT_STATUS(msid_twiddle_init(&tw, P_, mt, msid_twiddle_mem_size(P_)), MSID_OK);
    float *xf;
    double *x;
    float_samples((size_t)K * P_ * C, 17u, 2.0, &xf, &x);
    msid_cplx *a = (msid_cplx *)malloc(sizeof(msid_cplx) * K * L * C), *b = (msid_cplx *)malloc(sizeof(msid_cplx) * K * L * C);
    for (int path = 0; path < 2; ++path)
        for (int blocks = 0; blocks < 2; ++blocks) {
            const msid_dft_path p = path ? MSID_DFT_STREAM : MSID_DFT_STREAM_F32;
            run_periods(&tw, bins, L, C, K, p, x, NULL, blocks, a);
            run_periods(&tw, bins, L, C, K, p, NULL, xf, !blocks, b);
            UT_CHECK(memcmp(a, b, sizeof(msid_cplx) * K * L * C) == 0, "path %d blocks %d: float push differs", path,
                     blocks);
        }
    /* accuracy of the float path on float data (b holds it: path F32, blocks) */
    run_periods(&tw, bins, L, C, K, MSID_DFT_STREAM_F32, NULL, xf, 1, b);
    long double *twl = ut_tw_table(P_);
    double worst = 0.0;
    for (uint32_t k = 0; k < K; ++k)
        for (uint32_t c = 0; c < C; ++c) {
            double sa = 0.0;
            for (uint32_t n = 0; n < P_; ++n) sa += fabs(x[((size_t)k * P_ + n) * C + c]);
            const double bound = (P_ + 3.0) / 16777216.0 * sa;
            for (uint32_t l = 0; l < L; ++l) {
                long double re, im;
                ut_dft_ld(x + (size_t)k * P_ * C + c, C, P_, bins[l], twl, &re, &im);
                const msid_cplx z = b[((size_t)k * L + l) * C + c];
                const double e = fmax(fabs(z.re - (double)re), fabs(z.im - (double)im));
                UT_CHECK(e <= bound, "period %u line %u channel %u: error %g > bound %g", (unsigned)k, (unsigned)l,
                         (unsigned)c, e, bound);
                worst = fmax(worst, e / bound);
            }
        }
    print_message("float samples, float path: worst error %.4f of the bound\n", worst);
    /* negative control */
    xf[5 * C + 1] += 1e-3f;
    run_periods(&tw, bins, L, C, K, MSID_DFT_STREAM_F32, NULL, xf, 1, a);
    UT_CHECK(memcmp(a, b, sizeof(msid_cplx) * K * L * C) != 0, "%s", "a change of a float sample went unseen");
    free(twl);
    free(a);
    free(b);
    free(x);
    free(xf);
    tsim_free(mt);
}

/* msid_meas_push_f32 with the period end spread: the statistics equal msid_meas_push's. */
static void test_f32_meas_float_samples(void **state)
{
    (void)state;
    const uint32_t bins[4] = {1, 3, 40, 499}, K = 4, C = 3;
    msid_twiddle tw;
    void *mt = tsim_alloc(msid_twiddle_mem_size(P_));
    UT_STATUS(msid_twiddle_init(&tw, P_, mt, msid_twiddle_mem_size(P_)), MSID_OK);
    float *xf;
    double *x;
    float_samples((size_t)K * P_ * C, 21u, 0.0, &xf, &x);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P_; mc.n_inputs = 1; mc.n_outputs = 2; mc.n_experiments = 1; mc.n_lines = 3; mc.bins = bins;
    mc.n_detect = 1; mc.detect_bins = bins + 3; mc.twiddle = &tw; mc.path = MSID_DFT_STREAM_F32; mc.spread = 1;
    const size_t n = msid_meas_mem_size(&mc);
    void *m1 = tsim_alloc(n), *m2 = tsim_alloc(n);
    msid_meas a, b;
    UT_STATUS(msid_meas_init(&a, &mc, m1, n), MSID_OK);
    UT_STATUS(msid_meas_init(&b, &mc, m2, n), MSID_OK);
    UT_STATUS(msid_meas_begin(&a, 0), MSID_OK);
    UT_STATUS(msid_meas_begin(&b, 0), MSID_OK);
    for (uint32_t s = 0; s < K * P_; ++s) UT_STATUS(msid_meas_push(&a, x + (size_t)s * C, 1), MSID_OK);
    for (uint32_t s = 0; s < K * P_; s += 16) UT_STATUS(msid_meas_push_f32(&b, xf + (size_t)s * C, 16), MSID_OK);
    UT_STATUS(msid_meas_end(&a, NULL), MSID_OK);
    UT_STATUS(msid_meas_end(&b, NULL), MSID_OK);
    const msid_pstats *pa = msid_meas_stats(&a, 0), *pb = msid_meas_stats(&b, 0);
    UT_CHECK(pa->K == K && pb->K == K, "K %u %u", (unsigned)pa->K, (unsigned)pb->K);
    assert_memory_equal(pa->mean, pb->mean, sizeof(msid_cplx) * 4 * C);
    assert_memory_equal(pa->m2, pb->m2, sizeof(msid_cplx) * 4 * C * C);
    tsim_free(m1);
    tsim_free(m2);
    free(x);
    free(xf);
    tsim_free(mt);
}

static void test_f32_config(void **state)
{
    (void)state;
    const uint32_t bins[1] = {1};
    msid_twiddle tw;
    void *mt = tsim_alloc(msid_twiddle_mem_size(16));
    UT_STATUS(msid_twiddle_init(&tw, 16, mt, msid_twiddle_mem_size(16)), MSID_OK);
    msid_linedft_cfg c = {16, 1, 1, bins, NULL, MSID_DFT_STREAM_F32, NULL};
    const size_t n = msid_linedft_mem_size(&c);
    void *m = tsim_alloc(n);
    msid_linedft d;
    UT_STATUS(msid_linedft_init(&d, &c, m, n), MSID_E_NULL);   /* needs the twiddle table */
    c.twiddle = &tw;
    UT_STATUS(msid_linedft_init(&d, &c, m, n - 64), MSID_E_MEM_SIZE);
    UT_STATUS(msid_linedft_init(&d, &c, m, n), MSID_OK);
    /* AUTO never picks it */
    UT_CHECK(msid_linedft_choose(16, 1, 1, 0) == MSID_DFT_STREAM, "%d", 0);
    tsim_free(m);
    tsim_free(mt);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_f32_config),
        cmocka_unit_test(test_f32_blocks_bit_identical),
        cmocka_unit_test(test_f32_float_samples),
        cmocka_unit_test(test_f32_meas_float_samples),
        cmocka_unit_test(test_f32_error_bound_1e6_samples),
        cmocka_unit_test(test_f32_frf_close_to_double),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
