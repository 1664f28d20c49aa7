/* Golden values of the core, recorded before its objects got one layout routine each and
 * msid_frf_compute and msid_design_init their named steps, and before the spread period end:
 * every change since must give
 * the same bits. Each case hashes (FNV-1a over the bytes) every output of an
 * object for fixed seeds; the expected hashes were printed by this test on the
 * integration commit 1fc65f9 (MSID_GOLDEN_PRINT=1 prints the actual ones).
 * Memory sizes of every object are compared as plain numbers.
 *
 * Host only: the Cortex-M4F's software double may differ in the last bit of a
 * rare msid_cis_turns value (docs/target.md); tests/target/bits.c covers the
 * targets. The negative control perturbs one sample by one ulp and requires a
 * different FRF hash, so the hashes do look at the results. */
#include "unit_util.h"
#include <stdio.h>

typedef struct golden { uint64_t h; } golden;

static void gh_start(golden *g) { g->h = 0xcbf29ce484222325ull; }
static void gh(golden *g, const void *p, size_t n)
{
    const unsigned char *b = (const unsigned char *)p;
    for (size_t i = 0; i < n; ++i) { g->h ^= b[i]; g->h *= 0x100000001b3ull; }
}

static int golden_print(void) { return getenv("MSID_GOLDEN_PRINT") != NULL; }

static void check_hash(const char *name, uint64_t got, uint64_t want)
{
    if (golden_print()) { printf("golden %s 0x%016llxull\n", name, (unsigned long long)got); return; }
    UT_CHECK(got == want, "%s: hash 0x%016llx, recorded 0x%016llx", name, (unsigned long long)got,
             (unsigned long long)want);
}

/* ---- designs: coefficients, crest factors, condition numbers, aliasing map ---- */

static uint64_t design_hash(const msid_design_cfg *c, msid_status want)
{
    tsim_design t;
    const msid_status st = tsim_design_make(&t, c);
    UT_STATUS(st, want);
    golden g;
    gh_start(&g);
    if (st == MSID_OK) {
        const msid_design *d = &t.d;
        const size_t L = d->n_lines, nu = d->n_inputs, m = d->n_experiments;
        gh(&g, d->bins, L * sizeof(uint32_t));
        gh(&g, d->folded, L);
        gh(&g, d->omega, L * sizeof(double));
        gh(&g, d->amp, nu * L * sizeof(double));
        gh(&g, d->phase, nu * L * sizeof(double));
        gh(&g, d->coef, m * nu * L * sizeof(msid_cplx));
        gh(&g, d->cond, L * sizeof(double));
        gh(&g, &d->cond_max, sizeof(double));
        gh(&g, d->crest, m * nu * sizeof(double));
    } else {
        const msid_design_diag_t dg = msid_design_diag(&t.d);
        gh(&g, &dg.line_a, sizeof dg.line_a);
        gh(&g, &dg.line_b, sizeof dg.line_b);
        gh(&g, &dg.bin, sizeof dg.bin);
    }
    tsim_design_free(&t);
    return g.h;
}

