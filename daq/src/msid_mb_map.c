/* A Modbus device described by msid-device/1 as a tick-loop backend (msid_mb_map.h): spans of contiguous
 * registers, one request each, or FC 23 for the write and the first holding read. */
#include "msid_daq/msid_mb_map.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "msid_daq/msid_tick.h"

static int fail(msid_mb_map *m, int rc, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(m->err, sizeof m->err, fmt, ap);
    va_end(ap);
    return rc;
}

/* ---- the plan ------------------------------------------------------------------------------------ */

/* Spans of the channels ch[0..n) (sorted by table and address here, through an index), contiguous
 * registers merged up to cap registers; span_of[i] gets channel i's span. */
static uint32_t plan(const msid_dev_chan *ch, uint32_t n, uint32_t cap, msid_mb_span *sp, uint32_t *span_of)
{
    uint32_t idx[MSID_DEV_MAX_MEASURE];
    for (uint32_t i = 0; i < n; ++i) idx[i] = i;
    for (uint32_t i = 1; i < n; ++i) {   /* insertion sort: a few dozen channels */
        const uint32_t k = idx[i];
        uint32_t j = i;
        while (j > 0 && (ch[idx[j - 1]].table > ch[k].table ||
                         (ch[idx[j - 1]].table == ch[k].table && ch[idx[j - 1]].addr > ch[k].addr))) {
            idx[j] = idx[j - 1];
            --j;
        }
        idx[j] = k;
    }
    uint32_t ns = 0;
    for (uint32_t q = 0; q < n; ++q) {
        const msid_dev_chan *c = &ch[idx[q]];
        const uint32_t w = msid_dev_type_regs(c->type);
        msid_mb_span *last = ns ? &sp[ns - 1] : NULL;
        if (last && last->table == c->table && last->addr + last->n == c->addr && last->n + w <= cap) {
            last->n += w;
        } else {
            sp[ns].table = c->table;
            sp[ns].addr = c->addr;
            sp[ns].n = w;
            ++ns;
        }
        span_of[idx[q]] = ns - 1;
    }
    return ns;
}

int msid_mb_map_fc23_possible(const msid_mb_map *m)
{
    if (m->n_wspan != 1 || m->wspan[0].n > 121 || !m->tr->be->write_read) return 0;
    for (uint32_t s = 0; s < m->n_rspan; ++s)
        if (m->rspan[s].table == MSID_DEV_HOLDING) return 1;
    return 0;
}

uint32_t msid_mb_map_requests(const msid_mb_map *m)
{
    return m->use_fc23 ? m->n_rspan : m->n_wspan + m->n_rspan;
}

/* ---- requests ------------------------------------------------------------------------------------ */

/* The names of the channels a request carries (the span's, and for FC 23 the write span's too): a refused request
 * names what the description puts there, not only its addresses. At most three names, then how many more. */
static void span_names(const msid_mb_map *m, const msid_mb_span *r, const msid_mb_span *w, char *out, size_t cap)
{
    const msid_devdesc *d = m->desc;
    uint32_t n = 0;
    size_t len = 0;
    out[0] = 0;
    for (uint32_t i = 0; i < d->n_drive + d->n_measure; ++i) {
        const int drive = i < d->n_drive;
        const uint32_t k = drive ? i : i - d->n_drive;
        const msid_dev_chan *c = drive ? &d->drive[k] : &d->measure[k];
        const msid_mb_span *sp = drive ? w : r;   /* drive channels are written, measure channels read */
        if (!sp || c->table != sp->table || c->addr < sp->addr || c->addr >= sp->addr + sp->n) continue;
        if (n++ < 3 && len < cap)
            len += (size_t)snprintf(out + len, cap - len, "%s'%s'", n > 1 ? ", " : "",
                                    drive ? d->drive[k].name : d->measure[k].name);
    }
    if (n > 3 && len < cap) snprintf(out + len, cap - len, " and %u more", n - 3);
}

static int request_failed(msid_mb_map *m, int rc, uint32_t fc, const msid_mb_span *s, const msid_mb_span *w)
{
    m->cnt.failures++;
    m->cnt.last_function = fc;
    if (rc == -MSID_DAQ_E_TIMEOUT) m->cnt.timeouts++;
    else if (rc == -MSID_DAQ_E_EXCEPTION) {
        m->cnt.exceptions++;
        m->cnt.last_exception = msid_mb_exception(m->tr);
    } else if (rc == -MSID_DAQ_E_BADDATA || rc == -MSID_DAQ_E_CRC || rc == -MSID_DAQ_E_PROTOCOL) m->cnt.bad_replies++;
    else {
        m->cnt.io_errors++;
        m->lost = 1;
    }
    char names[200];
    if (fc == 16) span_names(m, NULL, s, names, sizeof names);   /* a write names the drive channels of s */
    else span_names(m, s, w, names, sizeof names);
    const char *what = fc == 16 ? "write" : "read";
    return fail(m, rc, "%s %s registers %u..%u (function %u; %s): %s", what,
                s->table == MSID_DEV_HOLDING ? "holding" : "input", s->addr, s->addr + s->n - 1, fc, names,
                msid_mb_error(m->tr));
}

