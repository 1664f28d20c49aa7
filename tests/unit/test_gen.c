/* Generator: on-the-fly vs block vs waveform-table output (bit-identical),
 * periodicity, equality with msid_design_sample and an independent cosine sum,
 * seek, and error codes. */
#include "unit_util.h"

#define GOLDEN_HASH 0xc544ab8c1fcfc165ull

typedef struct {
    tsim_design t;
    uint32_t P, L, nu, m;
} fixture;

static void make_fixture(fixture *f, uint32_t P, uint32_t L, uint32_t nu, uint32_t m, uint64_t seed)
{
    msid_rng r;
    msid_rng_seed(&r, seed);
    uint32_t bins[64];
    ut_distinct(&r, L, 0, (P - 1) / 2, bins);
    msid_design_cfg c = ut_design_cfg(P, L, bins, nu, m);
    c.phase_mode = MSID_PHASE_RANDOM;
    c.seed = seed;
    UT_STATUS(tsim_design_make(&f->t, &c), MSID_OK);
    f->P = P; f->L = L; f->nu = nu; f->m = m;
}

static void *gen_make(msid_gen *g, const fixture *f, uint32_t e, int table)
{
    msid_gen_cfg gc = {&f->t.d, &f->t.tw, e, table};
    const size_t n = msid_gen_mem_size(&gc);
    void *mem = tsim_alloc(n);
    UT_STATUS(msid_gen_init(g, &gc, mem, n), MSID_OK);
    return mem;
}

