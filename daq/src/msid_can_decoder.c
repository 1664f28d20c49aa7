/* msid-can/1 frames -> rows -> msid_meas, with gap, duplicate and reorder handling. */
#include "msid_daq/msid_can_decoder.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* CAN_ERR_* classes and controller bits (linux/can/error.h; ABI constants). */
#define E_TX_TIMEOUT 0x001u
#define E_LOSTARB 0x002u
#define E_CRTL 0x004u
#define E_PROT 0x008u
#define E_TRX 0x010u
#define E_ACK 0x020u
#define E_BUSOFF 0x040u
#define E_BUSERROR 0x080u
#define E_RESTARTED 0x100u
#define E_CRTL_RX_OVERFLOW 0x01u
#define E_CRTL_TX_OVERFLOW 0x02u
#define E_CRTL_RX_WARNING 0x04u
#define E_CRTL_TX_WARNING 0x08u
#define E_CRTL_RX_PASSIVE 0x10u
#define E_CRTL_TX_PASSIVE 0x20u
#define E_CRTL_ACTIVE 0x40u

const char *msid_can_bus_state_name(msid_can_bus_state s)
{
    switch (s) {
    case MSID_CAN_BUS_ACTIVE: return "active";
    case MSID_CAN_BUS_WARNING: return "warning";
    case MSID_CAN_BUS_PASSIVE: return "passive";
    case MSID_CAN_BUS_OFF: return "bus-off";
    case MSID_CAN_BUS_RESTARTED: return "restarted";
    default: return "unknown";
    }
}

static uint32_t win(const msid_can_decoder_cfg *c) { return c->window ? c->window : 16u; }
static uint32_t blk(const msid_can_decoder_cfg *c) { return c->block ? c->block : 256u; }
static size_t up(size_t n) { return (n + MSID_MEM_ALIGN - 1) / MSID_MEM_ALIGN * MSID_MEM_ALIGN; }

size_t msid_can_decoder_mem_size(const msid_can_decoder_cfg *c)
{
    if (!c) return 0;
    const uint32_t C = c->n_inputs + c->n_outputs;
    if (c->n_inputs == 0 || c->n_outputs == 0 || C > MSID_MAX_CHANNELS || win(c) > MSID_CAN_MAX_WINDOW ||
        blk(c) > (1u << 20) || c->encoding > 1 || c->fd > 1)
        return 0;
    if (msid_can_chunks(C, c->encoding, c->fd) > (c->fd ? (c->encoding ? 3u : 2u) : (c->encoding ? 32u : 16u)))
        return 0;
    const msid_stream_cfg sc = {C, blk(c), c->meas};
    return up(sizeof(msid_can_slot) * win(c)) + up(sizeof(double) * win(c) * C) + msid_stream_mem_size(&sc);
}

/* The decimal an int16 step uploaded as float32 stands for (0.001f -> 0.001): the DBC, and so cantools,
 * scale by that decimal; decoding with it makes every sample agree bit for bit with them. The shortest
 * %.{1..9}g that reads back as the same float32; a step that is not a float32 value is kept. */
double msid_can_step_decimal(double s)
{
    const float f = (float)s;
    if ((double)f != s) return s;
    char b[32];
    for (int p = 1; p <= 9; ++p) {
        snprintf(b, sizeof b, "%.*g", p, s);
        const double v = strtod(b, NULL);
        if ((float)v == f) return v;
    }
    return s;
}

msid_status msid_can_decoder_init(msid_can_decoder *d, const msid_can_decoder_cfg *c, void *mem, size_t len)
{
    if (!d || !c || !mem || !c->meas) return MSID_E_NULL;
    const size_t need = msid_can_decoder_mem_size(c);
    if (need == 0) return MSID_E_DIMS;
    if ((c->base & 0x7Fu) || c->base > 0x780u || c->period == 0 ||
        (c->encoding == MSID_CAN_ENC_S16 && !(c->scale > 0)))
        return MSID_E_ARG;
    if (((uintptr_t)mem) % MSID_MEM_ALIGN) return MSID_E_MEM_ALIGN;
    if (len < need) return MSID_E_MEM_SIZE;
    memset(d, 0, sizeof *d);
    d->cfg = *c;
    d->cfg.window = win(c);
    d->cfg.block = blk(c);
    d->cfg.scale = msid_can_step_decimal(c->scale);
    d->C = c->n_inputs + c->n_outputs;
    d->chunks = msid_can_chunks(d->C, c->encoding, c->fd);
    d->per = msid_can_chunk_channels(c->encoding, c->fd);
    d->full = d->chunks >= 64 ? ~0ull : (1ull << d->chunks) - 1;
    char *p = mem;
    d->slot = (msid_can_slot *)p; p += up(sizeof(msid_can_slot) * d->cfg.window);
    d->row = (double *)p; p += up(sizeof(double) * d->cfg.window * d->C);
    const msid_stream_cfg sc = {d->C, d->cfg.block, c->meas};
    const msid_status st = msid_stream_init(&d->st, &sc, p, need - (size_t)(p - (char *)mem));
    if (st != MSID_OK) return st;
    for (uint32_t i = 0; i < d->cfg.window; ++i) d->slot[i].n = -1;
    d->done_exp = -1;
    return MSID_OK;
}

