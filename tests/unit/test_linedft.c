/* Line DFT property tests: streaming and FFT paths against a naive long-double
 * DFT, linearity, circular shift, bit-identical results for any block
 * partition, gap / non-finite period flags, path choice and error codes. */
#include "unit_util.h"
#ifdef MSID_HAVE_FFTW
#include "msid/msid_fft_fftw.h"
#include <fftw3.h>   /* fftw_malloc: inputs of FFTW's alignment, and one off it */
#endif

/* ---------- helpers ---------- */

typedef struct {
    msid_twiddle tw;
    void *mem_tw;
    msid_linedft d;
    void *mem;
} ldft;

static msid_status ld_make(ldft *o, uint32_t P, uint32_t C, uint32_t L, const uint32_t *bins,
                           msid_dft_path path, const msid_fft_backend *fft)
{
    memset(o, 0, sizeof *o);
    const size_t nt = msid_twiddle_mem_size(P);
    o->mem_tw = tsim_alloc(nt);
    msid_status st = msid_twiddle_init(&o->tw, P, o->mem_tw, nt);
    if (st != MSID_OK) return st;
    msid_linedft_cfg c = {P, C, L, bins, &o->tw, path, fft};
    const size_t n = msid_linedft_mem_size(&c);
    o->mem = tsim_alloc(n);
    return msid_linedft_init(&o->d, &c, o->mem, n);
}

static void ld_free(ldft *o)
{
    tsim_free(o->mem);
    tsim_free(o->mem_tw);
}

/* Push n rows in blocks of blocks[i % nb] samples (0: the rest), collecting
 * every completed period into spec[p*L*C] and flags[p]. Returns periods. */
static uint32_t ld_run(msid_linedft *d, const double *x, size_t n, const size_t *blocks, size_t nb,
                       msid_cplx *spec, uint32_t *flags)
{
    const size_t C = d->n_channels, LC = (size_t)d->n_lines * C;
    size_t pos = 0, bi = 0;
    uint32_t np = 0;
    while (pos < n) {
        size_t want = blocks[bi++ % nb];
        if (want == 0 || want > n - pos) want = n - pos;
        size_t done = 0;
        while (done < want) {
            const size_t k = msid_linedft_push(d, x + (pos + done) * C, want - done);
            done += k;
            if (msid_linedft_ready(d)) {
                memcpy(spec + (size_t)np * LC, msid_linedft_spectra(d), LC * sizeof(msid_cplx));
                flags[np++] = msid_linedft_flags(d);
                msid_linedft_release(d);
            } else {
                UT_CHECK(k > 0 && done == want, "push consumed %zu of %zu without completing a period", done, want);
            }
        }
        pos += want;
    }
    return np;
}

static const size_t WHOLE[1] = {0};

/* Test signal: DC offset, a few sinusoids on and off the bins, Gaussian noise. */
static void fill_signal(double *x, size_t nrows, uint32_t C, uint32_t P, msid_rng *r)
{
    for (uint32_t c = 0; c < C; ++c) {
        const double dc = msid_rng_normal(r), a1 = 1.0 + msid_rng_uniform(r), f1 = (double)ut_randint(r, 1, P / 2) / P;
        const double a2 = msid_rng_uniform(r), f2 = 0.37 * msid_rng_uniform(r), p1 = msid_rng_uniform(r);
        for (size_t n = 0; n < nrows; ++n)
            x[n * C + c] = dc + a1 * cos(UT_TWO_PI * (f1 * (double)(n % P) + p1)) + a2 * sin(UT_TWO_PI * f2 * (double)n) +
                           0.5 * msid_rng_normal(r);
    }
}

/* Max |X - naive DFT| over all lines and channels of period p, relative to max |naive|. */
static double period_rel_err(const msid_cplx *spec, const double *x, uint32_t P, uint32_t C, uint32_t L,
                             const uint32_t *bins, const long double *tw, uint32_t p, double *maxabs)
{
    long double emax = 0.0L, xmax = 0.0L;
    for (uint32_t l = 0; l < L; ++l)
        for (uint32_t c = 0; c < C; ++c) {
            long double re, im;
            ut_dft_ld(x + (size_t)p * P * C + c, C, P, bins[l], tw, &re, &im);
            const msid_cplx X = spec[(size_t)l * C + c];
            const long double e = sqrtl((X.re - re) * (X.re - re) + (X.im - im) * (X.im - im));
            emax = fmaxl(emax, e);
            xmax = fmaxl(xmax, sqrtl(re * re + im * im));
        }
    if (maxabs) *maxabs = (double)xmax;
    return (double)(emax / xmax);
}

/* Bins for a test: L distinct in [0, P/2], with 0 and P/2 (floor) when L allows. */
static void pick_bins(msid_rng *r, uint32_t P, uint32_t L, uint32_t *bins)
{
    ut_distinct(r, L, 0, P / 2, bins);
    if (L >= 2) {
        /* force 0 and P/2 into the set (swap them in if missing) */
        int h0 = 0, hn = 0;
        for (uint32_t l = 0; l < L; ++l) { h0 |= bins[l] == 0; hn |= bins[l] == P / 2; }
        if (!h0) { for (uint32_t l = 0; l < L; ++l) if (bins[l] != P / 2) { bins[l] = 0; break; } }
        if (!hn) { for (uint32_t l = L; l-- > 0;) if (bins[l] != 0) { bins[l] = P / 2; break; } }
    }
}

