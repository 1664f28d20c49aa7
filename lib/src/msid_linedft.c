/* Streaming line DFT with exact integer twiddle indices, and the dense-line
 * FFT path through a backend table. X[b] = sum_n x(n) exp(-j 2 pi b n / P)
 * per period (Pintelon 2002 eq. 4 without the 1/sqrt(N) factor). */
#include "msid/msid_linedft.h"
#include "msid_internal.h"
#include "msid_linedft_kern.h"

/* Per-period cost model in nanoseconds, from `msid bench frf` on the
 * reference machine (see docs/benchmarks.md). Only ratios matter. */
#define COST_STREAM_NS 0.30   /* per line*channel*sample */
#define COST_FFT_NS 0.06      /* per channel * P*log2(P) */
#define COST_COPY_NS 1.0      /* per channel*sample (deinterleave + pick lines) */

msid_dft_path msid_linedft_choose(uint32_t P, uint32_t L, uint32_t C, int have_fft)
{
    if (!have_fft) return MSID_DFT_STREAM;
    double lg = 0.0;
    for (uint32_t p = P; p > 1u; p >>= 1) lg += 1.0;
    const double stream = COST_STREAM_NS * (double)L * (double)C * (double)P;
    const double fft = (double)C * (COST_FFT_NS * (double)P * lg + COST_COPY_NS * (double)P);
    return fft < stream ? MSID_DFT_FFT : MSID_DFT_STREAM;
}

static msid_dft_path resolve_path(const msid_linedft_cfg *c)
{
    if (c->path == MSID_DFT_STREAM || c->path == MSID_DFT_FFT || c->path == MSID_DFT_STREAM_F32) return c->path;
    return msid_linedft_choose(c->period, c->n_lines, c->n_channels, c->fft != 0);
}

/* The one memory layout (see msid__layout): bins, spectra out, then per path the
 * FFT period buffers, or the twiddle indices and accumulators (double or float,
 * with the float twiddle table). */
static size_t layout(msid_linedft *d, const msid_linedft_cfg *c, msid_dft_path path, void *mem)
{
    const size_t L = c->n_lines, C = c->n_channels, P = c->period;
    msid__layout y = msid__layout_begin(mem);
    d->bins = (uint32_t *)msid__lay(&y, L, sizeof(uint32_t));
    d->out = (msid_cplx *)msid__lay(&y, L * C, sizeof(msid_cplx));
    d->idx = 0; d->acc = 0; d->buf = 0; d->fout = 0; d->accf = 0; d->twf = 0;
    if (path == MSID_DFT_FFT) {   /* every period is fully written (data or gap zeros) before a transform */
        d->buf = (double *)msid__lay(&y, msid__mul(C, P), sizeof(double));
        d->fout = (msid_cplx *)msid__lay(&y, P / 2u + 1u, sizeof(msid_cplx));
    } else if (path == MSID_DFT_STREAM_F32) {
        d->idx = (uint32_t *)msid__lay(&y, L, sizeof(uint32_t));
        d->accf = (float *)msid__lay(&y, 2u * L * C, sizeof(float));
        d->twf = (float *)msid__lay(&y, msid__mul(2u, P), sizeof(float));
    } else {
        d->idx = (uint32_t *)msid__lay(&y, L, sizeof(uint32_t));
        d->acc = (msid_cplx *)msid__lay(&y, L * C, sizeof(msid_cplx));
    }
    d->acc2 = 0; d->accf2 = 0;
    if (c->spread && path == MSID_DFT_STREAM_F32)   /* spread: the pending period's sums */
        d->accf2 = (float *)msid__lay(&y, 2u * L * C, sizeof(float));
    else if (c->spread && path == MSID_DFT_STREAM)
        d->acc2 = (msid_cplx *)msid__lay(&y, L * C, sizeof(msid_cplx));
    return y.size;
}