static void emit_row(msid_can_decoder *d, const double *row)
{
    msid_stream_row(&d->st, row);
}

static void emit_lost(msid_can_decoder *d, uint64_t n, uint64_t frames_missing)
{
    msid_stream_lost(&d->st, n);
    d->cnt.frames_missing += frames_missing;
}

/* The stream's counters are the decoder's. */
static void sync(msid_can_decoder *d)
{
    d->cnt.samples = d->st.cnt.samples;
    d->cnt.samples_lost = d->st.cnt.samples_lost;
    d->cnt.gap_events = d->st.cnt.gap_events;
    d->cnt.periods_marked = d->st.cnt.periods_marked;
}

static int popc(uint64_t x)
{
    int k = 0;
    while (x) { x &= x - 1; ++k; }
    return k;
}

/* Emit or declare missing every sample before `upto`. */
static void advance(msid_can_decoder *d, int64_t upto)
{
    const uint32_t W = d->cfg.window;
    while (d->st.next < upto) {
        int any = 0;
        for (uint32_t i = 0; i < W && !any; ++i) any = d->slot[i].n >= d->st.next;
        if (!any) {
            /* nothing stored from here on: the rest is one run of missing samples */
            const uint64_t k = (uint64_t)(upto - d->st.next);
            emit_lost(d, k, k * d->chunks);
            return;
        }
        const int64_t n = d->st.next;
        msid_can_slot *s = &d->slot[n % W];
        if (s->n == n && s->mask == d->full) {
            emit_row(d, d->row + (size_t)(n % W) * d->C);
        } else {
            const int have = s->n == n ? popc(s->mask) : 0;
            emit_lost(d, 1, (uint64_t)(d->chunks - (uint32_t)have));
            if (s->n != n) { s->n = n; s->mask = 0; }
        }
        s->emitted = 1;
    }
}

/* Emit complete samples at the head of the window. */
static void drain(msid_can_decoder *d)
{
    const uint32_t W = d->cfg.window;
    for (;;) {
        const int64_t n = d->st.next;
        msid_can_slot *s = &d->slot[n % W];
        if (s->n != n || s->mask != d->full) return;
        emit_row(d, d->row + (size_t)(n % W) * d->C);
        s->emitted = 1;
    }
}

static void reset_window(msid_can_decoder *d)
{
    for (uint32_t i = 0; i < d->cfg.window; ++i) { d->slot[i].n = -1; d->slot[i].mask = 0; d->slot[i].emitted = 0; }
    d->last_s = -1;
    d->last_k = 0;
    d->seen = 0;
}

static void close_exp(msid_can_decoder *d, int64_t total)
{
    if (!d->open) return;
    if (total >= 0) advance(d, total);
    else {
        /* unknown end: flush what the window holds */
        int64_t hi = d->st.next;
        for (uint32_t i = 0; i < d->cfg.window; ++i)
            if (d->slot[i].n >= hi && d->slot[i].mask) hi = d->slot[i].n + 1;
        advance(d, hi);
    }
    msid_stream_end(&d->st);
    d->open = 0;
    if (d->t_first && d->t_last > d->t_first) d->cnt.stream_ns += d->t_last - d->t_first;
    d->t_first = d->t_last = 0;
}

static void open_exp(msid_can_decoder *d, uint32_t e)
{
    if (d->open) close_exp(d, -1);
    reset_window(d);
    d->open = msid_stream_begin(&d->st, e) == MSID_OK;
    d->exp = e;
}

int msid_can_device_update(msid_can_device *v, const uint8_t *b)
{
    switch (b[0]) {
    case MSID_CAN_ST_STATE:
        v->have_state = 1;
        v->state = b[1]; v->experiment = b[2]; v->error = b[3]; v->value = msid_can_get_u32(b + 4);
        return MSID_CAN_ST_STATE;
    case MSID_CAN_ST_INFO:
        v->have_info = 1;
        v->version = b[1]; v->nu = b[2]; v->ny = b[3]; v->cfg_crc = msid_can_get_u32(b + 4);
        return MSID_CAN_ST_INFO;
    case MSID_CAN_ST_COUNTERS:
        v->have_counters = 1;
        v->tec = b[1]; v->rec = b[2]; v->restarts = b[3]; v->tx_dropped = msid_can_get_u32(b + 4);
        return MSID_CAN_ST_COUNTERS;
    default:
        return -1;
    }
}