static void test_modes_bit_identical(void **state)
{
    (void)state;
    const uint32_t Ps[] = {50, 64, 7};
    for (int fi = 0; fi < 3; ++fi) {
        fixture f;
        make_fixture(&f, Ps[fi], Ps[fi] == 7 ? 3 : 7, 3, 4, 11u + (uint64_t)fi);
        const uint32_t P = f.P, nu = f.nu, N = 3 * P;
        msid_rng r;
        msid_rng_seed(&r, 99u);
        for (uint32_t e = 0; e < f.m; ++e) {
            double *a = (double *)calloc((size_t)N * nu, sizeof(double));
            double *b = (double *)calloc((size_t)N * nu, sizeof(double));
            double *c = (double *)calloc((size_t)N * nu, sizeof(double));
            double *d = (double *)calloc((size_t)N * nu, sizeof(double));
            const size_t stride = nu + 2;
            double *w = (double *)malloc(sizeof(double) * N * stride);
            for (size_t k = 0; k < (size_t)N * stride; ++k) w[k] = -12345.0;
            msid_gen g1, g2, g3, g4, g5;
            void *m1 = gen_make(&g1, &f, e, 0), *m2 = gen_make(&g2, &f, e, 0), *m3 = gen_make(&g3, &f, e, 1);
            void *m4 = gen_make(&g4, &f, e, 1), *m5 = gen_make(&g5, &f, e, 0);
            for (uint32_t n = 0; n < N; ++n) msid_gen_next(&g1, a + (size_t)n * nu);
            for (uint32_t n = 0; n < N;) {  /* random block sizes, including 0 */
                const uint32_t k = ut_randint(&r, 0, P + 3);
                const uint32_t kk = k > N - n ? N - n : k;
                msid_gen_block(&g2, b + (size_t)n * nu, kk, nu);
                n += kk;
            }
            for (uint32_t n = 0; n < N; ++n) msid_gen_next(&g3, c + (size_t)n * nu);
            for (uint32_t n = 0; n < N;) {
                const uint32_t k = ut_randint(&r, 1, 17);
                const uint32_t kk = k > N - n ? N - n : k;
                msid_gen_block(&g4, d + (size_t)n * nu, kk, nu);
                n += kk;
            }
            msid_gen_block(&g5, w, N, stride);
            UT_CHECK(memcmp(a, b, sizeof(double) * N * nu) == 0, "P=%u e=%u next vs block", P, e);
            UT_CHECK(memcmp(a, c, sizeof(double) * N * nu) == 0, "P=%u e=%u next vs table", P, e);
            UT_CHECK(memcmp(a, d, sizeof(double) * N * nu) == 0, "P=%u e=%u next vs table block", P, e);
            for (uint32_t n = 0; n < N; ++n) {
                UT_CHECK(memcmp(a + (size_t)n * nu, w + (size_t)n * stride, sizeof(double) * nu) == 0, "stride n=%u", n);
                UT_CHECK(w[(size_t)n * stride + nu] == -12345.0 && w[(size_t)n * stride + nu + 1] == -12345.0, "stride gap n=%u", n);
            }
            UT_CHECK(g1.count == N && g2.count == N && g3.count == N && g1.pos == 0 && g3.pos == 0, "count %llu pos %u",
                     (unsigned long long)g1.count, g1.pos);
            /* periodic with period P, equal to design_sample, near the cosine sum */
            for (uint32_t n = 0; n < N; ++n)
                for (uint32_t i = 0; i < nu; ++i) {
                    const double v = a[(size_t)n * nu + i];
                    if (n >= P) UT_CHECK(memcmp(&v, &a[(size_t)(n - P) * nu + i], sizeof v) == 0, "n=%u i=%u not periodic", n, i);
                    const double s = msid_design_sample(&f.t.d, &f.t.tw, e, i, n);
                    UT_CHECK(memcmp(&v, &s, sizeof v) == 0, "n=%u i=%u: %.17g vs design_sample %.17g", n, i, v, s);
                    long double ref = 0.0L, asum = 0.0L;
                    for (uint32_t l = 0; l < f.L; ++l) {
                        const msid_cplx cf = msid_design_coef(&f.t.d, e, i, l);
                        long double wr, wi;
                        ut_tw_ld((uint64_t)f.t.d.bins[l] * n, P, &wr, &wi);
                        ref += cf.re * wr + cf.im * wi;   /* Re{c exp(+j 2 pi b n / P)} */
                        asum += ut_cabs(cf);
                    }
                    UT_CHECK(fabsl(v - ref) <= 1e-13L * asum, "n=%u i=%u: %.17g vs %.17Lg", n, i, v, ref);
                }
            /* the period carries the energy of the lines: sum u^2 = P/2 sum |c|^2 (+ P c0^2 for DC) */
            for (uint32_t i = 0; i < nu; ++i) {
                long double ss = 0.0L, want = 0.0L;
                for (uint32_t n = 0; n < P; ++n) ss += (long double)a[(size_t)n * nu + i] * a[(size_t)n * nu + i];
                for (uint32_t l = 0; l < f.L; ++l) {
                    const msid_cplx cf = msid_design_coef(&f.t.d, e, i, l);
                    want += f.t.d.bins[l] == 0 ? (long double)P * cf.re * cf.re : 0.5L * P * (cf.re * cf.re + cf.im * cf.im);
                }
                UT_CHECK(fabsl(ss - want) <= 1e-12L * want, "Parseval i=%u: %.17Lg vs %.17Lg", i, ss, want);
            }
            tsim_free(m1); tsim_free(m2); tsim_free(m3); tsim_free(m4); tsim_free(m5);
            free(a); free(b); free(c); free(d); free(w);
        }
        tsim_design_free(&f.t);
    }
}

static void test_seek(void **state)
{
    (void)state;
    fixture f;
    make_fixture(&f, 50, 6, 2, 2, 3u);
    const uint64_t targets[] = {0, 1, 49, 50, 51, 1234567, (1ull << 40) + 3, ~0ull};
    for (int table = 0; table < 2; ++table) {
        msid_gen g;
        void *mem = gen_make(&g, &f, 1, table);
        double u[2];
        for (int k = 0; k < 17; ++k) msid_gen_next(&g, u);
        for (size_t t = 0; t < sizeof targets / sizeof targets[0]; ++t) {
            msid_gen_seek(&g, targets[t]);
            UT_CHECK(g.count == 0 && g.pos == (uint32_t)(targets[t] % 50), "seek %llu", (unsigned long long)targets[t]);
            for (uint32_t k = 0; k < 60; ++k) {
                msid_gen_next(&g, u);
                const uint32_t n = (uint32_t)((targets[t] % 50 + k) % 50);
                for (uint32_t i = 0; i < 2; ++i) {
                    const double s = msid_design_sample(&f.t.d, &f.t.tw, 1, i, n);
                    UT_CHECK(memcmp(&u[i], &s, sizeof s) == 0, "table %d seek %llu k=%u", table, (unsigned long long)targets[t], k);
                }
            }
            UT_CHECK(g.count == 60, "%llu", (unsigned long long)g.count);
        }
        tsim_free(mem);
    }
    tsim_design_free(&f.t);
}