size_t msid_linedft_mem_size(const msid_linedft_cfg *c)
{
    if (!c) return 0;
    if (c->period < MSID_MIN_PERIOD || c->period > MSID_MAX_PERIOD) return 0;
    if (c->n_channels == 0 || c->n_channels > MSID_MAX_CHANNELS || c->n_lines == 0) return 0;
    if (c->path != MSID_DFT_AUTO && c->path != MSID_DFT_STREAM && c->path != MSID_DFT_FFT &&
        c->path != MSID_DFT_STREAM_F32) return 0;
    if (c->spread && resolve_path(c) == MSID_DFT_FFT) return 0;
    msid_linedft tmp;
    return layout(&tmp, c, resolve_path(c), 0);
}

static void clear_period(msid_linedft *d)
{
    d->pos = 0;
    d->flags = 0;
    if (d->path == MSID_DFT_STREAM) {
        for (size_t k = 0; k < (size_t)d->n_lines * d->n_channels; ++k) d->acc[k].re = d->acc[k].im = 0.0;
        for (uint32_t l = 0; l < d->n_lines; ++l) d->idx[l] = 0;
    } else if (d->path == MSID_DFT_STREAM_F32) {
        for (size_t k = 0; k < 2u * (size_t)d->n_lines * d->n_channels; ++k) d->accf[k] = 0.0f;
        for (uint32_t l = 0; l < d->n_lines; ++l) d->idx[l] = 0;
    }
}

msid_status msid_linedft_init(msid_linedft *d, const msid_linedft_cfg *c, void *mem, size_t len)
{
    if (!d || !c || !c->bins) return MSID_E_NULL;
    if (c->period < MSID_MIN_PERIOD || c->period > MSID_MAX_PERIOD) return MSID_E_PERIOD;
    if (c->n_channels == 0 || c->n_channels > MSID_MAX_CHANNELS) return MSID_E_DIMS;
    if (c->n_lines == 0) return MSID_E_NO_LINES;
    if (c->path != MSID_DFT_AUTO && c->path != MSID_DFT_STREAM && c->path != MSID_DFT_FFT &&
        c->path != MSID_DFT_STREAM_F32) return MSID_E_ARG;
    for (uint32_t l = 0; l < c->n_lines; ++l)
        if ((uint64_t)c->bins[l] * 2u > c->period) return MSID_E_LINE_RANGE;
    const msid_dft_path path = resolve_path(c);
    if (c->spread && path == MSID_DFT_FFT) return MSID_E_ARG;
    if (path == MSID_DFT_FFT) {
        if (!c->fft || !c->fft->r2c || c->fft->period != c->period) return MSID_E_BACKEND;
    } else {
        if (!c->twiddle) return MSID_E_NULL;
        if (c->twiddle->period != c->period) return MSID_E_PERIOD;
    }
    const msid_status st = msid__mem_check(mem, len, msid_linedft_mem_size(c));
    if (st != MSID_OK) return st;
    (void)layout(d, c, path, mem);
    const size_t L = c->n_lines, C = c->n_channels, P = c->period;
    d->period = c->period;
    d->n_channels = c->n_channels;
    d->n_lines = c->n_lines;
    d->path = path;
    d->twiddle = c->twiddle;
    d->fft = c->fft;
    if (path == MSID_DFT_STREAM_F32) {
        for (size_t k = 0; k < P; ++k) {   /* correctly rounded, so the same floats everywhere */
            d->twf[2u * k] = (float)c->twiddle->w[k].re;
            d->twf[2u * k + 1u] = (float)c->twiddle->w[k].im;
        }
    }
    for (size_t l = 0; l < L; ++l) d->bins[l] = c->bins[l];
    for (size_t k = 0; k < L * C; ++k) d->out[k].re = d->out[k].im = 0.0;
    d->spread = c->spread ? 1 : 0;
    d->pending = 0;
    d->pend_line = 0;
    d->pend_flags = 0;
    if (d->acc2) for (size_t k = 0; k < L * C; ++k) d->acc2[k].re = d->acc2[k].im = 0.0;
    if (d->accf2) for (size_t k = 0; k < 2u * L * C; ++k) d->accf2[k] = 0.0f;
    d->ready = 0;
    d->out_flags = 0;
    d->periods = 0;
    d->err = MSID_OK;
    clear_period(d);
    return MSID_OK;
}