/* A backend computing the exact DFT naively: exercises the FFT path's
 * buffering and bin selection independently of FFTW. */
typedef struct { uint32_t P; long double *tw; int calls; int fail; } naive_ctx;
static msid_status naive_r2c(void *ctx, const double *in, msid_cplx *out)
{
    naive_ctx *c = (naive_ctx *)ctx;
    c->calls++;
    if (c->fail) return MSID_E_BACKEND;
    for (uint32_t k = 0; k <= c->P / 2; ++k) {
        long double re, im;
        ut_dft_ld(in, 1, c->P, k, c->tw, &re, &im);
        out[k].re = (double)re;
        out[k].im = (double)im;
    }
    return MSID_OK;
}
static msid_fft_backend naive_backend(naive_ctx *ctx, uint32_t P)
{
    ctx->P = P;
    ctx->tw = ut_tw_table(P);
    ctx->calls = 0;
    ctx->fail = 0;
    msid_fft_backend be = {"naive", P, ctx, naive_r2c, NULL};
    return be;
}

/* ---------- streaming path vs naive DFT ---------- */

static void test_stream_vs_naive(void **state)
{
    (void)state;
    const uint32_t Ps[] = {2, 7, 16, 1000, 1023};
    msid_rng r;
    msid_rng_seed(&r, 1001u);
    for (size_t pi = 0; pi < sizeof Ps / sizeof Ps[0]; ++pi) {
        const uint32_t P = Ps[pi];
        long double *tw = ut_tw_table(P);
        const uint32_t K = 2;
        double *x = (double *)malloc(sizeof(double) * K * P * 5);
        for (uint32_t C = 1; C <= 5; ++C)
            for (uint32_t L = 1; L <= 9 && L <= P / 2 + 1; ++L) {
                uint32_t bins[9];
                pick_bins(&r, P, L, bins);
                fill_signal(x, (size_t)K * P, C, P, &r);
                ldft o;
                UT_STATUS(ld_make(&o, P, C, L, bins, MSID_DFT_STREAM, NULL), MSID_OK);
                UT_CHECK(o.d.path == MSID_DFT_STREAM, "%d", (int)o.d.path);
                msid_cplx spec[2 * 9 * 5];
                uint32_t flags[2];
                const size_t blk[] = {P / 3 + 1};
                UT_CHECK(ld_run(&o.d, x, (size_t)K * P, blk, 1, spec, flags) == K, "P=%u", P);
                for (uint32_t p = 0; p < K; ++p) {
                    const double e = period_rel_err(spec + (size_t)p * L * C, x, P, C, L, bins, tw, p, NULL);
                    UT_CHECK(e <= 1e-12 && flags[p] == 0, "P=%u C=%u L=%u period %u: rel err %.3g flags %u", P, C, L, p, e, flags[p]);
                }
                ld_free(&o);
            }
        free(x);
        free(tw);
    }
}

/* ---------- FFT path ---------- */

static void test_fft_path_naive_backend(void **state)
{
    (void)state;
    const uint32_t P = 90, C = 3, L = 6, K = 3;
    const uint32_t bins[] = {45, 0, 7, 3, 44, 20};
    naive_ctx ctx;
    const msid_fft_backend be = naive_backend(&ctx, P);
    msid_rng r;
    msid_rng_seed(&r, 5u);
    double x[3 * 90 * 3];
    fill_signal(x, (size_t)K * P, C, P, &r);
    ldft o;
    UT_STATUS(ld_make(&o, P, C, L, bins, MSID_DFT_FFT, &be), MSID_OK);
    UT_CHECK(o.d.path == MSID_DFT_FFT, "%d", (int)o.d.path);
    msid_cplx spec[3 * 6 * 3];
    uint32_t flags[3];
    const size_t blk[] = {13};
    UT_CHECK(ld_run(&o.d, x, (size_t)K * P, blk, 1, spec, flags) == K, "%d", 0);
    UT_CHECK(ctx.calls == (int)(K * C), "backend calls %d", ctx.calls);
    for (uint32_t p = 0; p < K; ++p) {
        const double e = period_rel_err(spec + (size_t)p * L * C, x, P, C, L, bins, ctx.tw, p, NULL);
        UT_CHECK(e <= 1e-15 && flags[p] == 0, "period %u rel err %.3g", p, e);
    }
    UT_STATUS(msid_linedft_error(&o.d), MSID_OK);
    ld_free(&o);
    /* a failing backend: sticky error and the period is flagged non-finite */
    ctx.fail = 1;
    UT_STATUS(ld_make(&o, P, C, L, bins, MSID_DFT_FFT, &be), MSID_OK);
    UT_CHECK(ld_run(&o.d, x, P, WHOLE, 1, spec, flags) == 1, "%d", 0);
    UT_CHECK(flags[0] & MSID_PERIOD_NONFINITE, "flags %u", flags[0]);
    UT_STATUS(msid_linedft_error(&o.d), MSID_E_BACKEND);
    ld_free(&o);
    free(ctx.tw);
}

