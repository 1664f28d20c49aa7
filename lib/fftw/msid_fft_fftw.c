/* FFTW3 real-to-complex backend. Host only: FFTW allocates in its planner. */
#include "msid/msid_fft_fftw.h"
#include "msid/msid_dmath.h"
#include <fftw3.h>
#include <string.h>

/* The transform of `in` by the plan: new-array execute needs the alignment the plan was made
 * with, else through the planning buffer. */
static void run(msid_fft_fftw *f, const double *in, size_t n_in)
{
    fftw_plan plan = (fftw_plan)f->plan;
    const int same_in = fftw_alignment_of((double *)in) == fftw_alignment_of(f->in);
    if (!same_in) {
        memcpy(f->in, in, n_in * sizeof(double));
        in = f->in;
    }
    if (f->half) fftw_execute_dft(plan, (fftw_complex *)(void *)in, (fftw_complex *)f->out);
    else fftw_execute_dft_r2c(plan, (double *)in, (fftw_complex *)f->out);
}

/* Twiddles exp(-j 2 pi k / P) of `bins` in cache slot s (computed when the bins differ from the
 * slot's last ones); NULL if a bin exceeds P/2 or memory is short. */
static const msid_cplx *twiddles(msid_fft_fftw *f, int s, const uint32_t *bins, uint32_t n)
{
    const uint32_t P = f->be.period;
    if (f->tw[s].w && f->tw[s].n == n && memcmp(f->tw[s].bins, bins, (size_t)n * sizeof(uint32_t)) == 0)
        return f->tw[s].w;
    for (uint32_t i = 0; i < n; ++i)
        if (bins[i] > P / 2u) return NULL;
    /* FFTW's allocator, as for the plan's buffers (this backend lives outside the heap-free core) */
    fftw_free(f->tw[s].bins);
    fftw_free(f->tw[s].w);
    f->tw[s].n = 0;   /* valid again only when complete */
    uint32_t *b = f->tw[s].bins = (uint32_t *)fftw_malloc((size_t)(n ? n : 1) * sizeof(uint32_t));
    msid_cplx *w = f->tw[s].w = (msid_cplx *)fftw_malloc((size_t)(n ? n : 1) * sizeof(msid_cplx));
    if (!b || !w) return NULL;
    for (uint32_t i = 0; i < n; ++i) {
        b[i] = bins[i];
        msid_cis_turns(-(double)bins[i] / (double)P, &w[i].re, &w[i].im);
    }
    f->tw[s].n = n;
    return w;
}

/* The real DFT X[k] of x (P = 2N) from Z = DFT_N(z), z[n] = x[2n] + j x[2n+1]:
 * E = (Z[k] + conj Z[N-k]) / 2 and O = (Z[k] - conj Z[N-k]) / 2j are the DFTs of the even and
 * odd samples, X[k] = E + W^k O with W = exp(-j 2 pi / P) (indices mod N); X[0] and X[N] are
 * Re Z[0] +- Im Z[0], exactly real as FFTW's real transform gives them. */
static void split(const msid_fft_fftw *f, const uint32_t *bins, uint32_t n, const msid_cplx *w, msid_cplx *out,
                  uint32_t stride)
{
    const uint32_t N = f->be.period / 2u;
    const fftw_complex *Z = (const fftw_complex *)f->out;
    for (uint32_t i = 0; i < n; ++i) {
        const uint32_t k = bins[i];
        msid_cplx *x = out + (size_t)i * stride;
        if (k == 0u || k == N) {
            x->re = k == 0u ? Z[0][0] + Z[0][1] : Z[0][0] - Z[0][1];
            x->im = 0.0;
            continue;
        }
        const double zr = Z[k][0], zi = Z[k][1], cr = Z[N - k][0], ci = -Z[N - k][1];
        const double er = 0.5 * (zr + cr), ei = 0.5 * (zi + ci);
        const double or_ = 0.5 * (zi - ci), oi = -0.5 * (zr - cr);   /* (Z - conj) / 2, divided by j */
        x->re = er + (w[i].re * or_ - w[i].im * oi);
        x->im = ei + (w[i].re * oi + w[i].im * or_);
    }
}