/* ---- streaming kernels: per line the terms are added in sample order, so
 *      the sums do not depend on how the samples were split into blocks ---- */

#define CHUNK 256u

static inline uint32_t step(uint32_t i, uint32_t k, uint32_t P) { return msid__ldft_step(i, k, P); }

#ifdef MSID_LINEDFT_VEC
/* Four lines, all channels, ns samples: the channel pairs in the vector kernel (msid_linedft_vec.c),
 * an odd last channel here. acc is [4][C] (line stride C). */
static void kernel4(const msid_cplx *w, uint32_t P, const uint32_t *k, const uint32_t *idx,
                    msid_cplx *acc, uint32_t C, const double *x, uint32_t ns)
{
    const uint32_t k0 = k[0], k1 = k[1], k2 = k[2], k3 = k[3];
    const uint32_t c = msid__ldft_pairs4(w, P, k, idx, acc, C, x, ns);
    if (c < C) {
        uint32_t i0 = idx[0], i1 = idx[1], i2 = idx[2], i3 = idx[3];
        double r0 = acc[0 * C + c].re, q0 = acc[0 * C + c].im;
        double r1 = acc[1 * C + c].re, q1 = acc[1 * C + c].im;
        double r2 = acc[2 * C + c].re, q2 = acc[2 * C + c].im;
        double r3 = acc[3 * C + c].re, q3 = acc[3 * C + c].im;
        const double *row = x + c;
        for (uint32_t s = 0; s < ns; ++s, row += C) {
            const double v = row[0];
            r0 += v * w[i0].re; q0 += v * w[i0].im;
            r1 += v * w[i1].re; q1 += v * w[i1].im;
            r2 += v * w[i2].re; q2 += v * w[i2].im;
            r3 += v * w[i3].re; q3 += v * w[i3].im;
            i0 = step(i0, k0, P); i1 = step(i1, k1, P); i2 = step(i2, k2, P); i3 = step(i3, k3, P);
        }
        acc[0 * C + c].re = r0; acc[0 * C + c].im = q0;
        acc[1 * C + c].re = r1; acc[1 * C + c].im = q1;
        acc[2 * C + c].re = r2; acc[2 * C + c].im = q2;
        acc[3 * C + c].re = r3; acc[3 * C + c].im = q3;
    }
}
#endif

static void kernel1(const msid_cplx *w, uint32_t P, uint32_t k, uint32_t idx,
                    msid_cplx *acc, uint32_t C, const double *x, uint32_t ns)
{
    for (uint32_t c = 0; c < C; ++c) {
        uint32_t i = idx;
        double r = acc[c].re, q = acc[c].im;
        const double *row = x + c;
        for (uint32_t s = 0; s < ns; ++s, row += C) {
            const double v = row[0];
            r += v * w[i].re;
            q += v * w[i].im;
            i = step(i, k, P);
        }
        acc[c].re = r;
        acc[c].im = q;
    }
}

/* Two lines, all channels, ns samples: every line pair where there is no vector kernel (a Cortex-M7 or
 * 32-bit ARM with 16 double registers), the pair left after the vector kernel's groups of four
 * elsewhere. A channel pair shares each twiddle load and index
 * step, 8 accumulators in registers. Each accumulator still adds its terms in
 * sample order, so the sums equal kernel1's bit for bit. acc is [2][C]. */