static void test_fftw_vs_stream(void **state)
{
    (void)state;
#ifdef MSID_HAVE_FFTW
    const uint32_t Ps[] = {1024, 4096};
    msid_rng r;
    msid_rng_seed(&r, 777u);
    for (int pi = 0; pi < 2; ++pi) {
        const uint32_t P = Ps[pi], C = 3, L = 200, K = 2;
        uint32_t bins[200];
        pick_bins(&r, P, L, bins);
        double *x = (double *)malloc(sizeof(double) * K * P * C);
        fill_signal(x, (size_t)K * P, C, P, &r);
        for (int lines = 0; lines < 2; ++lines) {   /* the real plan, and the lines-only complex one */
        msid_fft_fftw f;
        UT_STATUS(msid_fft_fftw_create(&f, P, lines ? MSID_FFTW_LINES : MSID_FFTW_ESTIMATE), MSID_OK);
        ldft a, b;
        UT_STATUS(ld_make(&a, P, C, L, bins, MSID_DFT_STREAM, NULL), MSID_OK);
        UT_STATUS(ld_make(&b, P, C, L, bins, MSID_DFT_FFT, &f.be), MSID_OK);
        msid_cplx *sa = (msid_cplx *)malloc(sizeof(msid_cplx) * K * L * C), *sb = (msid_cplx *)malloc(sizeof(msid_cplx) * K * L * C);
        uint32_t fa[2], fb[2];
        const size_t blk[] = {333};
        UT_CHECK(ld_run(&a.d, x, (size_t)K * P, blk, 1, sa, fa) == K && ld_run(&b.d, x, (size_t)K * P, WHOLE, 1, sb, fb) == K, "%d", 0);
        long double *tw = ut_tw_table(P);
        for (uint32_t p = 0; p < K; ++p) {
            double xmax = 0.0, dmax = 0.0;
            for (size_t k = 0; k < (size_t)L * C; ++k) {
                xmax = fmax(xmax, ut_cabs(sa[p * L * C + k]));
                dmax = fmax(dmax, ut_cdist(sa[p * L * C + k], sb[p * L * C + k]));
            }
            UT_CHECK(dmax <= 1e-12 * xmax && fa[p] == 0 && fb[p] == 0, "P=%u period %u: max diff %.3g, max |X| %.3g", P, p, dmax, xmax);
            const double e = period_rel_err(sb + (size_t)p * L * C, x, P, C, L, bins, tw, p, NULL);
            UT_CHECK(e <= 1e-12, "P=%u FFTW vs naive %.3g", P, e);
        }
        free(tw);
        free(sa); free(sb);
        ld_free(&a); ld_free(&b);
        msid_fft_fftw_destroy(&f);
        }
        free(x);
    }
#else
    skip();
#endif
}

/* MSID_FFTW_LINES: the real DFT at chosen bins from one complex DFT of P/2 points, against
 * the naive long-double DFT (even P: the split; odd P: the real plan), stride > 1, DC and
 * Nyquist exactly real, the whole spectrum by r2c, an input of another alignment (copied: the
 * same bits), the twiddle cache when the same array holds other bins (a stale cache would
 * give the old bins' twiddles: wrong values), a bin beyond P/2 refused. ESTIMATE keeps no
 * r2c_bins (the core picks from r2c: unchanged bits). */