static int do_write(msid_mb_map *m, const double *drive)
{
    const msid_devdesc *d = m->desc;
    for (uint32_t i = 0; i < d->n_drive; ++i) {
        const msid_dev_chan *c = &d->drive[i];
        const msid_mb_span *s = &m->wspan[m->wspan_of[i]];
        if (msid_dev_encode(c, drive[i], &m->wbuf[m->wspan_of[i]][c->addr - s->addr]) != 0)
            return fail(m, -MSID_DAQ_E_ARG, "'%s': %.9g does not fit %s with scale %g and offset %g", c->name,
                        drive[i], msid_dev_type_name(c->type), c->scale, c->offset);
    }
    return 0;
}

static void decode_all(msid_mb_map *m, double *measure)
{
    const msid_devdesc *d = m->desc;
    for (uint32_t i = 0; i < d->n_measure; ++i) {
        const msid_dev_chan *c = &d->measure[i];
        const msid_mb_span *s = &m->rspan[m->rspan_of[i]];
        measure[i] = msid_dev_decode(c, &m->rbuf[m->rspan_of[i]][c->addr - s->addr]);
    }
}

/* The reads of spans [from, n_rspan), skipping span `skip` (read by FC 23 already). */
static int read_spans(msid_mb_map *m, uint32_t skip)
{
    for (uint32_t s = 0; s < m->n_rspan; ++s) {
        if (s == skip) continue;
        const msid_mb_span *sp = &m->rspan[s];
        m->cnt.requests++;
        const int rc = sp->table == MSID_DEV_HOLDING ? msid_mb_read_holding(m->tr, sp->addr, sp->n, m->rbuf[s])
                                                      : msid_mb_read_input(m->tr, sp->addr, sp->n, m->rbuf[s]);
        if (rc < 0) return request_failed(m, rc, sp->table == MSID_DEV_HOLDING ? 3 : 4, sp, NULL);
    }
    return 0;
}

static int write_spans(msid_mb_map *m)
{
    for (uint32_t s = 0; s < m->n_wspan; ++s) {
        const msid_mb_span *sp = &m->wspan[s];
        m->cnt.requests++;
        const int rc = msid_mb_write_holding(m->tr, sp->addr, sp->n, m->wbuf[s]);
        if (rc < 0) return request_failed(m, rc, 16, sp, NULL);
    }
    return 0;
}

static uint32_t first_holding_read(const msid_mb_map *m)
{
    for (uint32_t s = 0; s < m->n_rspan; ++s)
        if (m->rspan[s].table == MSID_DEV_HOLDING) return s;
    return UINT32_MAX;
}

/* The counter's read before the write, where the write's transaction does not read it: FC 23 reads the device
   at the write's own instant only for the first holding span. */
static int counter_outside_write(const msid_mb_map *m)
{
    if (m->counter < 0) return 0;
    return !m->use_fc23 || m->rspan_of[m->counter] != first_holding_read(m);
}

static int read_counter_before(msid_mb_map *m, msid_devio_times *t)
{
    const msid_dev_chan *c = &m->desc->measure[m->counter];
    const msid_mb_span one = {c->table, c->addr, msid_dev_type_regs(c->type)};
    m->cnt.requests++;
    const int rc = c->table == MSID_DEV_HOLDING ? msid_mb_read_holding(m->tr, one.addr, one.n, m->cbuf)
                                                 : msid_mb_read_input(m->tr, one.addr, one.n, m->cbuf);
    if (rc < 0) return request_failed(m, rc, c->table == MSID_DEV_HOLDING ? 3 : 4, &one, NULL);
    t->counter_before = msid_dev_decode(c, m->cbuf);
    t->has_counter_before = 1;
    return 0;
}

/* ---- the backend --------------------------------------------------------------------------------- */

static int exchange_(void *ctx, const double *drive, double *measure, msid_devio_times *t)
{
    msid_mb_map *m = ctx;
    m->cnt.exchanges++;
    int rc = do_write(m, drive);
    if (rc < 0) return rc;
    const uint32_t before = (uint32_t)m->cnt.requests;
    if (counter_outside_write(m) && (rc = read_counter_before(m, t)) < 0) return rc;
    if (m->use_fc23) {
        const uint32_t s = first_holding_read(m);
        const msid_mb_span *w = &m->wspan[0], *r = &m->rspan[s];
        t->w0 = t->r0 = msid_now_ns();
        m->cnt.requests++;
        rc = msid_mb_write_read(m->tr, w->addr, w->n, m->wbuf[0], r->addr, r->n, m->rbuf[s]);
        t->w1 = msid_now_ns();
        if (rc < 0) return request_failed(m, rc, 23, r, w);
        rc = read_spans(m, s);
        t->r1 = msid_now_ns();
    } else {
        t->w0 = msid_now_ns();
        rc = write_spans(m);
        t->w1 = t->r0 = msid_now_ns();
        if (rc < 0) return rc;
        rc = read_spans(m, UINT32_MAX);
        t->r1 = msid_now_ns();
    }
    t->transactions = (uint32_t)m->cnt.requests - before;
    if (rc < 0) return rc;
    decode_all(m, measure);
    return 0;
}