static void kernel2(const msid_cplx *w, uint32_t P, const uint32_t *k, const uint32_t *idx,
                    msid_cplx *acc, uint32_t C, const double *x, uint32_t ns)
{
    const uint32_t k0 = k[0], k1 = k[1];
    uint32_t c = 0;
    for (; c + 2u <= C; c += 2u) {
        uint32_t i0 = idx[0], i1 = idx[1];
        msid_cplx *a0 = acc + c, *a1 = acc + C + c;
        double r00 = a0[0].re, q00 = a0[0].im, r01 = a0[1].re, q01 = a0[1].im;
        double r10 = a1[0].re, q10 = a1[0].im, r11 = a1[1].re, q11 = a1[1].im;
        const double *row = x + c;
        for (uint32_t s = 0; s < ns; ++s, row += C) {
            const double v0 = row[0], v1 = row[1];
            const double c0 = w[i0].re, s0 = w[i0].im, c1 = w[i1].re, s1 = w[i1].im;
            r00 += v0 * c0; q00 += v0 * s0; r01 += v1 * c0; q01 += v1 * s0;
            r10 += v0 * c1; q10 += v0 * s1; r11 += v1 * c1; q11 += v1 * s1;
            i0 = step(i0, k0, P); i1 = step(i1, k1, P);
        }
        a0[0].re = r00; a0[0].im = q00; a0[1].re = r01; a0[1].im = q01;
        a1[0].re = r10; a1[0].im = q10; a1[1].re = r11; a1[1].im = q11;
    }
    if (c < C) {   /* odd channel count: the last channel, line by line */
        for (uint32_t j = 0; j < 2u; ++j) {
            uint32_t i = idx[j];
            double r = acc[j * C + c].re, q = acc[j * C + c].im;
            const double *row = x + c;
            for (uint32_t s = 0; s < ns; ++s, row += C) {
                r += row[0] * w[i].re;
                q += row[0] * w[i].im;
                i = step(i, k[j], P);
            }
            acc[j * C + c].re = r;
            acc[j * C + c].im = q;
        }
    }
}

static void stream_block(msid_linedft *d, const double *x, uint32_t n)
{
    const uint32_t P = d->period, C = d->n_channels, L = d->n_lines;
    const msid_cplx *w = d->twiddle->w;
    for (uint32_t s0 = 0; s0 < n; s0 += CHUNK) {
        const uint32_t ns = (n - s0) < CHUNK ? (n - s0) : CHUNK;
        const double *xs = x + (size_t)s0 * C;
        uint32_t l = 0;
#ifdef MSID_LINEDFT_VEC
        for (; l + 4u <= L; l += 4u) kernel4(w, P, d->bins + l, d->idx + l, d->acc + (size_t)l * C, C, xs, ns);
#endif
        for (; l + 2u <= L; l += 2u) kernel2(w, P, d->bins + l, d->idx + l, d->acc + (size_t)l * C, C, xs, ns);
        for (; l < L; ++l) kernel1(w, P, d->bins[l], d->idx[l], d->acc + (size_t)l * C, C, xs, ns);
        /* (idx + b*ns) mod P in 32 bits (no 64-bit division on a Cortex-M): b <= P/2 <= 2^23
         * and ns <= CHUNK = 2^8, so b*ns < 2^32; idx + (b*ns mod P) < 2P < 2^32. Same integers. */
        for (l = 0; l < L; ++l) {
            const uint32_t adv = ns == 1u ? d->bins[l] : (d->bins[l] * ns) % P;
            const uint32_t t = d->idx[l] + adv;
            d->idx[l] = t >= P ? t - P : t;
        }
    }
}

/* One sample (the per-sample interrupt of a firmware): each accumulator gets
 * the same single term v*w added as in the kernels, so the bits are the same. */
static void stream_one(msid_linedft *d, const double *x)
{
    const uint32_t P = d->period, C = d->n_channels, L = d->n_lines;
    const msid_cplx *w = d->twiddle->w;
    msid_cplx *acc = d->acc;
    for (uint32_t l = 0; l < L; ++l, acc += C) {
        const uint32_t i = d->idx[l];
        const double wr = w[i].re, wi = w[i].im;
        for (uint32_t c = 0; c < C; ++c) {
            const double v = x[c];
            acc[c].re += v * wr;
            acc[c].im += v * wi;
        }
        d->idx[l] = step(i, d->bins[l], P);
    }
}