static void test_golden_design(void **state)
{
    (void)state;
    /* DT, DC line, random phases, 2 inputs x 2 experiments (DFT pattern), direct crest */
    const uint32_t bins[7] = {0, 1, 5, 17, 40, 99, 63};
    msid_design_cfg c;
    memset(&c, 0, sizeof c);
    c.period = 200; c.n_lines = 7; c.bins = bins; c.n_inputs = 2; c.n_experiments = 2; c.seed = 99u;
    check_hash("design_dt_random", design_hash(&c, MSID_OK), 0xf75298f3c073f268ull);
    /* Schroeder phases, per-input amplitudes, 3 inputs x 4 experiments, Hadamard */
    double amp[3 * 7];
    for (int k = 0; k < 21; ++k) amp[k] = 0.25 + 0.125 * (double)(k % 5);
    c.n_inputs = 3; c.n_experiments = 4; c.pattern = MSID_PATTERN_HADAMARD;
    c.phase_mode = MSID_PHASE_SCHROEDER; c.amplitudes = amp; c.amp_per_input = 1;
    check_hash("design_schroeder_hadamard", design_hash(&c, MSID_OK), 0xdcbd9072cd71f482ull);
    /* user phases, 1 input, no crest factors */
    double ph[7];
    for (int k = 0; k < 7; ++k) ph[k] = 0.37 * (double)k - 1.5;
    memset(&c, 0, sizeof c);
    c.period = 200; c.n_lines = 7; c.bins = bins; c.n_inputs = 1; c.n_experiments = 3;
    c.phase_mode = MSID_PHASE_USER; c.phases = ph; c.crest = MSID_CREST_NONE;
    check_hash("design_user", design_hash(&c, MSID_OK), 0x12cacc482488906aull);
    /* continuous time: lines above the Nyquist frequency fold */
    const double h = 1e-3, w0 = 2.0 * M_PI / (256.0 * h);
    const double om[5] = {3 * w0, 100 * w0, 200 * w0, 300 * w0, 511 * w0};
    memset(&c, 0, sizeof c);
    c.period = 256; c.n_lines = 5; c.omega = om; c.sample_time = h; c.n_inputs = 2; c.n_experiments = 3;
    check_hash("design_ct_folded", design_hash(&c, MSID_OK), 0xdf573a40d9fdf0dbull);
    /* failures name the lines: a duplicate bin, an alias collision */
    const uint32_t dup[4] = {3, 9, 12, 9};
    memset(&c, 0, sizeof c);
    c.period = 64; c.n_lines = 4; c.bins = dup; c.n_inputs = 1; c.n_experiments = 1;
    check_hash("design_dup", design_hash(&c, MSID_E_LINE_DUP), 0xf1c80611aadffd1eull);
    const double coll[3] = {3 * w0, 253 * w0, 7 * w0};
    memset(&c, 0, sizeof c);
    c.period = 256; c.n_lines = 3; c.omega = coll; c.sample_time = h; c.n_inputs = 1; c.n_experiments = 1;
    check_hash("design_collision", design_hash(&c, MSID_E_ALIAS_COLLISION), 0xefccf13426ff0a17ull);
}

/* ---- memory sizes of every object, as numbers ---- */

static void test_golden_mem_sizes(void **state)
{
    (void)state;
    const uint32_t bins[7] = {0, 1, 5, 17, 40, 99, 63}, det[2] = {2, 70};
    size_t got[16];
    int n = 0;
    got[n++] = msid_twiddle_mem_size(200);
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = 200; dc.n_lines = 7; dc.bins = bins; dc.n_inputs = 2; dc.n_experiments = 2;
    got[n++] = msid_design_mem_size(&dc);
    dc.crest = MSID_CREST_FFT;
    got[n++] = msid_design_mem_size(&dc);
    msid_linedft_cfg lc = {200, 3, 7, bins, NULL, MSID_DFT_STREAM, NULL};
    got[n++] = msid_linedft_mem_size(&lc);
    lc.path = MSID_DFT_FFT;
    got[n++] = msid_linedft_mem_size(&lc);
    lc.path = MSID_DFT_STREAM_F32;
    got[n++] = msid_linedft_mem_size(&lc);
    msid_pstats_cfg pc = {9, 4, 1, 0, MSID_TRANSIENT_OFF, 0.0, 0};
    got[n++] = msid_pstats_mem_size(&pc);
    pc.max_periods = 11;
    got[n++] = msid_pstats_mem_size(&pc);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = 200; mc.n_inputs = 2; mc.n_outputs = 2; mc.n_experiments = 3; mc.n_lines = 6; mc.bins = bins + 1;
    mc.n_detect = 2; mc.detect_bins = det; mc.path = MSID_DFT_STREAM; mc.max_periods = 8;
    got[n++] = msid_meas_mem_size(&mc);
    mc.path = MSID_DFT_STREAM_F32; mc.max_periods = 0; mc.n_detect = 0;
    got[n++] = msid_meas_mem_size(&mc);
    msid_frf_cfg fc = {200, 2, 3, 3, 6, 2, NULL};
    got[n++] = msid_frf_mem_size(&fc);
    fc.n_detect = 0; fc.n_inputs = 1; fc.n_outputs = 1; fc.n_experiments = 1;
    got[n++] = msid_frf_mem_size(&fc);
    /* meas's memory holds its m = 3 msid_pstats structs, whose pointer and size_t members make them 192 bytes
     * on LP64 (x86-64, aarch64) and 152 on ILP32 (armhf, Cortex-M): 576 or, rounded up to 64, 512 bytes. */
#if UINTPTR_MAX > 0xFFFFFFFFu
    static const size_t want[12] = {3200, 1408, 5504, 896, 6912, 2304, 2880, 11008, 26560, 8896, 10880, 1344};
#else
    static const size_t want[12] = {3200, 1408, 5504, 896, 6912, 2304, 2880, 11008, 26496, 8832, 10880, 1344};
#endif
    for (int k = 0; k < n; ++k) {
        if (golden_print()) { printf("golden mem[%d] %zu\n", k, got[k]); continue; }
        UT_CHECK(got[k] == want[k], "mem size %d: %zu bytes, recorded %zu", k, got[k], want[k]);
    }
}