static void on_status(msid_can_decoder *d, const msid_can_frame *f)
{
    d->cnt.status_frames++;
    if (f->len != 8 || (f->flags & MSID_CANF_FD)) { d->cnt.malformed++; return; }
    msid_can_device *v = &d->dev;
    switch (msid_can_device_update(v, f->data)) {
    case MSID_CAN_ST_STATE: {
        if ((v->state == MSID_CAN_STATE_RUNNING || v->state == MSID_CAN_STATE_DONE) &&
            v->experiment >= d->cfg.meas->n_experiments) {
            d->cnt.malformed++;   /* an experiment the design does not have (found by fuzz_can_decoder) */
            break;
        }
        if (v->state == MSID_CAN_STATE_RUNNING) {
            if (!d->open || d->exp != v->experiment) open_exp(d, v->experiment);
        } else if (v->state == MSID_CAN_STATE_DONE) {
            if (d->open && d->exp == v->experiment) {
                int64_t n = (int64_t)v->value;
                if (d->cfg.samples_total && (uint64_t)n > d->cfg.samples_total) {
                    /* more samples than the design has: never let the device's count size the gap walk */
                    d->cnt.malformed++;
                    d->cnt.done_beyond++;
                    n = (int64_t)d->cfg.samples_total;
                }
                if (d->seen && d->last_s >= n) {
                    /* a DONE counting no more samples than have arrived is stale (a replay of an earlier
                       run's DONE): ignored, or it would close the experiment and drop the rest */
                    d->cnt.malformed++;
                    break;
                }
                close_exp(d, n);
                d->done_exp = (int)v->experiment;
                d->cnt.experiments_done++;
            }
        } else if (v->state == MSID_CAN_STATE_ERROR || v->state == MSID_CAN_STATE_IDLE) {
            close_exp(d, -1);
        }
        break;
    }
    case MSID_CAN_ST_INFO:
    case MSID_CAN_ST_COUNTERS:
        break;
    default:
        d->cnt.malformed++;
    }
}

msid_can_bus_state msid_can_bus_state_after(msid_can_bus_state s, const msid_can_frame *f)
{
    const uint32_t cls = f->id & 0x1FFFFFFFu;
    const uint8_t ctrl = f->len > 1 ? f->data[1] : 0;
    if (!(f->id & MSID_CAN_ERR_FLAG)) return s;
    if (cls & E_BUSOFF) s = MSID_CAN_BUS_OFF;
    if (cls & E_RESTARTED) s = MSID_CAN_BUS_RESTARTED;
    if (cls & E_CRTL) {
        if (ctrl & (E_CRTL_RX_PASSIVE | E_CRTL_TX_PASSIVE)) s = MSID_CAN_BUS_PASSIVE;
        else if (ctrl & (E_CRTL_RX_WARNING | E_CRTL_TX_WARNING)) s = MSID_CAN_BUS_WARNING;
        if (ctrl & E_CRTL_ACTIVE) s = MSID_CAN_BUS_ACTIVE;
    }
    return s;
}

static void on_error(msid_can_decoder *d, const msid_can_frame *f)
{
    d->cnt.error_frames++;
    d->bus = msid_can_bus_state_after(d->bus, f);
    const uint32_t cls = f->id & 0x1FFFFFFFu;
    const uint8_t ctrl = f->len > 1 ? f->data[1] : 0;
    int lost = 0, counted = 0;
    if (cls & E_BUSOFF) { d->cnt.err_bus_off++; lost = 1; counted = 1; }
    if (cls & E_RESTARTED) { d->cnt.err_restarted++; counted = 1; }
    if (cls & E_CRTL) {
        if (ctrl & (E_CRTL_RX_OVERFLOW | E_CRTL_TX_OVERFLOW)) { d->cnt.err_ctrl_overflow++; lost = 1; counted = 1; }
        if (ctrl & (E_CRTL_RX_PASSIVE | E_CRTL_TX_PASSIVE)) { d->cnt.err_passive++; counted = 1; }
        else if (ctrl & (E_CRTL_RX_WARNING | E_CRTL_TX_WARNING)) { d->cnt.err_warning++; counted = 1; }
        if (ctrl & E_CRTL_ACTIVE) counted = 1;
    }
    if (cls & E_PROT) { d->cnt.err_protocol++; counted = 1; }
    if (cls & E_ACK) { d->cnt.err_ack++; counted = 1; }
    if (!counted) d->cnt.err_other++;
    (void)E_TX_TIMEOUT; (void)E_LOSTARB; (void)E_TRX; (void)E_BUSERROR;
    if (lost && d->open) {
        /* frames were lost on the bus: the period being assembled cannot be trusted */
        msid_stream_mark(&d->st);
    }
}

