/* Online ISP regression of discrete-cISSIM (You et al. 2023, Algorithm 2). */
#include "msid/msid_cissim.h"
#include "msid_internal.h"

static uint32_t rows_of(const uint32_t *bins, uint32_t q)
{
    uint32_t s = 0, l;
    for (l = 0; l < q; ++l) s += bins[l] == 0u ? 1u : 2u;
    return s;
}

static msid_status check_cfg(const msid_cissim_cfg *cfg)
{
    uint32_t l, k;
    if (!cfg || !cfg->bins || !cfg->twiddle) return MSID_E_NULL;
    if (cfg->period < MSID_MIN_PERIOD || cfg->period > MSID_MAX_PERIOD) return MSID_E_PERIOD;
    if (cfg->twiddle->period != cfg->period) return MSID_E_BACKEND;
    if (cfg->n_lines == 0u) return MSID_E_NO_LINES;
    if (cfg->n_channels < 2u || cfg->n_channels > MSID_MAX_CHANNELS) return MSID_E_DIMS;
    for (l = 0; l < cfg->n_lines; ++l) {
        if ((uint64_t)cfg->bins[l] * 2u >= cfg->period) return MSID_E_LINE_RANGE;
        for (k = 0; k < l; ++k)
            if (cfg->bins[k] == cfg->bins[l]) return MSID_E_LINE_DUP;
    }
    return MSID_OK;
}

/* The one memory layout (msid__layout): bins, phases, the period sum, the running mean. */
static size_t layout(msid_cissim *cs, const msid_cissim_cfg *cfg, void *mem)
{
    const size_t s = (size_t)rows_of(cfg->bins, cfg->n_lines) * cfg->n_channels;
    msid__layout y = msid__layout_begin(mem);
    cs->bins = (uint32_t *)msid__lay(&y, cfg->n_lines, sizeof(uint32_t));
    cs->phase = (uint32_t *)msid__lay(&y, cfg->n_lines, sizeof(uint32_t));
    cs->acc = (double *)msid__lay(&y, s, sizeof(double));
    cs->est = (double *)msid__lay(&y, s, sizeof(double));
    return y.size;
}

size_t msid_cissim_mem_size(const msid_cissim_cfg *cfg)
{
    msid_cissim tmp;
    size_t n;
    if (check_cfg(cfg) != MSID_OK) return 0;
    n = layout(&tmp, cfg, 0);
    return n == SIZE_MAX ? 0 : n;
}

msid_status msid_cissim_init(msid_cissim *cs, const msid_cissim_cfg *cfg, void *mem, size_t len)
{
    msid_status st;
    size_t s, i;
    uint32_t l;
    if (!cs) return MSID_E_NULL;
    st = check_cfg(cfg);
    if (st != MSID_OK) return st;
    st = msid__mem_check(mem, len, msid_cissim_mem_size(cfg));
    if (st != MSID_OK) return st;
    (void)layout(cs, cfg, mem);
    cs->period = cfg->period;
    cs->n_lines = cfg->n_lines;
    cs->n_channels = cfg->n_channels;
    cs->n_rows = rows_of(cfg->bins, cfg->n_lines);
    cs->tw = cfg->twiddle;
    s = (size_t)cs->n_rows * cs->n_channels;
    for (l = 0; l < cfg->n_lines; ++l) {
        cs->bins[l] = cfg->bins[l];
        cs->phase[l] = 0u;
    }
    for (i = 0; i < s; ++i) cs->acc[i] = cs->est[i] = 0.0;
    cs->in_period = 0u;
    cs->periods = 0u;
    return MSID_OK;
}

/* Alg. 2 steps 6-10: fold the period's sum into the running mean. */
static void end_period(msid_cissim *cs)
{
    const size_t s = (size_t)cs->n_rows * cs->n_channels;
    const double t = (double)(cs->periods + 1u), g = 2.0 / (double)cs->period;
    size_t i;
    for (i = 0; i < s; ++i) {
        cs->est[i] = ((t - 1.0) / t) * cs->est[i] + (1.0 / t) * (g * cs->acc[i]);
        cs->acc[i] = 0.0;
    }
    cs->periods++;
    cs->in_period = 0u;
}

msid_status msid_cissim_push(msid_cissim *cs, const double *rows, size_t n)
{
    const uint32_t C = cs ? cs->n_channels : 0u;
    const double dc = 0.70710678118654752440;   /* 1/sqrt(2), eq. (7) */
    size_t k, i;
    uint32_t l, c;
    if (!cs || (!rows && n)) return MSID_E_NULL;
    for (i = 0; i < n * C; ++i)
        if (!msid__finite(rows[i])) return MSID_E_NOT_FINITE;
    for (k = 0; k < n; ++k) {
        const double *z = rows + k * C;
        double *r = cs->acc;
        for (l = 0; l < cs->n_lines; ++l) {
            if (cs->bins[l] == 0u) {
                for (c = 0; c < C; ++c) r[c] += dc * z[c];
                r += C;
            } else {
                const msid_cplx w = cs->tw->w[cs->phase[l]];   /* (cos, -sin) of 2 pi b k / T */
                const double sn = -w.im, cn = w.re;
                for (c = 0; c < C; ++c) {
                    r[c] += sn * z[c];
                    r[C + c] += cn * z[c];
                }
                r += 2u * C;
                cs->phase[l] += cs->bins[l];
                if (cs->phase[l] >= cs->period) cs->phase[l] -= cs->period;
            }
        }
        if (++cs->in_period == cs->period) end_period(cs);
    }
    return MSID_OK;
}

uint32_t msid_cissim_rows(const msid_cissim *cs) { return cs ? cs->n_rows : 0u; }
uint64_t msid_cissim_periods(const msid_cissim *cs) { return cs ? cs->periods : 0u; }
const double *msid_cissim_estimate(const msid_cissim *cs) { return cs ? cs->est : 0; }