/* ---- FRF: every output of msid_frf after msid_meas, for fixed seeds ---- */

typedef struct frf_case {
    uint32_t P, K, L, nu, ny, m, D;
    const uint32_t *bins;        /* [L] lines the estimator looks at */
    const uint32_t *design_bins; /* [Ld] lines excited */
    uint32_t Ld;
    const uint32_t *det;
    const uint8_t *folded;
    msid_dft_path path;
    msid_transient_mode transient;
    uint32_t skip;
    int block;                   /* 0: uneven blocks; 1: one sample per call; 2: one whole period per call */
    double sig_u, sig_y, color;
    uint64_t seed;
    double poke;                 /* negative control: multiply sample 2P + 5 of output 0 by (1 + poke) */
} frf_case;

static uint64_t frf_hash(const frf_case *k, msid_status want)
{
    msid_design_cfg c;
    memset(&c, 0, sizeof c);
    c.period = k->P; c.n_lines = k->Ld; c.bins = k->design_bins; c.n_inputs = k->nu; c.n_experiments = k->m;
    c.seed = k->seed;
    tsim_design t;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    /* a stable 1st-order plant per channel pair, coupled */
    double A[1] = {0.6}, B[MSID_MAX_INPUTS], C[MSID_MAX_OUTPUTS], Dm[MSID_MAX_INPUTS * MSID_MAX_OUTPUTS];
    for (uint32_t j = 0; j < k->nu; ++j) B[j] = 1.0 + 0.5 * (double)j;
    for (uint32_t i = 0; i < k->ny; ++i) C[i] = 1.0 - 0.3 * (double)i;
    for (uint32_t q = 0; q < k->nu * k->ny; ++q) Dm[q] = 0.1 * (double)(q + 1u);
    msid_plant_cfg pc = {1, k->nu, k->ny, A, B, C, Dm};
    tsim_bench b;
    UT_STATUS(tsim_bench_make(&b, &pc, 2u * k->P), MSID_OK);
    if (k->color != 0.0) UT_STATUS(tsim_bench_color(&b, k->color), MSID_OK);
    for (uint32_t i = 0; i < k->ny; ++i) b.sigma_y[i] = k->sig_y * (1.0 + (double)i);
    for (uint32_t j = 0; j < k->nu; ++j) b.sigma_u[j] = k->sig_u;
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = k->P; mc.n_inputs = k->nu; mc.n_outputs = k->ny; mc.n_experiments = k->m; mc.n_lines = k->L;
    mc.bins = k->bins; mc.n_detect = k->D; mc.detect_bins = k->det; mc.twiddle = &t.tw; mc.path = k->path;
    mc.transient = k->transient; mc.max_periods = k->transient != MSID_TRANSIENT_OFF ? k->K : 0u;
    mc.skip_periods = k->skip;
    const size_t nm = msid_meas_mem_size(&mc);
    void *mm = tsim_alloc(nm);
    msid_meas ms;
    UT_STATUS(msid_meas_init(&ms, &mc, mm, nm), MSID_OK);
    const size_t C_ = (size_t)k->nu + k->ny, N = (size_t)k->K * k->P;
    double *rows = (double *)malloc(sizeof(double) * N * C_);
    msid_rng r;
    msid_rng_seed(&r, k->seed + 1u);
    for (uint32_t e = 0; e < k->m; ++e) {
        tsim_run(&b, &t, e, k->K, &r, rows);
        if (e == 0 && k->poke != 0.0) rows[(2u * k->P + 5u) * C_ + k->nu] *= 1.0 + k->poke;
        UT_STATUS(msid_meas_begin(&ms, e), MSID_OK);
        size_t done = 0, blk = 1;
        while (done < N) {
            size_t n = k->block == 1 ? 1u : (k->block == 2 ? k->P : blk);
            if (n > N - done) n = N - done;
            UT_STATUS(msid_meas_push(&ms, rows + done * C_, n), MSID_OK);
            done += n;
            blk = blk * 5 % 131 + 1;
        }
        UT_STATUS(msid_meas_end(&ms, NULL), MSID_OK);
    }
    msid_frf_cfg fc = {k->P, k->nu, k->ny, k->m, k->L, k->D, k->folded};
    const size_t nf = msid_frf_mem_size(&fc);
    void *fm = tsim_alloc(nf);
    msid_frf f;
    UT_STATUS(msid_frf_init(&f, &fc, fm, nf), MSID_OK);
    const msid_pstats *ps[MSID_MAX_EXPERIMENTS];
    for (uint32_t e = 0; e < k->m; ++e) ps[e] = msid_meas_stats(&ms, e);
    const msid_status st = msid_frf_compute(&f, ps);
    UT_STATUS(st, want);
    golden g;
    gh_start(&g);
    const size_t L = k->L, gg = (size_t)k->nu * k->ny, ny = k->ny;
    gh(&g, f.G, L * gg * sizeof(msid_cplx));
    gh(&g, f.cov, L * gg * gg * sizeof(msid_cplx));
    gh(&g, f.cov_ki, L * gg * gg * sizeof(msid_cplx));
    gh(&g, f.dof, L * sizeof(double));
    gh(&g, f.dof_ki, L * sizeof(double));
    gh(&g, f.noise, L * ny * ny * sizeof(msid_cplx));
    gh(&g, f.snr, L * ny * sizeof(double));
    gh(&g, f.cond, L * sizeof(double));
    gh(&g, f.urel, L * sizeof(double));
    gh(&g, f.usnr, L * sizeof(double));
    gh(&g, f.line_status, L);
    gh(&g, f.noise_time, ny * ny * sizeof(msid_cplx));
    if (k->D) {
        gh(&g, f.dmean, (size_t)k->D * k->m * ny * sizeof(msid_cplx));
        gh(&g, f.dvar, (size_t)k->D * ny * sizeof(double));
        gh(&g, f.dpval, (size_t)k->D * ny * sizeof(double));
    }
    const int32_t meta[3] = {f.bad_line, f.bad_experiment, (int32_t)f.K_total};
    gh(&g, meta, sizeof meta);
    for (uint32_t e = 0; e < k->m; ++e) {
        const msid_pstats_counts cn = msid_pstats_get_counts(ps[e]);
        const uint32_t cv[7] = {cn.offered, cn.skipped, cn.gap, cn.nonfinite, cn.transient_flagged,
                                cn.transient_dropped, cn.used};
        gh(&g, cv, sizeof cv);
        for (uint32_t p = 0; p < msid_pstats_history(ps[e]); ++p) {
            double pv;
            const int s = msid_pstats_period_state(ps[e], p, &pv);
            gh(&g, &s, sizeof s);
            gh(&g, &pv, sizeof pv);
        }
    }
    free(rows);
    tsim_free(fm);
    tsim_free(mm);
    tsim_bench_free(&b);
    tsim_design_free(&t);
    return g.h;
}

