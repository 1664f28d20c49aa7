/* Multisine sample generator: u_i(n) = sum_l Re{c_{e,i,l} exp(j 2 pi b_l n / P)}
 * (González et al. 2025 eq. 2 sampled at t = nh), exact integer twiddle index. */
#include "msid/msid_gen.h"
#include "msid_internal.h"

/* The one memory layout (see msid__layout): the waveform table, or the twiddle index per line. */
static size_t layout(msid_gen *g, const msid_gen_cfg *c, void *mem)
{
    const msid_design *d = c->design;
    msid__layout y = msid__layout_begin(mem);
    g->wave = 0;
    g->idx = 0;
    if (c->waveform_table)
        g->wave = (double *)msid__lay(&y, (size_t)d->period * d->n_inputs, sizeof(double));
    else
        g->idx = (uint32_t *)msid__lay(&y, d->n_lines, sizeof(uint32_t));
    return y.size;
}

size_t msid_gen_mem_size(const msid_gen_cfg *c)
{
    if (!c || !c->design) return 0;
    msid_gen tmp;
    return layout(&tmp, c, 0);
}

static void fill_idx(msid_gen *g)
{
    const msid_design *d = g->design;
    for (uint32_t l = 0; l < d->n_lines; ++l)
        g->idx[l] = (uint32_t)((uint64_t)d->bins[l] * g->pos % d->period);
}

msid_status msid_gen_init(msid_gen *g, const msid_gen_cfg *c, void *mem, size_t len)
{
    if (!g || !c || !c->design || !c->twiddle) return MSID_E_NULL;
    const msid_design *d = c->design;
    if (c->experiment >= d->n_experiments) return MSID_E_ARG;
    if (c->twiddle->period != d->period) return MSID_E_PERIOD;
    const msid_status st = msid__mem_check(mem, len, msid_gen_mem_size(c));
    if (st != MSID_OK) return st;
    (void)layout(g, c, mem);
    g->design = d;
    g->twiddle = c->twiddle;
    g->experiment = c->experiment;
    g->pos = 0;
    g->count = 0;
    const uint32_t P = d->period, L = d->n_lines, nu = d->n_inputs;
    if (c->waveform_table) {
        const msid_cplx *w = c->twiddle->w;
        for (size_t k = 0; k < (size_t)P * nu; ++k) g->wave[k] = 0.0;
        /* Line-outer, sample-inner: for each sample the terms are still added
         * in line order starting from 0.0, so the bits equal the on-the-fly sum. */
        for (uint32_t i = 0; i < nu; ++i) {
            const msid_cplx *cf = d->coef + ((size_t)c->experiment * nu + i) * L;
            for (uint32_t l = 0; l < L; ++l) {
                const uint32_t b = d->bins[l];
                uint32_t ix = 0;
                for (uint32_t n = 0; n < P; ++n) {
                    const msid_cplx t = w[ix];
                    g->wave[(size_t)n * nu + i] += cf[l].re * t.re + cf[l].im * t.im;
                    ix += b;
                    if (ix >= P) ix -= P;
                }
            }
        }
    } else {
        fill_idx(g);
    }
    return MSID_OK;
}

void msid_gen_next(msid_gen *g, double *u)
{
    const msid_design *d = g->design;
    const uint32_t P = d->period, nu = d->n_inputs, L = d->n_lines;
    if (g->wave) {
        const double *row = g->wave + (size_t)g->pos * nu;
        for (uint32_t i = 0; i < nu; ++i) u[i] = row[i];
    } else {
        const msid_cplx *w = g->twiddle->w;
        for (uint32_t i = 0; i < nu; ++i) {
            const msid_cplx *cf = d->coef + ((size_t)g->experiment * nu + i) * L;
            double s = 0.0;
            for (uint32_t l = 0; l < L; ++l) {
                const msid_cplx t = w[g->idx[l]];
                s += cf[l].re * t.re + cf[l].im * t.im;
            }
            u[i] = s;
        }
        for (uint32_t l = 0; l < L; ++l) {
            uint32_t ix = g->idx[l] + d->bins[l];
            if (ix >= P) ix -= P;
            g->idx[l] = ix;
        }
    }
    if (++g->pos == P) g->pos = 0;
    g->count++;
}

void msid_gen_block(msid_gen *g, double *u, size_t n, size_t stride)
{
    for (size_t k = 0; k < n; ++k) msid_gen_next(g, u + k * stride);
}

void msid_gen_seek(msid_gen *g, uint64_t sample)
{
    g->pos = (uint32_t)(sample % g->design->period);
    g->count = 0;
    if (g->idx) fill_idx(g);
}