/* Single-precision streaming (MSID_DFT_STREAM_F32): each sample is rounded to
 * float once, each accumulator adds its terms in sample order in float.
 * Samples are converted in blocks of F32_BLOCK (1 KB of stack at 32 channels);
 * within a block two lines and a channel pair share each twiddle load and
 * index step, 8 accumulators in registers. The order of the terms per
 * accumulator is the sample order whatever the blocking: same bits. */
#define F32_BLOCK 8u

static void f32_one_line(const float *tw, uint32_t P, uint32_t k, uint32_t *idx, float *a, uint32_t C,
                         const float *xf, uint32_t ns)
{
    for (uint32_t c = 0; c < C; ++c) {
        uint32_t i = *idx;
        float re = a[2u * c], im = a[2u * c + 1u];
        for (uint32_t s = 0; s < ns; ++s) {
            const float v = xf[s * C + c];
            re += v * tw[2u * i];
            im += v * tw[2u * i + 1u];
            i = step(i, k, P);
        }
        a[2u * c] = re;
        a[2u * c + 1u] = im;
    }
    for (uint32_t s = 0; s < ns; ++s) *idx = step(*idx, k, P);
}

/* One float sample row (the per-sample interrupt). */
static void f32_sample(msid_linedft *d, const float *xf)
{
    const uint32_t P = d->period, C = d->n_channels, L = d->n_lines;
    const float *tw = d->twf;
    float *a = d->accf;
    for (uint32_t l = 0; l < L; ++l, a += 2u * C) {
        const uint32_t i = d->idx[l];
        const float wr = tw[2u * i], wi = tw[2u * i + 1u];
        for (uint32_t c = 0; c < C; ++c) {
            const float re = a[2u * c] + xf[c] * wr, im = a[2u * c + 1u] + xf[c] * wi;
            a[2u * c] = re;
            a[2u * c + 1u] = im;
        }
        d->idx[l] = step(i, d->bins[l], P);
    }
}

/* ns float sample rows: two lines and a channel pair per pass. */
static void f32_block(msid_linedft *d, const float *xf, uint32_t ns)
{
    const uint32_t P = d->period, C = d->n_channels, L = d->n_lines;
    const float *tw = d->twf;
    uint32_t l = 0;
    for (; l + 2u <= L; l += 2u) {
        const uint32_t k0 = d->bins[l], k1 = d->bins[l + 1u];
        float *a0 = d->accf + 2u * (size_t)l * C, *a1 = a0 + 2u * C;
        uint32_t c = 0;
        for (; c + 2u <= C; c += 2u) {
            uint32_t i0 = d->idx[l], i1 = d->idx[l + 1u];
            float r00 = a0[2u * c], q00 = a0[2u * c + 1u], r01 = a0[2u * c + 2u], q01 = a0[2u * c + 3u];
            float r10 = a1[2u * c], q10 = a1[2u * c + 1u], r11 = a1[2u * c + 2u], q11 = a1[2u * c + 3u];
            const float *row = xf + c;
            for (uint32_t s = 0; s < ns; ++s, row += C) {
                const float v0 = row[0], v1 = row[1];
                const float c0 = tw[2u * i0], s0f = tw[2u * i0 + 1u], c1 = tw[2u * i1], s1f = tw[2u * i1 + 1u];
                r00 += v0 * c0; q00 += v0 * s0f; r01 += v1 * c0; q01 += v1 * s0f;
                r10 += v0 * c1; q10 += v0 * s1f; r11 += v1 * c1; q11 += v1 * s1f;
                i0 = step(i0, k0, P); i1 = step(i1, k1, P);
            }
            a0[2u * c] = r00; a0[2u * c + 1u] = q00; a0[2u * c + 2u] = r01; a0[2u * c + 3u] = q01;
            a1[2u * c] = r10; a1[2u * c + 1u] = q10; a1[2u * c + 2u] = r11; a1[2u * c + 3u] = q11;
        }
        if (c < C) {   /* odd channel count: the last channel of both lines */
            uint32_t i0 = d->idx[l], i1 = d->idx[l + 1u];
            float r0 = a0[2u * c], q0 = a0[2u * c + 1u], r1 = a1[2u * c], q1 = a1[2u * c + 1u];
            const float *row = xf + c;
            for (uint32_t s = 0; s < ns; ++s, row += C) {
                const float v = row[0];
                r0 += v * tw[2u * i0]; q0 += v * tw[2u * i0 + 1u];
                r1 += v * tw[2u * i1]; q1 += v * tw[2u * i1 + 1u];
                i0 = step(i0, k0, P); i1 = step(i1, k1, P);
            }
            a0[2u * c] = r0; a0[2u * c + 1u] = q0; a1[2u * c] = r1; a1[2u * c + 1u] = q1;
        }
        for (uint32_t s = 0; s < ns; ++s) {
            d->idx[l] = step(d->idx[l], k0, P);
            d->idx[l + 1u] = step(d->idx[l + 1u], k1, P);
        }
    }
    if (l < L) f32_one_line(tw, P, d->bins[l], &d->idx[l], d->accf + 2u * (size_t)l * C, C, xf, ns);
}

