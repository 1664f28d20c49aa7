/* Bit-identity probe: built for the host and for each target CPU, it prints
 * one FNV-1a hash per group of library outputs the host promises to be
 * bit-identical on every IEEE-754 platform (lib/ is built with
 * -ffp-contract=off and computes these with +, -, *, /, sqrt only):
 *   cis     msid_cis_turns over 60,000 angles (the ranges of test_cis_random),
 *           every value printed ("v cis c s" in hex) so a comparison can count ulps
 *   log     msid_log and msid_sqrt over 60,000 arguments
 *   twiddle tables of periods 3, 7, 128, 1000, 4096
 *   rng     msid_rng uniform and normal streams
 *   gen     generated samples of a 2-input, 2-experiment design (both modes)
 *   frf     a 2x2 plant with 2 experiments, noisy inputs, coloured output noise:
 *           G, covariances, dof (msid_meas + msid_frf, tests/common simulator);
 *   frf_f32 the same through MSID_DFT_STREAM_F32
 * Lines starting with "libm" hold values that go through the C library's
 * exp/log (p-values); they are compared with a relative tolerance of 1e-12.
 * Everything else must match exactly, except where compare.py is told a
 * group's ulp bound (the Cortex-M4F's software double, see docs/target.md).
 * ctest (tests/target) runs both builds and compares. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "msid_test_sim.h"

static uint64_t H;
static void hb(const void *p, size_t n)
{
    const unsigned char *b = (const unsigned char *)p;
    for (size_t i = 0; i < n; ++i) { H ^= b[i]; H *= 0x100000001b3ull; }
}
static void start(void) { H = 0xcbf29ce484222325ull; }
static void put(const char *name)
{
    printf("%s %08lx%08lx\n", name, (unsigned long)(H >> 32), (unsigned long)(H & 0xffffffffu));
}

static void cis_and_log(void)
{
    msid_rng r;
    msid_rng_seed(&r, 20240601u);
    start();
    for (int i = 0; i < 60000; ++i) {
        const double u = msid_rng_uniform(&r) - 0.5;
        double t, c, s;
        switch (i % 6) {
        case 0: t = 8.0 * u; break;
        case 1: t = 2.0e6 * u; break;
        case 2: t = 2.0e-3 * u; break;
        case 3: t = (double)(int64_t)(2000.0 * u) + 1e-9 * u; break;
        case 4: t = -msid_rng_uniform(&r); break;
        default: t = 1.0e6 * u + 0.25 * (double)(i % 4) + 1e-12 * u; break;
        }
        msid_cis_turns(t, &c, &s);
        uint64_t bc, bs;
        memcpy(&bc, &c, 8);
        memcpy(&bs, &s, 8);
        printf("v cis %08lx%08lx %08lx%08lx\n", (unsigned long)(bc >> 32), (unsigned long)(bc & 0xffffffffu),
               (unsigned long)(bs >> 32), (unsigned long)(bs & 0xffffffffu));
    }
    start();
    for (int i = 0; i < 60000; ++i) {
        const double x = (i % 2) ? msid_rng_uniform(&r) * 4.0 : 1e-300 + msid_rng_uniform(&r) * 1e6 * (double)(i % 7);
        const double l = msid_log(x), q = msid_sqrt(x);
        hb(&l, sizeof l);
        hb(&q, sizeof q);
    }
    put("log");
}

static void twiddles(void)
{
    static const uint32_t Ps[5] = {3, 7, 128, 1000, 4096};
    start();
    for (int k = 0; k < 5; ++k) {
        const size_t n = msid_twiddle_mem_size(Ps[k]);
        void *mem = tsim_alloc(n);
        msid_twiddle tw;
        if (msid_twiddle_init(&tw, Ps[k], mem, n) != MSID_OK) { printf("twiddle init failed\n"); exit(1); }
        hb(tw.w, sizeof(msid_cplx) * Ps[k]);
        tsim_free(mem);
    }
    put("twiddle");
}

static void rng(void)
{
    msid_rng r;
    start();
    for (uint64_t seed = 0; seed < 4; ++seed) {
        msid_rng_seed(&r, seed);
        for (int i = 0; i < 5000; ++i) {
            const uint64_t a = msid_rng_u64(&r);
            const double u = msid_rng_uniform(&r), g = msid_rng_normal(&r);
            hb(&a, sizeof a);
            hb(&u, sizeof u);
            hb(&g, sizeof g);
        }
    }
    put("rng");
}

static void gen(void)
{
    const uint32_t bins[6] = {0, 1, 5, 17, 40, 99};
    msid_design_cfg c;
    memset(&c, 0, sizeof c);
    c.period = 200; c.n_lines = 6; c.bins = bins; c.n_inputs = 2; c.n_experiments = 2;
    c.phase_mode = MSID_PHASE_SCHROEDER;
    tsim_design t;
    if (tsim_design_make(&t, &c) != MSID_OK) { printf("design failed\n"); exit(1); }
    start();
    hb(t.d.coef, sizeof(msid_cplx) * 2 * 2 * 6);
    hb(t.d.crest, sizeof(double) * 4);
    for (int mode = 0; mode < 2; ++mode)
        for (uint32_t e = 0; e < 2; ++e) {
            msid_gen_cfg gc = {&t.d, &t.tw, e, mode};
            const size_t n = msid_gen_mem_size(&gc);
            void *mem = tsim_alloc(n);
            msid_gen g;
            if (msid_gen_init(&g, &gc, mem, n) != MSID_OK) { printf("gen init failed\n"); exit(1); }
            for (int k = 0; k < 400; ++k) {
                double u[2];
                msid_gen_next(&g, u);
                hb(u, sizeof u);
            }
            tsim_free(mem);
        }
    put("gen");
    tsim_design_free(&t);
}

static void frf(int f32)
{
    enum { P = 128, K = 6, L = 8, NU = 2, NY = 2, M = 2, D = 2 };
    uint32_t bins[L];
    for (uint32_t l = 0; l < L; ++l) bins[l] = 3u + 7u * l;
    const uint32_t det[D] = {2, 60};
    msid_design_cfg c;
    memset(&c, 0, sizeof c);
    c.period = P; c.n_lines = L; c.bins = bins; c.n_inputs = NU; c.n_experiments = M; c.seed = 77u;
    tsim_design t;
    if (tsim_design_make(&t, &c) != MSID_OK) { printf("design failed\n"); exit(1); }
    static const double A[4] = {0.5, 0.2, -0.3, 0.7}, B[4] = {1, 0, 0.5, 1}, C[4] = {1, 0.2, 0, 1};
    msid_plant_cfg pc = {2, NU, NY, A, B, C, NULL};
    tsim_bench b;
    if (tsim_bench_make(&b, &pc, 3 * P) != MSID_OK || tsim_bench_color(&b, 0.6) != MSID_OK) {
        printf("bench failed\n");
        exit(1);
    }
    b.sigma_y[0] = 0.05; b.sigma_y[1] = 0.02; b.sigma_u[0] = 0.01; b.sigma_u[1] = 0.01;
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = NU; mc.n_outputs = NY; mc.n_experiments = M; mc.n_lines = L; mc.bins = bins;
    mc.n_detect = D; mc.detect_bins = det; mc.twiddle = &t.tw; mc.path = f32 ? MSID_DFT_STREAM_F32 : MSID_DFT_STREAM;
    mc.max_periods = K; mc.transient = MSID_TRANSIENT_FLAG;
    const size_t nm = msid_meas_mem_size(&mc);
    void *mm = tsim_alloc(nm);
    msid_meas ms;
    if (msid_meas_init(&ms, &mc, mm, nm) != MSID_OK) { printf("meas init failed\n"); exit(1); }
    double *rows = (double *)malloc(sizeof(double) * K * P * (NU + NY));
    msid_rng r;
    msid_rng_seed(&r, 4242u);
    for (uint32_t e = 0; e < M; ++e) {
        tsim_run(&b, &t, e, K, &r, rows);
        msid_meas_begin(&ms, e);
        /* uneven blocks, as an acquisition would deliver them */
        size_t done = 0, blk = 1;
        while (done < (size_t)K * P) {
            const size_t k = blk < (size_t)K * P - done ? blk : (size_t)K * P - done;
            if (msid_meas_push(&ms, rows + done * (NU + NY), k) != MSID_OK) { printf("push failed\n"); exit(1); }
            done += k;
            blk = blk * 3 % 97 + 1;
        }
        msid_meas_end(&ms, NULL);
    }
    msid_frf_cfg fc = {P, NU, NY, M, L, D, NULL};
    const size_t nf = msid_frf_mem_size(&fc);
    void *fm = tsim_alloc(nf);
    msid_frf f;
    if (msid_frf_init(&f, &fc, fm, nf) != MSID_OK) { printf("frf init failed\n"); exit(1); }
    const msid_pstats *ps[M] = {msid_meas_stats(&ms, 0), msid_meas_stats(&ms, 1)};
    const msid_status st = msid_frf_compute(&f, ps);
    start();
    const int32_t st32 = (int32_t)st;   /* enums are 1 byte on arm-none-eabi (-fshort-enums) */
    hb(&st32, sizeof st32);
    for (uint32_t l = 0; l < L; ++l) {
        hb(msid_frf_G(&f, l), sizeof(msid_cplx) * NY * NU);
        hb(msid_frf_cov(&f, l), sizeof(msid_cplx) * 16);
        hb(msid_frf_cov_known_input(&f, l), sizeof(msid_cplx) * 16);
        const double dof = msid_frf_dof(&f, l), dki = msid_frf_dof_known_input(&f, l);
        hb(&dof, sizeof dof);
        hb(&dki, sizeof dki);
        hb(msid_frf_noise_cov(&f, l), sizeof(msid_cplx) * NY * NY);
    }
    for (uint32_t d = 0; d < D; ++d) hb(msid_frf_detect_var(&f, d), sizeof(double) * NY);
    put(f32 ? "frf_f32" : "frf");
    /* p-values use libm exp/log: printed, compared with a tolerance */
    for (uint32_t d = 0; d < D; ++d) {
        const double *p = msid_frf_detect_pvalue(&f, d);
        printf("libm dpval%u%s %.17g %.17g\n", (unsigned)d, f32 ? "_f32" : "", p[0], p[1]);
    }
    free(rows);
    tsim_free(fm);
    tsim_free(mm);
    tsim_bench_free(&b);
    tsim_design_free(&t);
}

int main(void)
{
    static char buf[8192];
    setvbuf(stdout, buf, _IOFBF, sizeof buf);   /* few semihosting writes */
    cis_and_log();
    twiddles();
    rng();
    gen();
    frf(0);
    frf(1);   /* the single-precision streaming path: float arithmetic is IEEE-754 too */
    return 0;
}