static void test_fftw_lines_backend(void **state)
{
    (void)state;
#ifdef MSID_HAVE_FFTW
    const uint32_t Ps[] = {2, 4, 6, 64, 1023, 1024, 4096};
    msid_rng r;
    msid_rng_seed(&r, 4242u);
    for (size_t pi = 0; pi < sizeof Ps / sizeof Ps[0]; ++pi) {
        const uint32_t P = Ps[pi], H = P / 2u, S = 3;
        double *x = (double *)fftw_malloc(sizeof(double) * (P + 1u));
        for (uint32_t n = 0; n < P; ++n) x[n] = msid_rng_normal(&r) + (n % 7u == 3u ? 5.0 : 0.0);
        long double *tw = ut_tw_table(P);
        msid_fft_fftw f, e;
        UT_STATUS(msid_fft_fftw_create(&f, P, MSID_FFTW_LINES), MSID_OK);
        UT_STATUS(msid_fft_fftw_create(&e, P, MSID_FFTW_ESTIMATE), MSID_OK);
        UT_CHECK(f.be.r2c_bins != NULL && e.be.r2c_bins == NULL && f.half == (P % 2u == 0u), "P=%u", P);
        /* exact spectrum and its scale */
        msid_cplx *X0 = (msid_cplx *)malloc(sizeof(msid_cplx) * (H + 1u));
        double xmax = 0.0;
        for (uint32_t k = 0; k <= H; ++k) {
            long double re, im;
            ut_dft_ld(x, 1, P, k, tw, &re, &im);
            X0[k].re = (double)re;
            X0[k].im = (double)im;
            xmax = fmax(xmax, ut_cabs(X0[k]));
        }
        /* bins: all of them reversed (the split's index pairs k, N-k in any order), stride S */
        const uint32_t n = H + 1u;
        uint32_t *bins = (uint32_t *)malloc(sizeof(uint32_t) * n);
        for (uint32_t i = 0; i < n; ++i) bins[i] = H - i;
        msid_cplx *out = (msid_cplx *)malloc(sizeof(msid_cplx) * n * S), *full = (msid_cplx *)malloc(sizeof(msid_cplx) * n);
        for (int pass = 0; pass < 2; ++pass) {   /* pass 1: the same array, other bins (cache) */
            if (pass) for (uint32_t i = 0; i < n; ++i) bins[i] = (uint32_t)((i * 7u + 1u) % n);
            UT_STATUS(f.be.r2c_bins(f.be.ctx, x, bins, n, out, S), MSID_OK);
            double dmax = 0.0;
            for (uint32_t i = 0; i < n; ++i) dmax = fmax(dmax, ut_cdist(out[(size_t)i * S], X0[bins[i]]));
            UT_CHECK(dmax <= 1e-13 * xmax, "P=%u pass %d: r2c_bins off by %.3g of %.3g", P, pass, dmax, xmax);
            for (uint32_t i = 0; i < n; ++i)
                if (bins[i] == 0u || (P % 2u == 0u && bins[i] == H))
                    UT_CHECK(out[(size_t)i * S].im == 0.0, "P=%u bin %u not real: %.3g", P, bins[i], out[(size_t)i * S].im);
        }
        /* the whole spectrum by r2c, and an input of another alignment: the same bits as aligned */
        UT_STATUS(f.be.r2c(f.be.ctx, x, full), MSID_OK);
        double dmax = 0.0;
        for (uint32_t k = 0; k <= H; ++k) dmax = fmax(dmax, ut_cdist(full[k], X0[k]));
        UT_CHECK(dmax <= 1e-13 * xmax, "P=%u: r2c off by %.3g of %.3g", P, dmax, xmax);
        double *xs = (double *)fftw_malloc(sizeof(double) * (P + 1u));
        memcpy(xs + 1, x, sizeof(double) * P);
        UT_STATUS(f.be.r2c_bins(f.be.ctx, x, bins, n, out, 1u), MSID_OK);
        msid_cplx *out2 = (msid_cplx *)malloc(sizeof(msid_cplx) * n);
        UT_STATUS(f.be.r2c_bins(f.be.ctx, xs + 1, bins, n, out2, 1u), MSID_OK);
        UT_CHECK(memcmp(out, out2, sizeof(msid_cplx) * n) == 0, "P=%u: misaligned input changed the bits", P);
        /* a bin beyond P/2 */
        const uint32_t bad = H + 1u;
        UT_STATUS(f.be.r2c_bins(f.be.ctx, x, &bad, 1u, out, 1u), MSID_E_BACKEND);
        free(out2); fftw_free(xs);
        free(out); free(full); free(bins); free(X0); free(tw); fftw_free(x);
        msid_fft_fftw_destroy(&f);
        msid_fft_fftw_destroy(&e);
    }
    msid_fft_fftw z;
    UT_STATUS(msid_fft_fftw_create(&z, 64, (msid_fftw_effort)7), MSID_E_ARG);
#else
    skip();
#endif
}

/* ---------- algebraic properties ---------- */

static void test_linearity_and_shift(void **state)
{
    (void)state;
    const uint32_t Ps[] = {1000, 1023, 64};
    msid_rng r;
    msid_rng_seed(&r, 31u);
    for (int pi = 0; pi < 3; ++pi) {
        const uint32_t P = Ps[pi], C = 2, L = 9;
        uint32_t bins[9];
        pick_bins(&r, P, L, bins);
        double *x = (double *)malloc(sizeof(double) * P * C * 4);
        double *y = x + (size_t)P * C, *z = y + (size_t)P * C, *s = z + (size_t)P * C;
        fill_signal(x, P, C, P, &r);
        fill_signal(y, P, C, P, &r);
        const double a = 0.7, b = -1.3;
        for (size_t k = 0; k < (size_t)P * C; ++k) z[k] = a * x[k] + b * y[k];
        const uint32_t shifts[] = {1, 17, P / 2, P - 1};
        msid_cplx X[9 * 2], Y[9 * 2], Z[9 * 2], S[9 * 2];
        uint32_t fl[1];
        ldft o;
        UT_STATUS(ld_make(&o, P, C, L, bins, MSID_DFT_STREAM, NULL), MSID_OK);
        ld_run(&o.d, x, P, WHOLE, 1, X, fl);
        ld_run(&o.d, y, P, WHOLE, 1, Y, fl);
        ld_run(&o.d, z, P, WHOLE, 1, Z, fl);
        double xmax = 0.0, emax = 0.0;
        for (uint32_t k = 0; k < L * C; ++k) {
            const msid_cplx w = ut_c(a * X[k].re + b * Y[k].re, a * X[k].im + b * Y[k].im);
            xmax = fmax(xmax, fmax(ut_cabs(w), fmax(ut_cabs(X[k]), ut_cabs(Y[k]))));
            emax = fmax(emax, ut_cdist(w, Z[k]));
        }
        UT_CHECK(emax <= 1e-12 * xmax, "P=%u linearity err %.3g of %.3g", P, emax, xmax);
        for (int si = 0; si < 4; ++si) {
            const uint32_t sh = shifts[si];
            for (uint32_t n = 0; n < P; ++n)
                for (uint32_t c = 0; c < C; ++c) s[(size_t)n * C + c] = x[(size_t)((n + sh) % P) * C + c];
            ld_run(&o.d, s, P, WHOLE, 1, S, fl);
            double smax = 0.0, xm = 0.0;
            for (uint32_t l = 0; l < L; ++l) {
                long double wr, wi;
                ut_tw_ld((uint64_t)bins[l] * sh, P, &wr, &wi);
                wi = -wi;  /* exp(+j 2 pi b s / P) */
                for (uint32_t c = 0; c < C; ++c) {
                    const msid_cplx x0 = X[l * C + c];
                    const long double er = x0.re * wr - x0.im * wi - S[l * C + c].re;
                    const long double ei = x0.re * wi + x0.im * wr - S[l * C + c].im;
                    smax = fmax(smax, (double)sqrtl(er * er + ei * ei));
                    xm = fmax(xm, ut_cabs(x0));
                }
            }
            UT_CHECK(smax <= 1e-12 * xm, "P=%u shift %u: err %.3g of %.3g", P, sh, smax, xm);
        }
        ld_free(&o);
        free(x);
    }
}