/* Double sample rows: each rounded to float once, F32_BLOCK rows at a time. */
static void stream_f32(msid_linedft *d, const double *x, uint32_t n)
{
    const uint32_t C = d->n_channels;
    float xf[F32_BLOCK * MSID_MAX_CHANNELS];
    if (n == 1u) {   /* one sample per call: no blocking overhead */
        for (uint32_t c = 0; c < C; ++c) xf[c] = (float)x[c];
        f32_sample(d, xf);
        return;
    }
    for (uint32_t s0 = 0; s0 < n; s0 += F32_BLOCK) {
        const uint32_t ns = (n - s0) < F32_BLOCK ? (n - s0) : F32_BLOCK;
        for (uint32_t k = 0; k < ns * C; ++k) xf[k] = (float)x[(size_t)s0 * C + k];
        f32_block(d, xf, ns);
    }
}

/* Float sample rows (msid_linedft_push_f32): no conversion at all. */
static void stream_f32_in(msid_linedft *d, const float *x, uint32_t n)
{
    if (n == 1u) { f32_sample(d, x); return; }
    for (uint32_t s0 = 0; s0 < n; s0 += F32_BLOCK)
        f32_block(d, x + (size_t)s0 * d->n_channels, (n - s0) < F32_BLOCK ? (n - s0) : F32_BLOCK);
}

/* Spread period end, O(1): the completed sums become the pending period and the
 * free (zeroed) second set accumulates the next one. The twiddle indices are
 * already 0: each advanced by b*P = 0 mod P over the period. */
static void swap_period(msid_linedft *d)
{
    if (d->path == MSID_DFT_STREAM_F32) {
        float *t = d->accf; d->accf = d->accf2; d->accf2 = t;
    } else {
        msid_cplx *t = d->acc; d->acc = d->acc2; d->acc2 = t;
    }
    d->pending = 1;
    d->pend_line = 0;
    d->pend_flags = d->flags;
    d->periods++;
    d->pos = 0;
    d->flags = 0;
}

