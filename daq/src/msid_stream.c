/* Sample-index stream -> msid_meas: rows in blocks, runs of missing samples as gaps, segments. */
#include "msid_daq/msid_stream.h"

#include <string.h>

static uint32_t blk(const msid_stream_cfg *c) { return c->block ? c->block : 256u; }

size_t msid_stream_mem_size(const msid_stream_cfg *c)
{
    if (!c || c->n_channels == 0 || c->n_channels > MSID_MAX_CHANNELS || blk(c) > (1u << 20)) return 0;
    const size_t n = sizeof(double) * blk(c) * c->n_channels;
    return (n + MSID_MEM_ALIGN - 1) / MSID_MEM_ALIGN * MSID_MEM_ALIGN;
}

msid_status msid_stream_init(msid_stream *s, const msid_stream_cfg *c, void *mem, size_t len)
{
    if (!s || !c || !mem || !c->meas) return MSID_E_NULL;
    const size_t need = msid_stream_mem_size(c);
    if (need == 0) return MSID_E_DIMS;
    if (((uintptr_t)mem) % MSID_MEM_ALIGN) return MSID_E_MEM_ALIGN;
    if (len < need) return MSID_E_MEM_SIZE;
    memset(s, 0, sizeof *s);
    s->cfg = *c;
    s->cfg.block = blk(c);
    s->rows = mem;
    s->err = MSID_OK;
    return MSID_OK;
}

static void core(msid_stream *s, msid_status st)
{
    if (st != MSID_OK && s->err == MSID_OK) s->err = st;
}

static void flush_rows(msid_stream *s)
{
    if (s->nrows) core(s, msid_meas_push(s->cfg.meas, s->rows, s->nrows));
    s->nrows = 0;
}

static void flush_gap(msid_stream *s)
{
    if (s->gap_run) {
        core(s, msid_meas_push_gap(s->cfg.meas, (size_t)s->gap_run));
        s->cnt.gap_events++;
    }
    s->gap_run = 0;
}

msid_status msid_stream_begin(msid_stream *s, uint32_t e)
{
    msid_stream_end(s);
    core(s, msid_meas_begin(s->cfg.meas, e));
    s->open = s->err == MSID_OK;
    s->exp = e;
    s->next = 0;
    s->cnt.segments += (uint64_t)s->open;
    return s->err;
}

msid_status msid_stream_row(msid_stream *s, const double *row)
{
    if (!s->open) return s->err;
    flush_gap(s);
    memcpy(s->rows + (size_t)s->nrows * s->cfg.n_channels, row, sizeof(double) * s->cfg.n_channels);
    if (++s->nrows == s->cfg.block) flush_rows(s);
    s->cnt.samples++;
    s->next++;
    return s->err;
}

msid_status msid_stream_lost(msid_stream *s, uint64_t n)
{
    if (!s->open || !n) return s->err;
    flush_rows(s);
    s->gap_run += n;
    s->cnt.samples_lost += n;
    s->next += (int64_t)n;
    return s->err;
}

msid_status msid_stream_mark(msid_stream *s)
{
    if (!s->open) return s->err;
    flush_rows(s);
    flush_gap(s);
    core(s, msid_meas_mark_gap(s->cfg.meas));
    s->cnt.periods_marked++;
    return s->err;
}

msid_status msid_stream_end(msid_stream *s)
{
    if (!s->open) return s->err;
    flush_rows(s);
    flush_gap(s);
    core(s, msid_meas_end(s->cfg.meas, NULL));
    s->open = 0;
    return s->err;
}