/* ---------- chunking determinism ---------- */

static void check_chunking(uint32_t P, uint32_t C, uint32_t L, const uint32_t *bins, msid_dft_path path,
                           const msid_fft_backend *be, const double *x, msid_rng *r)
{
    const uint32_t K = 5;
    const size_t N = (size_t)K * P, LC = (size_t)L * C;
    size_t rnd[64];
    for (int k = 0; k < 64; ++k) rnd[k] = 1 + msid_rng_u64(r) % (2 * P);
    const size_t one[] = {1}, seven[] = {7}, b256[] = {256};
    const size_t *sets[] = {one, seven, b256, rnd, WHOLE};
    const size_t nsets[] = {1, 1, 1, 64, 1};
    msid_cplx *ref = (msid_cplx *)malloc(sizeof(msid_cplx) * K * LC), *got = (msid_cplx *)malloc(sizeof(msid_cplx) * K * LC);
    uint32_t fr[5], fg[5];
    for (int s = 0; s < 5; ++s) {
        ldft o;
        UT_STATUS(ld_make(&o, P, C, L, bins, path, be), MSID_OK);
        UT_CHECK(ld_run(&o.d, x, N, sets[s], nsets[s], s ? got : ref, s ? fg : fr) == K, "set %d", s);
        if (s) {
            for (uint32_t p = 0; p < K; ++p)
                UT_CHECK(memcmp(ref + p * LC, got + p * LC, LC * sizeof(msid_cplx)) == 0 && fr[p] == fg[p],
                         "path %d P=%u C=%u L=%u: block set %d differs in period %u", (int)path, P, C, L, s, p);
        }
        UT_CHECK(o.d.periods == K, "%llu", (unsigned long long)o.d.periods);
        ld_free(&o);
    }
    free(ref);
    free(got);
}

static void test_chunking_bit_identical(void **state)
{
    (void)state;
    const uint32_t P = 1000;
    msid_rng r;
    msid_rng_seed(&r, 2718u);
    double *x = (double *)malloc(sizeof(double) * 5 * P * 5);
    naive_ctx ctx;
    const msid_fft_backend nb = naive_backend(&ctx, P);
#ifdef MSID_HAVE_FFTW
    msid_fft_fftw f;
    UT_STATUS(msid_fft_fftw_create(&f, P, MSID_FFTW_ESTIMATE), MSID_OK);
    const msid_fft_backend *be = &f.be;
#else
    const msid_fft_backend *be = &nb;
#endif
    const uint32_t Cs[] = {1, 3, 4, 5};
    const uint32_t Ls[] = {13, 5, 9, 2};
    for (int k = 0; k < 4; ++k) {
        uint32_t bins[13];
        pick_bins(&r, P, Ls[k], bins);
        fill_signal(x, 5 * P, Cs[k], P, &r);
        check_chunking(P, Cs[k], Ls[k], bins, MSID_DFT_STREAM, NULL, x, &r);
        check_chunking(P, Cs[k], Ls[k], bins, MSID_DFT_FFT, be, x, &r);
    }
    /* many lines through the 4-line kernels, odd P */
    uint32_t bins[200];
    pick_bins(&r, 511, 101, bins);
    fill_signal(x, 5 * 511, 3, 511, &r);
    check_chunking(511, 3, 101, bins, MSID_DFT_STREAM, NULL, x, &r);
#ifdef MSID_HAVE_FFTW
    msid_fft_fftw_destroy(&f);
#endif
    (void)nb;
    free(ctx.tw);
    free(x);
}

/* ---------- every kernel: the plain sample-order sum, bit for bit ---------- */

/* The streaming sums equal acc += x*w.re, acc += x*w.im in sample order with the library's own
 * twiddles, exactly, whichever kernel runs: the vector kernel (msid_linedft_vec.c: SSE2 on x86-64,
 * Advanced SIMD on AArch64) with its odd-channel tail and the scalar line tail here; the scalar
 * kernels in test_linedft_scalar (the core built with MSID_NO_SIMD) and on 32-bit ARM. 6 lines =
 * 4 + 2, 3 channels = a pair + 1, blocks of 256 and 7 samples. */