size_t msid_linedft_settle(msid_linedft *d, size_t n_lines)
{
    if (!d->pending || d->ready) return 0;
    const size_t C = d->n_channels, l0 = d->pend_line;
    const size_t l1 = n_lines < d->n_lines - l0 ? l0 + n_lines : d->n_lines;
    uint32_t fl = d->pend_flags;
    for (size_t k = l0 * C; k < l1 * C; ++k) {
        if (d->path == MSID_DFT_STREAM_F32) {
            d->out[k].re = (double)d->accf2[2u * k];
            d->out[k].im = (double)d->accf2[2u * k + 1u];
            d->accf2[2u * k] = d->accf2[2u * k + 1u] = 0.0f;
        } else {
            d->out[k] = d->acc2[k];
            d->acc2[k].re = d->acc2[k].im = 0.0;
        }
        if (!msid__finite(d->out[k].re) || !msid__finite(d->out[k].im)) fl |= MSID_PERIOD_NONFINITE;
    }
    d->pend_flags = fl;
    d->pend_line = (uint32_t)l1;
    if (l1 == d->n_lines) {
        d->pending = 0;
        d->out_flags = fl;
        d->ready = 1;
    }
    return l1 - l0;
}

int msid_linedft_pending(const msid_linedft *d) { return d->pending; }

static void finish_period(msid_linedft *d)
{
    const size_t L = d->n_lines, C = d->n_channels, P = d->period;
    if (d->spread) { swap_period(d); return; }
    if (d->path == MSID_DFT_FFT) {
        for (size_t c = 0; c < C; ++c) {
            msid_status st;
            if (d->fft->r2c_bins) {   /* the lines only, straight into out[l * C + c] */
                st = d->fft->r2c_bins(d->fft->ctx, d->buf + c * P, d->bins, (uint32_t)L, d->out + c, (uint32_t)C);
            } else {
                st = d->fft->r2c(d->fft->ctx, d->buf + c * P, d->fout);
                for (size_t l = 0; l < L; ++l) d->out[l * C + c] = d->fout[d->bins[l]];
            }
            if (st != MSID_OK) { d->err = MSID_E_BACKEND; d->flags |= MSID_PERIOD_NONFINITE; }
        }
    } else if (d->path == MSID_DFT_STREAM_F32) {
        for (size_t k = 0; k < L * C; ++k) {
            d->out[k].re = (double)d->accf[2u * k];
            d->out[k].im = (double)d->accf[2u * k + 1u];
        }
    } else {
        for (size_t k = 0; k < L * C; ++k) d->out[k] = d->acc[k];
    }
    uint32_t fl = d->flags;
    for (size_t k = 0; k < L * C; ++k)
        if (!msid__finite(d->out[k].re) || !msid__finite(d->out[k].im)) { fl |= MSID_PERIOD_NONFINITE; break; }
    d->out_flags = fl;
    d->ready = 1;
    d->periods++;
    clear_period(d);
}

/* Samples of n that may be taken now. Without spreading none while a completed
 * period waits for release. Spread: the period may not complete while another is
 * pending or ready; the pending one is settled here if `out` is free. */
static uint32_t room_for(msid_linedft *d, size_t n)
{
    uint32_t room = d->period - d->pos;
    if (!d->spread) return d->ready ? 0u : room;
    if (n >= room && d->pending) (void)msid_linedft_settle(d, d->n_lines);
    if (d->pending || d->ready) room--;
    return room;
}