static int write_(void *ctx, const double *drive, msid_devio_times *t)
{
    msid_mb_map *m = ctx;
    int rc = do_write(m, drive);
    if (rc < 0) return rc;
    t->w0 = msid_now_ns();
    rc = write_spans(m);
    t->w1 = msid_now_ns();
    t->transactions = m->n_wspan;
    return rc;
}

static int read_(void *ctx, double *measure, msid_devio_times *t)
{
    msid_mb_map *m = ctx;
    t->r0 = msid_now_ns();
    const int rc = read_spans(m, UINT32_MAX);
    t->r1 = msid_now_ns();
    t->transactions = m->n_rspan;
    if (rc < 0) return rc;
    decode_all(m, measure);
    return 0;
}

static int recover_(void *ctx)
{
    msid_mb_map *m = ctx;
    m->cnt.recoveries++;
    /* a lost connection (an I/O error) is connected again; a timeout or a bad reply only flushes */
    if (m->lost) {
        m->lost = 0;
        const int rc = msid_mb_reconnect(m->tr);
        if (rc < 0) return fail(m, rc, "reconnecting: %s", msid_mb_error(m->tr));
        return 0;
    }
    msid_mb_flush(m->tr);
    return 0;
}

int msid_mb_map_read_span(msid_mb_map *m, uint32_t s, double *measure)
{
    if (s >= m->n_rspan) return fail(m, -MSID_DAQ_E_ARG, "no read span %u", s);
    const msid_mb_span *sp = &m->rspan[s];
    m->cnt.requests++;
    const int rc = sp->table == MSID_DEV_HOLDING ? msid_mb_read_holding(m->tr, sp->addr, sp->n, m->rbuf[s])
                                                  : msid_mb_read_input(m->tr, sp->addr, sp->n, m->rbuf[s]);
    if (rc < 0) return request_failed(m, rc, sp->table == MSID_DEV_HOLDING ? 3 : 4, sp, NULL);
    const msid_devdesc *d = m->desc;
    for (uint32_t i = 0; i < d->n_measure; ++i)
        if (m->rspan_of[i] == s)
            measure[i] = msid_dev_decode(&d->measure[i], &m->rbuf[s][d->measure[i].addr - sp->addr]);
    return 0;
}

static const char *error_(void *ctx) { return ((msid_mb_map *)ctx)->err; }

static const char *describe_(void *ctx)
{
    msid_mb_map *m = ctx;
    char reads[24]; /* "%u read(s)": at most 19 bytes */
    snprintf(reads, sizeof reads, "%u read(s)", m->use_fc23 ? m->n_rspan - 1 : m->n_rspan);
    const char *pre = counter_outside_write(m) ? "the counter's read + " : "";
    if (m->use_fc23)
        snprintf(m->how, sizeof m->how, "%sFC 23 (write and read in one transaction)%s%s", pre,
                 m->n_rspan > 1 ? " + " : "", m->n_rspan > 1 ? reads : "");
    else
        snprintf(m->how, sizeof m->how, "%s%u FC 16 write(s) + %s (FC 03/04)", pre, m->n_wspan, reads);
    return m->how;
}

static const msid_devio_backend MB_MAP = {"modbus", exchange_, write_, read_, recover_, error_, describe_};

int msid_mb_map_init(msid_mb_map *m, const msid_devdesc *d, msid_mb_transport *tr, int fc23)
{
    memset(m, 0, sizeof *m);
    if (!d || !tr || d->transport != MSID_DEV_MODBUS) return fail(m, -MSID_DAQ_E_ARG, "not a Modbus description");
    m->desc = d;
    m->tr = tr;
    m->n_wspan = plan(d->drive, d->n_drive, fc23 ? 121 : 123, m->wspan, m->wspan_of);
    m->n_rspan = plan(d->measure, d->n_measure, 125, m->rspan, m->rspan_of);
    m->use_fc23 = fc23 && msid_mb_map_fc23_possible(m);
    m->counter = -1;
    for (uint32_t i = 0; i < d->n_measure && m->counter < 0; ++i)
        if (d->measure[i].role == MSID_DEV_ROLE_COUNTER) m->counter = (int32_t)i;
    m->io.be = &MB_MAP;
    m->io.ctx = m;
    return 0;
}
