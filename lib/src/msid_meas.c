/* Measurement pipeline: rows -> line DFT -> period statistics per experiment. */
#include "msid/msid_meas.h"
#include "msid_internal.h"

/* Bins of the DFT: excited lines first, then detection lines. */
static size_t nbins(const msid_meas_cfg *c) { return (size_t)c->n_lines + c->n_detect; }

static void sub_cfgs(const msid_meas_cfg *c, const uint32_t *bins, msid_linedft_cfg *dc, msid_pstats_cfg *pc)
{
    dc->period = c->period;
    dc->n_channels = c->n_inputs + c->n_outputs;
    dc->n_lines = (uint32_t)nbins(c);
    dc->bins = bins;
    dc->twiddle = c->twiddle;
    dc->path = c->path;
    dc->fft = c->fft;
    dc->spread = c->spread ? 1 : 0;
    pc->n_lines = (uint32_t)nbins(c);
    pc->n_channels = c->n_inputs + c->n_outputs;
    pc->skip_periods = c->skip_periods;
    pc->max_periods = c->max_periods;
    pc->beyond_history = c->beyond_history;
    pc->transient = c->transient;
    pc->alpha = c->alpha;
}

/* Chunks of a measurement that are not members of the instance. */
typedef struct meas_chunks {
    uint32_t *bins, *sorted;   /* [L + D] bins (excited, then detection) and a sorted copy */
    void *dft, *ps;            /* memory of the line DFT and of the m period statistics */
    size_t dft_size, ps_size;  /* their _mem_size (0: invalid configuration) */
} meas_chunks;

/* The one memory layout (see msid__layout): bins, sorted scratch, line DFT, the
 * m statistics instances, their memory, leftover and sample counters. */
static size_t layout(msid_meas *ms, meas_chunks *k, const msid_meas_cfg *c, void *mem)
{
    uint32_t dummy = 0;
    msid_linedft_cfg dc;
    msid_pstats_cfg pc;
    sub_cfgs(c, &dummy, &dc, &pc);
    k->bins = k->sorted = 0;
    k->dft = k->ps = 0;
    k->dft_size = msid_linedft_mem_size(&dc);
    k->ps_size = msid_pstats_mem_size(&pc);
    if (k->dft_size == 0 || k->ps_size == 0) return 0;
    const size_t m = c->n_experiments;
    msid__layout y = msid__layout_begin(mem);
    k->bins = (uint32_t *)msid__lay(&y, nbins(c), sizeof(uint32_t));
    k->sorted = (uint32_t *)msid__lay(&y, nbins(c), sizeof(uint32_t));
    k->dft = msid__lay(&y, k->dft_size, 1);
    ms->ps = (msid_pstats *)msid__lay(&y, m, sizeof(msid_pstats));
    k->ps = msid__lay(&y, m, k->ps_size);
    ms->leftover = (uint64_t *)msid__lay(&y, m, sizeof(uint64_t));
    ms->samples = (uint64_t *)msid__lay(&y, m, sizeof(uint64_t));
    return y.size;
}

size_t msid_meas_mem_size(const msid_meas_cfg *c)
{
    if (!c || c->n_lines == 0) return 0;
    if (c->n_inputs == 0 || c->n_inputs > MSID_MAX_INPUTS || c->n_outputs == 0 ||
        c->n_outputs > MSID_MAX_OUTPUTS || c->n_experiments == 0 ||
        c->n_experiments > MSID_MAX_EXPERIMENTS) return 0;
    msid_meas tmp;
    meas_chunks k;
    return layout(&tmp, &k, c, 0);
}