/* Push of double rows x, or (STREAM_F32 only) float rows xf. */
MSID__ALWAYS_INLINE size_t push_rows(msid_linedft *d, const double *x, const float *xf, size_t n)
{
    if (n == 0) return 0;
    const uint32_t room = room_for(d, n);
    if (room == 0) return 0;
    const uint32_t take = n < room ? (uint32_t)n : room;
    const uint32_t C = d->n_channels;
    if (d->path == MSID_DFT_FFT) {
        const size_t P = d->period;
        uint32_t c = 0;
        /* de-interleave four channels per pass: one read stream, four write streams */
        for (; c + 4u <= C; c += 4u) {
            double *d0 = d->buf + c * P + d->pos, *d1 = d0 + P, *d2 = d1 + P, *d3 = d2 + P;
            const double *src = x + c;
            for (uint32_t s = 0; s < take; ++s, src += C) {
                d0[s] = src[0]; d1[s] = src[1]; d2[s] = src[2]; d3[s] = src[3];
            }
        }
        for (; c + 2u <= C; c += 2u) {
            double *d0 = d->buf + c * P + d->pos, *d1 = d0 + P;
            const double *src = x + c;
            for (uint32_t s = 0; s < take; ++s, src += C) { d0[s] = src[0]; d1[s] = src[1]; }
        }
        for (; c < C; ++c) {
            double *d0 = d->buf + c * P + d->pos;
            const double *src = x + c;
            for (uint32_t s = 0; s < take; ++s, src += C) d0[s] = src[0];
        }
    } else if (d->path == MSID_DFT_STREAM_F32) {
        if (xf) stream_f32_in(d, xf, take);
        else stream_f32(d, x, take);
    } else if (take == 1u) {
        stream_one(d, x);
    } else {
        stream_block(d, x, take);
    }
    d->pos += take;
    if (d->pos == d->period) finish_period(d);
    return take;
}

size_t msid_linedft_push(msid_linedft *d, const double *x, size_t n) { return push_rows(d, x, 0, n); }

size_t msid_linedft_push_f32(msid_linedft *d, const float *x, size_t n)
{
    if (d->path == MSID_DFT_STREAM_F32) return push_rows(d, 0, x, n);
    /* double paths: float to double is exact, F32_BLOCK rows at a time */
    const size_t C = d->n_channels;
    double buf[F32_BLOCK * MSID_MAX_CHANNELS];
    size_t done = 0;
    while (done < n) {
        const size_t k = n - done < F32_BLOCK ? n - done : F32_BLOCK;
        for (size_t j = 0; j < k * C; ++j) buf[j] = (double)x[done * C + j];
        const size_t t = push_rows(d, buf, 0, k);
        done += t;
        if (t < k) break;
    }
    return done;
}

size_t msid_linedft_push_gap(msid_linedft *d, size_t n)
{
    if (n == 0) return 0;
    const uint32_t room = room_for(d, n);
    if (room == 0) return 0;
    const uint32_t take = n < room ? (uint32_t)n : room;
    d->flags |= MSID_PERIOD_GAP;
    if (d->path == MSID_DFT_FFT) {
        const size_t P = d->period;
        for (uint32_t c = 0; c < d->n_channels; ++c)
            for (uint32_t s = 0; s < take; ++s) d->buf[c * P + d->pos + s] = 0.0;
    } else {
        for (uint32_t l = 0; l < d->n_lines; ++l)
            d->idx[l] = (uint32_t)(((uint64_t)d->idx[l] + (uint64_t)d->bins[l] * take) % d->period);
    }
    d->pos += take;
    if (d->pos == d->period) finish_period(d);
    return take;
}

void msid_linedft_mark_gap(msid_linedft *d) { d->flags |= MSID_PERIOD_GAP; }
int msid_linedft_ready(const msid_linedft *d) { return d->ready; }
const msid_cplx *msid_linedft_spectra(const msid_linedft *d) { return d->ready ? d->out : 0; }
uint32_t msid_linedft_flags(const msid_linedft *d) { return d->out_flags; }
void msid_linedft_release(msid_linedft *d) { d->ready = 0; }
msid_status msid_linedft_error(const msid_linedft *d) { return d->err; }

void msid_linedft_reset(msid_linedft *d)
{
    if (d->pending) {   /* drop the pending period: its sums are cleared as settling would */
        const size_t n = (size_t)d->n_lines * d->n_channels;
        if (d->acc2) for (size_t k = 0; k < n; ++k) d->acc2[k].re = d->acc2[k].im = 0.0;
        if (d->accf2) for (size_t k = 0; k < 2u * n; ++k) d->accf2[k] = 0.0f;
        d->pending = 0;
    }
    d->ready = 0;
    d->out_flags = 0;
    d->periods = 0;
    clear_period(d);
}