static void test_kernels_equal_sample_order_sum(void **state)
{
    (void)state;
    const uint32_t P = 1000, C = 3, L = 6;
    const uint32_t bins[6] = {0, 1, 7, 499, 500, 123};
    msid_rng r;
    msid_rng_seed(&r, 4242u);
    double *x = (double *)malloc(sizeof(double) * P * C);
    fill_signal(x, P, C, P, &r);
    const size_t blocks[][1] = {{256}, {7}};
    for (int b = 0; b < 2; ++b) {
        ldft o;
        UT_STATUS(ld_make(&o, P, C, L, bins, MSID_DFT_STREAM, NULL), MSID_OK);
        msid_cplx spec[6 * 3];
        uint32_t flags[1];
        UT_CHECK(ld_run(&o.d, x, P, blocks[b], 1, spec, flags) == 1, "block %zu", blocks[b][0]);
        for (uint32_t l = 0; l < L; ++l)
            for (uint32_t c = 0; c < C; ++c) {
                double re = 0.0, im = 0.0;
                for (uint32_t n = 0; n < P; ++n) {
                    const msid_cplx w = o.tw.w[(uint64_t)bins[l] * n % P];
                    const double v = x[(size_t)n * C + c];
                    re += v * w.re;
                    im += v * w.im;
                }
                const msid_cplx g = spec[l * C + c];
                UT_CHECK(memcmp(&g.re, &re, sizeof re) == 0 && memcmp(&g.im, &im, sizeof im) == 0,
                         "block %zu line %u channel %u: %.17g%+.17gj vs the sample-order sum %.17g%+.17gj",
                         blocks[b][0], l, c, g.re, g.im, re, im);
            }
        ld_free(&o);
    }
    free(x);
}

/* ---------- gaps and non-finite samples ---------- */

static void check_gaps(msid_dft_path path, const msid_fft_backend *be)
{
    const uint32_t P = 64, C = 2, L = 4, K = 8;
    const uint32_t bins[] = {0, 1, 5, 32};
    msid_rng r;
    msid_rng_seed(&r, 44u);
    double x[8 * 64 * 2];
    fill_signal(x, (size_t)K * P, C, P, &r);
    long double *tw = ut_tw_table(P);
    ldft o;
    UT_STATUS(ld_make(&o, P, C, L, bins, path, be), MSID_OK);
    msid_cplx spec[8][4 * 2];
    uint32_t flags[8];
    uint32_t np = 0;
#define ROWS(n0) (x + (size_t)(n0) * C)
#define COLLECT()                                                      \
    do {                                                               \
        if (msid_linedft_ready(&o.d)) {                                \
            memcpy(spec[np], msid_linedft_spectra(&o.d), sizeof spec[0]); \
            flags[np++] = msid_linedft_flags(&o.d);                    \
            msid_linedft_release(&o.d);                                \
        }                                                              \
    } while (0)
    /* period 0: clean */
    UT_CHECK(msid_linedft_push(&o.d, ROWS(0), P) == P, "%d", 0);
    COLLECT();
    /* period 1: 5 samples lost in the middle */
    msid_linedft_push(&o.d, ROWS(P), 10);
    UT_CHECK(msid_linedft_push_gap(&o.d, 5) == 5, "%d", 1);
    msid_linedft_push(&o.d, ROWS(P + 15), P - 15);
    COLLECT();
    /* period 2: clean */
    msid_linedft_push(&o.d, ROWS(2 * P), P);
    COLLECT();
    /* periods 3-4: a gap across the boundary */
    msid_linedft_push(&o.d, ROWS(3 * P), 30);
    size_t left = (P - 30) + 20;
    const size_t g1 = msid_linedft_push_gap(&o.d, left);
    UT_CHECK(g1 == P - 30, "push_gap stops at the period end: %zu", g1);
    UT_CHECK(msid_linedft_push_gap(&o.d, 1) == 0 && msid_linedft_push(&o.d, ROWS(0), 1) == 0, "%s", "ready period blocks pushing");
    COLLECT();
    left -= g1;
    UT_CHECK(msid_linedft_push_gap(&o.d, left) == left, "%d", 3);
    msid_linedft_push(&o.d, ROWS(4 * P + 20), P - 20);
    COLLECT();
    /* period 5: marked before its first sample */
    msid_linedft_mark_gap(&o.d);
    msid_linedft_push(&o.d, ROWS(5 * P), P);
    COLLECT();
    /* period 6: marked in the middle */
    msid_linedft_push(&o.d, ROWS(6 * P), 32);
    msid_linedft_mark_gap(&o.d);
    msid_linedft_push(&o.d, ROWS(6 * P + 32), 32);
    COLLECT();
    /* period 7: clean again, and still aligned */
    msid_linedft_push(&o.d, ROWS(7 * P), P);
    COLLECT();
    UT_CHECK(np == K, "periods %u", np);
    const uint32_t want[8] = {0, MSID_PERIOD_GAP, 0, MSID_PERIOD_GAP, MSID_PERIOD_GAP, MSID_PERIOD_GAP, MSID_PERIOD_GAP, 0};
    for (uint32_t p = 0; p < K; ++p) {
        UT_CHECK(flags[p] == want[p], "path %d period %u flags %u want %u", (int)path, p, flags[p], want[p]);
        if (!want[p]) {
            const double e = period_rel_err(spec[p], x, P, C, L, bins, tw, p, NULL);
            UT_CHECK(e <= 1e-12, "path %d clean period %u rel err %.3g", (int)path, p, e);
        }
    }
    ld_free(&o);
    /* non-finite samples flag only their own period */
    double y[4 * 64 * 2];
    memcpy(y, x, sizeof y);
    y[(1 * P + 17) * C + 1] = NAN;
    y[(3 * P + 63) * C + 0] = HUGE_VAL;
    UT_STATUS(ld_make(&o, P, C, L, bins, path, be), MSID_OK);
    msid_cplx s4[4 * 4 * 2];
    uint32_t f4[4];
    const size_t blk[] = {24};
    UT_CHECK(ld_run(&o.d, y, 4 * P, blk, 1, s4, f4) == 4, "%d", 0);
    const uint32_t wnf[4] = {0, MSID_PERIOD_NONFINITE, 0, MSID_PERIOD_NONFINITE};
    for (uint32_t p = 0; p < 4; ++p) {
        UT_CHECK(f4[p] == wnf[p], "path %d period %u flags %u", (int)path, p, f4[p]);
        if (!wnf[p]) UT_CHECK(period_rel_err(s4 + p * L * C, y, P, C, L, bins, tw, p, NULL) <= 1e-12, "period %u", p);
    }
    ld_free(&o);
    free(tw);
#undef ROWS
#undef COLLECT
}