msid_status msid_meas_init(msid_meas *ms, const msid_meas_cfg *c, void *mem, size_t len)
{
    if (!ms || !c || !c->bins || (c->n_detect && !c->detect_bins)) return MSID_E_NULL;
    if (c->n_lines == 0) return MSID_E_NO_LINES;
    if (c->n_inputs == 0 || c->n_inputs > MSID_MAX_INPUTS || c->n_outputs == 0 ||
        c->n_outputs > MSID_MAX_OUTPUTS || c->n_experiments == 0 ||
        c->n_experiments > MSID_MAX_EXPERIMENTS) return MSID_E_DIMS;
    if (c->n_experiments < c->n_inputs) return MSID_E_EXPERIMENTS;
    if (c->period < MSID_MIN_PERIOD || c->period > MSID_MAX_PERIOD) return MSID_E_PERIOD;
    for (uint32_t l = 0; l < c->n_lines; ++l)
        if ((uint64_t)c->bins[l] * 2u >= c->period) return MSID_E_LINE_RANGE;
    for (uint32_t l = 0; l < c->n_detect; ++l)   /* complex bins only: the tests assume circular noise */
        if (c->detect_bins[l] == 0u || (uint64_t)c->detect_bins[l] * 2u >= c->period) return MSID_E_LINE_RANGE;
    const size_t need = msid_meas_mem_size(c);
    if (need == 0) return MSID_E_DIMS;
    msid_status st = msid__mem_check(mem, len, need);
    if (st != MSID_OK) return st;
    meas_chunks k;
    (void)layout(ms, &k, c, mem);
    const size_t nb = nbins(c), m = c->n_experiments;
    uint32_t *bins = k.bins;
    for (size_t l = 0; l < c->n_lines; ++l) bins[l] = c->bins[l];
    for (size_t l = 0; l < c->n_detect; ++l) bins[c->n_lines + l] = c->detect_bins[l];
    /* no bin twice (excited or detection): sort a copy, O(L log L) */
    uint32_t *srt = k.sorted;
    for (size_t l = 0; l < nb; ++l) srt[l] = bins[l];
    msid__sort_u32(srt, nb);
    for (size_t l = 1; l < nb; ++l) if (srt[l] == srt[l - 1]) return MSID_E_LINE_DUP;
    msid_linedft_cfg dc;
    msid_pstats_cfg pc;
    sub_cfgs(c, bins, &dc, &pc);
    st = msid_linedft_init(&ms->dft, &dc, k.dft, k.dft_size);
    if (st != MSID_OK) return st;
    for (size_t e = 0; e < m; ++e) {
        st = msid_pstats_init(&ms->ps[e], &pc, (unsigned char *)k.ps + e * k.ps_size, k.ps_size);
        if (st != MSID_OK) return st;
    }
    for (size_t e = 0; e < m; ++e) ms->leftover[e] = ms->samples[e] = 0;
    ms->period = c->period;
    ms->n_inputs = c->n_inputs;
    ms->n_outputs = c->n_outputs;
    ms->n_experiments = c->n_experiments;
    ms->n_lines = c->n_lines;
    ms->n_detect = c->n_detect;
    ms->current = -1;
    ms->err = MSID_OK;
    ms->spread = c->spread ? 1 : 0;
    ms->spread_rate = (uint32_t)((2u * nb + c->period - 1u) / c->period);
    ms->pend = 0;
    ms->pend_unit = 0;
    ms->pend_use = 0;
    return MSID_OK;
}

msid_status msid_meas_begin(msid_meas *ms, uint32_t e)
{
    if (e >= ms->n_experiments) return MSID_E_ARG;
    if (ms->current >= 0) return MSID_E_STATE;
    ms->current = (int)e;
    msid_linedft_reset(&ms->dft);
    msid_pstats_new_segment(&ms->ps[e]);
    return MSID_OK;
}

/* Hand a completed period to the statistics. */
static msid_status drain(msid_meas *ms)
{
    if (!msid_linedft_ready(&ms->dft)) return MSID_OK;
    msid_status st = msid_pstats_add(&ms->ps[ms->current], msid_linedft_spectra(&ms->dft),
                                     msid_linedft_flags(&ms->dft));
    msid_linedft_release(&ms->dft);
    if (st == MSID_OK && msid_linedft_error(&ms->dft) != MSID_OK) st = msid_linedft_error(&ms->dft);
    return st;
}

/* Spread mode: up to `units` units of the deferred period-end work, in order:
 * settle the spectra line by line (linedft), then count the period and update
 * its statistics line by line (pstats). */
static msid_status spread_work(msid_meas *ms, size_t units)
{
    if (!ms->pend && msid_linedft_pending(&ms->dft)) { ms->pend = 1; ms->pend_unit = 0; }
    if (!ms->pend) return MSID_OK;
    const uint32_t nb = ms->n_lines + ms->n_detect;
    msid_pstats *ps = &ms->ps[ms->current];
    msid_status st = MSID_OK;
    while (units && ms->pend) {
        if (ms->pend_unit < nb) {
            const size_t k = msid_linedft_settle(&ms->dft, units);
            ms->pend_unit += (uint32_t)k;
            units -= k;
            if (ms->pend_unit < nb) break;
            st = msid_pstats_add_begin(ps, msid_linedft_flags(&ms->dft), &ms->pend_use);
            if (st != MSID_OK || !ms->pend_use) ms->pend_unit = 2u * nb;
        } else {
            const uint32_t l0 = ms->pend_unit - nb;
            const uint32_t k = units < nb - l0 ? (uint32_t)units : nb - l0;
            msid_pstats_add_lines(ps, msid_linedft_spectra(&ms->dft), l0, l0 + k);
            ms->pend_unit += k;
            units -= k;
        }
        if (ms->pend_unit == 2u * nb) {
            msid_linedft_release(&ms->dft);
            ms->pend = 0;
            if (msid_linedft_pending(&ms->dft)) { ms->pend = 1; ms->pend_unit = 0; }
        }
        if (st != MSID_OK) return st;
    }
    return MSID_OK;
}