static void test_errors(void **state)
{
    (void)state;
    fixture f;
    make_fixture(&f, 32, 4, 2, 3, 5u);
    msid_twiddle tw16;
    void *mt = tsim_alloc(msid_twiddle_mem_size(16));
    UT_STATUS(msid_twiddle_init(&tw16, 16, mt, msid_twiddle_mem_size(16)), MSID_OK);
    msid_gen g;
    msid_gen_cfg gc = {&f.t.d, &f.t.tw, 0, 0};
    const size_t n0 = msid_gen_mem_size(&gc);
    UT_CHECK(n0 == ut_round64(4 * sizeof(uint32_t)), "%zu", n0);
    gc.waveform_table = 1;
    const size_t n1 = msid_gen_mem_size(&gc);
    UT_CHECK(n1 == ut_round64((size_t)32 * 2 * sizeof(double)), "%zu", n1);
    UT_CHECK(msid_gen_mem_size(NULL) == 0, "%d", 0);
    unsigned char *mem = (unsigned char *)tsim_alloc(n1 + 64);
    UT_STATUS(msid_gen_init(NULL, &gc, mem, n1), MSID_E_NULL);
    UT_STATUS(msid_gen_init(&g, NULL, mem, n1), MSID_E_NULL);
    msid_gen_cfg bad = gc;
    bad.design = NULL;
    UT_STATUS(msid_gen_init(&g, &bad, mem, n1), MSID_E_NULL);
    UT_CHECK(msid_gen_mem_size(&bad) == 0, "%d", 0);
    bad = gc;
    bad.twiddle = NULL;
    UT_STATUS(msid_gen_init(&g, &bad, mem, n1), MSID_E_NULL);
    bad = gc;
    bad.experiment = 3;
    UT_STATUS(msid_gen_init(&g, &bad, mem, n1), MSID_E_ARG);
    bad = gc;
    bad.twiddle = &tw16;
    UT_STATUS(msid_gen_init(&g, &bad, mem, n1), MSID_E_PERIOD);
    UT_STATUS(msid_gen_init(&g, &gc, NULL, n1), MSID_E_NULL);
    UT_STATUS(msid_gen_init(&g, &gc, ut_misalign(mem), n1), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_gen_init(&g, &gc, mem, n1 - 1), MSID_E_MEM_SIZE);
    gc.waveform_table = 0;
    UT_STATUS(msid_gen_init(&g, &gc, mem, n0 - 1), MSID_E_MEM_SIZE);
    UT_STATUS(msid_gen_init(&g, &gc, mem + 64, n0), MSID_OK);
    tsim_free(mem);
    tsim_free(mt);
    tsim_design_free(&f.t);
}

/* Cross-platform and cross-version reproducibility: the generated samples of a
 * fixed design are pinned by a hash of their bits. The core computes them with
 * +,-,*,/ only (msid_dmath), so any IEEE-754 platform must give this value; a
 * change here breaks every stored design's regeneration and must be deliberate. */
static uint64_t fnv1a(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = (const unsigned char *)p;
    for (size_t i = 0; i < n; ++i) { h ^= b[i]; h *= 0x100000001b3ull; }
    return h;
}

static void test_golden_samples(void **state)
{
    (void)state;
    const uint32_t bins[5] = {1, 3, 7, 20, 50};
    msid_design_cfg c = ut_design_cfg(128, 5, bins, 2, 2);
    c.phase_mode = MSID_PHASE_RANDOM; c.seed = 20261122u;
    tsim_design t;
    UT_STATUS(tsim_design_make(&t, &c), MSID_OK);
    uint64_t h = 0xcbf29ce484222325ull;
    for (uint32_t e = 0; e < 2; ++e) {
        msid_gen g;
        fixture f = {t, 128, 5, 2, 2};
        void *mem = gen_make(&g, &f, e, 0);
        double u[2];
        for (uint32_t n = 0; n < 256; ++n) { msid_gen_next(&g, u); h = fnv1a(h, u, sizeof u); }
        tsim_free(mem);
    }
    print_message("golden hash %016llx\n", (unsigned long long)h);
    UT_CHECK(h == GOLDEN_HASH, "generated samples changed: hash %016llx", (unsigned long long)h);
    tsim_design_free(&t);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_modes_bit_identical),
        cmocka_unit_test(test_seek),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_golden_samples),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