static void test_gaps_and_nonfinite(void **state)
{
    (void)state;
    check_gaps(MSID_DFT_STREAM, NULL);
    naive_ctx ctx;
    const msid_fft_backend nb = naive_backend(&ctx, 64);
    check_gaps(MSID_DFT_FFT, &nb);
#ifdef MSID_HAVE_FFTW
    msid_fft_fftw f;
    UT_STATUS(msid_fft_fftw_create(&f, 64, MSID_FFTW_ESTIMATE), MSID_OK);
    check_gaps(MSID_DFT_FFT, &f.be);
    msid_fft_fftw_destroy(&f);
#endif
    free(ctx.tw);
}

static void test_release_and_reset(void **state)
{
    (void)state;
    const uint32_t P = 16, bins[] = {1, 3};
    double x[3 * 16];
    msid_rng r;
    msid_rng_seed(&r, 8u);
    fill_signal(x, 3 * P, 1, P, &r);
    ldft o;
    UT_STATUS(ld_make(&o, P, 1, 2, bins, MSID_DFT_STREAM, NULL), MSID_OK);
    UT_CHECK(msid_linedft_spectra(&o.d) == NULL && !msid_linedft_ready(&o.d), "%d", 0);
    UT_CHECK(msid_linedft_push(&o.d, x, 0) == 0, "%d", 0);
    /* push stops at the period end */
    UT_CHECK(msid_linedft_push(&o.d, x, 3 * P) == P && msid_linedft_ready(&o.d), "%d", 0);
    msid_cplx first[2];
    memcpy(first, msid_linedft_spectra(&o.d), sizeof first);
    UT_CHECK(msid_linedft_push(&o.d, x + P, P) == 0, "%s", "no push while a period waits");
    msid_linedft_release(&o.d);
    /* a partial period dropped by reset: the next full period equals the first */
    UT_CHECK(msid_linedft_push(&o.d, x + P, 5) == 5, "%d", 0);
    msid_linedft_mark_gap(&o.d);
    msid_linedft_reset(&o.d);
    UT_CHECK(msid_linedft_push(&o.d, x, P) == P, "%d", 0);
    UT_CHECK(memcmp(first, msid_linedft_spectra(&o.d), sizeof first) == 0 && msid_linedft_flags(&o.d) == 0, "%s", "reset");
    UT_CHECK(o.d.periods == 1, "%llu", (unsigned long long)o.d.periods);
    ld_free(&o);
}

/* ---------- path choice and errors ---------- */