msid_status msid_meas_flush(msid_meas *ms)
{
    if (!ms->spread || ms->current < 0) return MSID_OK;
    msid_status st = spread_work(ms, SIZE_MAX);
    if (st != MSID_OK && ms->err == MSID_OK) ms->err = st;
    return ms->err;
}

/* Rows of doubles x, or of floats xf. */
MSID__ALWAYS_INLINE size_t push_dft(msid_meas *ms, const double *x, const float *xf, size_t off, size_t n)
{
    return xf ? msid_linedft_push_f32(&ms->dft, xf + off, n) : msid_linedft_push(&ms->dft, x + off, n);
}

MSID__ALWAYS_INLINE msid_status push_rows(msid_meas *ms, const double *x, const float *xf, size_t n)
{
    if (ms->current < 0) return MSID_E_STATE;
    if (ms->err != MSID_OK) return ms->err;
    if (n && !x && !xf) return MSID_E_NULL;
    const size_t C = (size_t)ms->n_inputs + ms->n_outputs;
    size_t off = 0;
    while (n) {
        msid_status st = MSID_OK;
        size_t k;
        if (ms->spread) {
            /* the deferred work of these samples first; all of it before a sample that ends a period */
            const size_t room = ms->period - ms->dft.pos, want = n < room ? n : room;
            if (ms->pend || ms->dft.pending) st = spread_work(ms, want == room ? SIZE_MAX : want * ms->spread_rate);
            if (st == MSID_OK) {
                k = push_dft(ms, x, xf, off, want);
                off += k * C;
                n -= k;
                ms->samples[ms->current] += k;
            }
        } else {
            k = push_dft(ms, x, xf, off, n);
            off += k * C;
            n -= k;
            ms->samples[ms->current] += k;
            st = drain(ms);
        }
        if (st != MSID_OK) { ms->err = st; return st; }
    }
    return MSID_OK;
}

msid_status msid_meas_push(msid_meas *ms, const double *rows, size_t n) { return push_rows(ms, rows, 0, n); }

msid_status msid_meas_push_f32(msid_meas *ms, const float *rows, size_t n) { return push_rows(ms, 0, rows, n); }

msid_status msid_meas_push_gap(msid_meas *ms, size_t n)
{
    if (ms->current < 0) return MSID_E_STATE;
    if (ms->err != MSID_OK) return ms->err;
    const size_t P = ms->period;
    while (n) {
        if (ms->spread) {   /* gaps are not per-sample work: finish any deferred period now */
            msid_status st = msid_meas_flush(ms);
            if (st != MSID_OK) return st;
        }
        if (ms->dft.pos == 0 && !msid_linedft_ready(&ms->dft) && n >= P) {
            /* whole missing periods: each is offered and rejected as a gap, counted in O(1), so the
               cost of a gap does not grow with its length (counters saturate) */
            const uint64_t q = n / P;
            msid_pstats_counts *c = &ms->ps[ms->current].cnt;
            const uint64_t off = (uint64_t)c->offered + q, gap = (uint64_t)c->gap + q;
            c->offered = off > UINT32_MAX ? UINT32_MAX : (uint32_t)off;
            c->gap = gap > UINT32_MAX ? UINT32_MAX : (uint32_t)gap;
            ms->dft.periods += q;
            ms->dft.flags = 0;   /* a pending mark belonged to the first of these periods */
            ms->samples[ms->current] += q * P;
            n -= (size_t)(q * P);
            continue;
        }
        const size_t k = msid_linedft_push_gap(&ms->dft, n);
        n -= k;
        ms->samples[ms->current] += k;
        msid_status st = ms->spread ? msid_meas_flush(ms) : drain(ms);
        if (st != MSID_OK) { ms->err = st; return st; }
    }
    return MSID_OK;
}

msid_status msid_meas_mark_gap(msid_meas *ms)
{
    if (ms->current < 0) return MSID_E_STATE;
    msid_linedft_mark_gap(&ms->dft);
    return MSID_OK;
}

msid_status msid_meas_end(msid_meas *ms, uint64_t *leftover)
{
    if (ms->current < 0) return MSID_E_STATE;
    (void)msid_meas_flush(ms);   /* an error is sticky: the next push reports it, as without spreading */
    const uint32_t e = (uint32_t)ms->current;
    const uint64_t left = ms->dft.pos;
    ms->leftover[e] += left;
    if (leftover) *leftover = left;
    msid_linedft_reset(&ms->dft);
    ms->current = -1;
    return msid_pstats_detect(&ms->ps[e]);
}

const msid_pstats *msid_meas_stats(const msid_meas *ms, uint32_t e)
{
    return e < ms->n_experiments ? &ms->ps[e] : 0;
}

uint64_t msid_meas_leftover(const msid_meas *ms, uint32_t e)
{
    return e < ms->n_experiments ? ms->leftover[e] : 0;
}