static const uint32_t B8[8] = {3, 10, 17, 24, 31, 38, 45, 52}, DET2[2] = {2, 60};
static const uint32_t B3[3] = {1, 7, 30}, B4[4] = {0, 5, 11, 23}, B4x[4] = {0, 5, 11, 29}, DET1[1] = {13};

/* 2x2, 2 experiments, noisy inputs, coloured noise, detection lines, transient DROP, uneven blocks */
static const frf_case CASE_MIMO = {128, 8, 8, 2, 2, 2, 2, B8, B8, 8, DET2, NULL, MSID_DFT_STREAM,
                                   MSID_TRANSIENT_DROP, 1, 0, 0.01, 0.05, 0.6, 11u, 0.0};

static void test_golden_frf(void **state)
{
    (void)state;
    check_hash("frf_mimo", frf_hash(&CASE_MIMO, MSID_OK), 0xbfd9c82fbcfccb62ull);
    /* SISO, folded lines, one sample per call, single precision streaming */
    static const uint8_t fold[3] = {0, 1, 1};
    const frf_case siso = {64, 5, 3, 1, 1, 1, 0, B3, B3, 3, NULL, fold, MSID_DFT_STREAM_F32,
                           MSID_TRANSIENT_OFF, 0, 1, 0.0, 0.1, 0.0, 5u, 0.0};
    check_hash("frf_siso_f32_folded", frf_hash(&siso, MSID_OK), 0x0fb9a3ee21084aa7ull);
    /* 3 inputs (SVD path of the condition number), 2 outputs, 3 experiments, DC line, whole periods,
       transient FLAG */
    const frf_case mi3 = {96, 6, 4, 3, 2, 3, 1, B4, B4, 4, DET1, NULL, MSID_DFT_STREAM,
                          MSID_TRANSIENT_FLAG, 0, 2, 0.02, 0.03, 0.0, 23u, 0.0};
    check_hash("frf_3in", frf_hash(&mi3, MSID_OK), 0xc6745a2fa10d315aull);
    /* one line the design does not excite: it is reported UNEXCITED, the rest solved */
    const frf_case unex = {96, 4, 4, 2, 1, 2, 0, B4x, B4, 4, NULL, NULL, MSID_DFT_STREAM,
                           MSID_TRANSIENT_OFF, 0, 0, 0.0, 0.05, 0.3, 31u, 0.0};
    check_hash("frf_unexcited", frf_hash(&unex, MSID_E_SINGULAR), 0x4d66fc348bd5bec3ull);
}

/* Negative control: a one-ulp change of one sample changes the hash. */
static void test_golden_detects_one_ulp(void **state)
{
    (void)state;
    frf_case k = CASE_MIMO;
    const uint64_t h0 = frf_hash(&k, MSID_OK);
    k.poke = 0x1p-52;
    const uint64_t h1 = frf_hash(&k, MSID_OK);
    UT_CHECK(h0 != h1, "a one-ulp change of one sample left the FRF hash at 0x%016llx", (unsigned long long)h0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_golden_design),
        cmocka_unit_test(test_golden_mem_sizes),
        cmocka_unit_test(test_golden_frf),
        cmocka_unit_test(test_golden_detects_one_ulp),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