static void test_choose_and_errors(void **state)
{
    (void)state;
    const uint32_t Ps[] = {2, 64, 1000, 4096, 1u << 20};
    for (int k = 0; k < 5; ++k)
        for (uint32_t L = 1; L <= 1000; L *= 10)
            UT_CHECK(msid_linedft_choose(Ps[k], L, 3, 0) == MSID_DFT_STREAM, "P=%u L=%u", Ps[k], L);
    UT_CHECK(msid_linedft_choose(4096, 200, 3, 1) == MSID_DFT_FFT, "%d", 0);
    UT_CHECK(msid_linedft_choose(4096, 1, 3, 1) == MSID_DFT_STREAM, "%d", 0);

    const uint32_t P = 64;
    uint32_t bins[40];
    for (uint32_t l = 0; l < 40; ++l) bins[l] = l;
    naive_ctx ctx;
    msid_fft_backend be = naive_backend(&ctx, P);
    ldft o;
    /* AUTO: stream without a backend; FFT for many lines with one */
    UT_STATUS(ld_make(&o, P, 2, 33, bins, MSID_DFT_AUTO, NULL), MSID_OK);
    UT_CHECK(o.d.path == MSID_DFT_STREAM, "%d", (int)o.d.path);
    ld_free(&o);
    UT_STATUS(ld_make(&o, P, 2, 33, bins, MSID_DFT_AUTO, &be), MSID_OK);
    UT_CHECK(o.d.path == msid_linedft_choose(P, 33, 2, 1), "%d", (int)o.d.path);
    ld_free(&o);
    /* FFT requested without a (matching, complete) backend */
    UT_STATUS(ld_make(&o, P, 2, 3, bins, MSID_DFT_FFT, NULL), MSID_E_BACKEND);
    ld_free(&o);
    msid_fft_backend b2 = be;
    b2.period = 32;
    UT_STATUS(ld_make(&o, P, 2, 3, bins, MSID_DFT_FFT, &b2), MSID_E_BACKEND);
    ld_free(&o);
    b2 = be;
    b2.r2c = NULL;
    UT_STATUS(ld_make(&o, P, 2, 3, bins, MSID_DFT_FFT, &b2), MSID_E_BACKEND);
    ld_free(&o);
    /* bins: P/2 allowed, beyond refused (even and odd P) */
    const uint32_t ok[] = {0, 32}, bad[] = {3, 33}, bad15[] = {8};
    UT_STATUS(ld_make(&o, P, 1, 2, ok, MSID_DFT_STREAM, NULL), MSID_OK);
    ld_free(&o);
    UT_STATUS(ld_make(&o, P, 1, 2, bad, MSID_DFT_STREAM, NULL), MSID_E_LINE_RANGE);
    ld_free(&o);
    UT_STATUS(ld_make(&o, 15, 1, 1, bad15, MSID_DFT_STREAM, NULL), MSID_E_LINE_RANGE);
    ld_free(&o);

    /* arguments and memory */
    msid_twiddle tw, tw32;
    void *mt = tsim_alloc(msid_twiddle_mem_size(P)), *mt32 = tsim_alloc(msid_twiddle_mem_size(32));
    msid_twiddle_init(&tw, P, mt, msid_twiddle_mem_size(P));
    msid_twiddle_init(&tw32, 32, mt32, msid_twiddle_mem_size(32));
    msid_linedft_cfg c = {P, 3, 4, bins, &tw, MSID_DFT_STREAM, NULL};
    const size_t need = msid_linedft_mem_size(&c);
    msid_linedft_cfg cf = {P, 3, 4, bins, NULL, MSID_DFT_FFT, &be};
    const size_t wantf = msid_linedft_mem_size(&cf);
    /* the FFT path buffers one period of every channel (C*P doubles) */
    UT_CHECK(need > 0 && wantf >= need + (size_t)3 * P * sizeof(double), "stream %zu fft %zu", need, wantf);
    unsigned char *mem = (unsigned char *)tsim_alloc(wantf + 64);
    msid_linedft d;
    UT_STATUS(msid_linedft_init(&d, &cf, mem, wantf), MSID_OK);  /* FFT path needs no twiddle */
    UT_STATUS(msid_linedft_init(NULL, &c, mem, need), MSID_E_NULL);
    UT_STATUS(msid_linedft_init(&d, NULL, mem, need), MSID_E_NULL);
    UT_STATUS(msid_linedft_init(&d, &c, NULL, need), MSID_E_NULL);
    UT_STATUS(msid_linedft_init(&d, &c, ut_misalign(mem), need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_linedft_init(&d, &c, mem, need - 1), MSID_E_MEM_SIZE);
    UT_STATUS(msid_linedft_init(&d, &c, mem + 64, need), MSID_OK);
    msid_linedft_cfg e = c;
    e.bins = NULL;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_NULL);
    e = c; e.twiddle = NULL;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_NULL);
    e = c; e.twiddle = &tw32;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_PERIOD);
    e = c; e.period = 1;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_PERIOD);
    UT_CHECK(msid_linedft_mem_size(&e) == 0, "%d", 0);
    e = c; e.n_channels = 0;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_DIMS);
    UT_CHECK(msid_linedft_mem_size(&e) == 0, "%d", 0);
    e = c; e.n_channels = MSID_MAX_CHANNELS + 1u;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_DIMS);
    e = c; e.n_lines = 0;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_NO_LINES);
    e = c; e.path = (msid_dft_path)5;
    UT_STATUS(msid_linedft_init(&d, &e, mem, need), MSID_E_ARG);
    UT_CHECK(msid_linedft_mem_size(&e) == 0 && msid_linedft_mem_size(NULL) == 0, "%d", 0);
    tsim_free(mem);
    tsim_free(mt);
    tsim_free(mt32);
    free(ctx.tw);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_stream_vs_naive),
        cmocka_unit_test(test_fft_path_naive_backend),
        cmocka_unit_test(test_fftw_vs_stream),
        cmocka_unit_test(test_fftw_lines_backend),
        cmocka_unit_test(test_linearity_and_shift),
        cmocka_unit_test(test_chunking_bit_identical),
        cmocka_unit_test(test_kernels_equal_sample_order_sum),
        cmocka_unit_test(test_gaps_and_nonfinite),
        cmocka_unit_test(test_release_and_reset),
        cmocka_unit_test(test_choose_and_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