static msid_status feed(msid_can_decoder *d, const msid_can_frame *f)
{
    const uint32_t off = f->id & 0x7Fu;
    if (!(f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) && (f->id & 0x780u) == d->cfg.base &&
        (off == MSID_CAN_ID_CTRL || off == MSID_CAN_ID_CFG)) {
        d->cnt.host_frames++;   /* the host's own frames (in logs) */
        return d->st.err;
    }
    d->cnt.frames++;
    if (f->id & MSID_CAN_ERR_FLAG) { on_error(d, f); return d->st.err; }
    if ((f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG)) || (f->id & 0x780u) != d->cfg.base) {
        d->cnt.foreign++;
        return d->st.err;
    }
    if (off == MSID_CAN_ID_STATUS) { on_status(d, f); return d->st.err; }
    uint32_t enc, fd, k;
    if (!msid_can_classify_sample(off, &enc, &fd, &k)) { d->cnt.foreign++; return d->st.err; }
    const uint32_t want_len = msid_can_sample_len(d->cfg.fd);
    if (enc != d->cfg.encoding || fd != d->cfg.fd || k >= d->chunks || f->len != want_len ||
        ((f->flags & MSID_CANF_FD) != 0) != (d->cfg.fd != 0)) {
        d->cnt.malformed++;
        return d->st.err;
    }
    const uint8_t *b = f->data;
    const uint32_t exp = b[3] & MSID_CAN_EXP_MASK, flags = b[3] & (MSID_CAN_PSTART | MSID_CAN_SEGSTART);
    const uint32_t seq = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16;
    if (!d->open || exp != d->exp) { d->cnt.foreign++; return d->st.err; }
    const uint32_t W = d->cfg.window;
    if ((flags & MSID_CAN_SEGSTART) && seq == 0 && d->seen && d->st.next >= (int64_t)W) {
        /* the device restarted: close this segment, open a new one of the same experiment */
        const uint32_t e = d->exp;
        close_exp(d, -1);
        open_exp(d, e);
        d->cnt.restarts++;
        if (d->st.err) return d->st.err;
    }
    /* absolute sample index from the 24-bit counter, nearest to the emit position */
    uint32_t delta = (seq - (uint32_t)(d->st.next & (MSID_CAN_SEQ_MOD - 1))) & (MSID_CAN_SEQ_MOD - 1);
    const int64_t s = d->st.next + (delta >= MSID_CAN_SEQ_MOD / 2 ? (int64_t)delta - MSID_CAN_SEQ_MOD : (int64_t)delta);
    if (((flags & MSID_CAN_PSTART) != 0) != (s >= 0 && s % d->cfg.period == 0) ||
        ((flags & MSID_CAN_SEGSTART) != 0) != (s == 0)) {
        d->cnt.malformed++;
        return d->st.err;
    }
    if (d->cfg.samples_total && s >= (int64_t)d->cfg.samples_total) {
        d->cnt.malformed++;   /* beyond the design's K P samples */
        return d->st.err;
    }
    msid_can_slot *sl = &d->slot[(uint64_t)s % W];
    if (s < d->st.next) {
        if (sl->n == s && (sl->mask >> k & 1u)) d->cnt.duplicates++;
        else d->cnt.late++;
        return d->st.err;
    }
    if (s >= d->st.next + (int64_t)W) {
        advance(d, s - (int64_t)W + 1);
    }
    if (sl->n != s) { sl->n = s; sl->mask = 0; sl->emitted = 0; }
    if (sl->mask >> k & 1u) { d->cnt.duplicates++; return d->st.err; }
    if (d->seen && (s < d->last_s || (s == d->last_s && k < d->last_k))) d->cnt.reordered++;
    else { d->last_s = s; d->last_k = k; }
    d->seen = 1;
    if (f->t_ns) {
        if (!d->t_first) d->t_first = f->t_ns;
        d->t_last = f->t_ns;
    }
    msid_can_decode_values(b, enc, fd, k, d->row + (size_t)((uint64_t)s % W) * d->C, d->C, d->cfg.scale);
    sl->mask |= 1ull << k;
    d->cnt.sample_frames++;
    drain(d);
    return d->st.err;
}

msid_status msid_can_decoder_feed(msid_can_decoder *d, const msid_can_frame *f)
{
    const msid_status st = feed(d, f);
    sync(d);
    return st;
}

msid_status msid_can_decoder_abort(msid_can_decoder *d)
{
    close_exp(d, -1);
    sync(d);
    return d->st.err;
}