static msid_status r2c(void *ctx, const double *in, msid_cplx *out)
{
    msid_fft_fftw *f = (msid_fft_fftw *)ctx;
    const uint32_t P = f->be.period;
    if (f->half) {   /* every bin 0..P/2: the split with the whole twiddle table (slot 1) */
        const uint32_t N = P / 2u;
        if (f->tw[1].n != N + 1u) {
            uint32_t *all = (uint32_t *)fftw_malloc(((size_t)N + 1u) * sizeof(uint32_t));
            if (!all) return MSID_E_BACKEND;
            for (uint32_t k = 0; k <= N; ++k) all[k] = k;
            const msid_cplx *w = twiddles(f, 1, all, N + 1u);
            fftw_free(all);
            if (!w) return MSID_E_BACKEND;
        }
        run(f, in, P);
        split(f, f->tw[1].bins, N + 1u, f->tw[1].w, out, 1u);
        return MSID_OK;
    }
    const int same_in = fftw_alignment_of((double *)in) == fftw_alignment_of(f->in);
    const int same_out = fftw_alignment_of((double *)out) == fftw_alignment_of((double *)f->out);
    if (same_in && same_out) {
        fftw_execute_dft_r2c((fftw_plan)f->plan, (double *)in, (fftw_complex *)out);
    } else {
        run(f, in, P);
        memcpy(out, f->out, ((size_t)P / 2u + 1u) * sizeof(msid_cplx));
    }
    return MSID_OK;
}

static msid_status r2c_bins(void *ctx, const double *in, const uint32_t *bins, uint32_t n, msid_cplx *out,
                            uint32_t stride)
{
    msid_fft_fftw *f = (msid_fft_fftw *)ctx;
    const uint32_t P = f->be.period;
    if (!f->half) {   /* odd P: the whole real spectrum, then the bins */
        for (uint32_t i = 0; i < n; ++i)
            if (bins[i] > P / 2u) return MSID_E_BACKEND;
        run(f, in, P);
        const msid_cplx *X = (const msid_cplx *)f->out;
        for (uint32_t i = 0; i < n; ++i) out[(size_t)i * stride] = X[bins[i]];
        return MSID_OK;
    }
    const msid_cplx *w = twiddles(f, 0, bins, n);
    if (!w) return MSID_E_BACKEND;
    run(f, in, P);
    split(f, bins, n, w, out, stride);
    return MSID_OK;
}

msid_status msid_fft_fftw_create(msid_fft_fftw *f, uint32_t period, msid_fftw_effort effort)
{
    if (!f) return MSID_E_NULL;
    memset(f, 0, sizeof(*f));
    if (period < MSID_MIN_PERIOD || period > MSID_MAX_PERIOD) return MSID_E_PERIOD;
    if (effort != MSID_FFTW_ESTIMATE && effort != MSID_FFTW_MEASURE && effort != MSID_FFTW_LINES) return MSID_E_ARG;
    f->half = effort == MSID_FFTW_LINES && period % 2u == 0u;
    f->in = fftw_alloc_real(period);
    f->out = fftw_alloc_complex(period / 2u + 1u);
    if (!f->in || !f->out) { msid_fft_fftw_destroy(f); return MSID_E_BACKEND; }
    const unsigned flags = (effort == MSID_FFTW_MEASURE ? FFTW_MEASURE : FFTW_ESTIMATE);
    if (f->half)
        f->plan = fftw_plan_dft_1d((int)(period / 2u), (fftw_complex *)(void *)f->in, (fftw_complex *)f->out,
                                   FFTW_FORWARD, flags);
    else
        f->plan = fftw_plan_dft_r2c_1d((int)period, f->in, (fftw_complex *)f->out, flags);
    if (!f->plan) { msid_fft_fftw_destroy(f); return MSID_E_BACKEND; }
    f->be.name = "fftw3";
    f->be.period = period;
    f->be.ctx = f;
    f->be.r2c = r2c;
    f->be.r2c_bins = effort == MSID_FFTW_LINES ? r2c_bins : NULL;
    return MSID_OK;
}

void msid_fft_fftw_destroy(msid_fft_fftw *f)
{
    if (!f) return;
    if (f->plan) fftw_destroy_plan((fftw_plan)f->plan);
    if (f->in) fftw_free(f->in);
    if (f->out) fftw_free(f->out);
    for (int s = 0; s < 2; ++s) {
        fftw_free(f->tw[s].bins);
        fftw_free(f->tw[s].w);
    }
    memset(f, 0, sizeof(*f));
}
