/* A CANopen drive's tick: RPDO + SYNC out, the TPDOs of that SYNC in (msid_co_map.h). */
#include "msid_daq/msid_co_map.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "msid_daq/msid_tick.h"

static int failv(msid_co_map *m, int rc, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(m->err, sizeof m->err, fmt, ap);
    va_end(ap);
    return rc;
}

/* The channel as a big-endian register value of its own type (ABCD), so that msid_dev_encode's range and
 * rounding rules are the ones every transport uses; CANopen puts the bytes on the bus the other way round. */
int msid_co_map_encode(const msid_dev_chan *c, double v, uint8_t *bytes)
{
    msid_dev_chan abcd = *c;
    abcd.word_order = 0;   /* MSID_MB_ABCD */
    uint16_t r[2] = {0, 0};
    if (msid_dev_encode(&abcd, v, r) != 0) return -1;
    const unsigned n = msid_dev_co_bytes(c);
    uint8_t be[4] = {(uint8_t)(r[0] >> 8), (uint8_t)r[0], (uint8_t)(r[1] >> 8), (uint8_t)r[1]};
    for (unsigned i = 0; i < n; ++i) bytes[i] = be[n - 1 - i];
    return 0;
}

double msid_co_map_decode(const msid_dev_chan *c, const uint8_t *bytes)
{
    msid_dev_chan abcd = *c;
    abcd.word_order = 0;
    const unsigned n = msid_dev_co_bytes(c);
    uint8_t be[4] = {0, 0, 0, 0};
    for (unsigned i = 0; i < n; ++i) be[i] = bytes[n - 1 - i];
    const uint16_t r[2] = {(uint16_t)(be[0] << 8 | be[1]), (uint16_t)(be[2] << 8 | be[3])};
    return msid_dev_decode(&abcd, r);
}

/* A frame that is not a TPDO of the tick: EMCY, heartbeat. Sets m->fatal for a way out. */
static void watch(msid_co_map *m, const msid_can_frame *f, uint64_t now_ms)
{
    msid_co_emcy e;
    const int em = msid_co_emcy_decode(f, m->node, &e);
    if (em == 1) {
        m->cnt.emcy++;
        if (e.code != 0 && !m->fatal[0]) {
            m->last_emcy = e;
            char line[200];
            msid_co_emcy_describe(&e, line, sizeof line);
            snprintf(m->fatal, sizeof m->fatal, "%s", line);
        }
        return;
    }
    const int hb = m->hb.time_ms ? msid_co_hb_frame(&m->hb, f, now_ms) : 0;
    const int is_hb = hb == 1 || (!m->hb.time_ms && f->id == MSID_CO_COB_HEARTBEAT + m->node && f->len == 1);
    if (is_hb) {
        m->cnt.heartbeats++;
        const unsigned st = f->data[0] & 0x7Fu;
        if (m->operational && st != MSID_CO_STATE_OPERATIONAL && !m->fatal[0])
            snprintf(m->fatal, sizeof m->fatal, "node %u left operational: its heartbeat says %s", (unsigned)m->node,
                     msid_co_state_name(st));
    }
}

/* Which TPDO a frame is (0, 1), or -1. */
static int tpdo_index(const msid_co_map *m, const msid_can_frame *f)
{
    if (f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) return -1;
    for (uint32_t k = 0; k < m->n_tpdo; ++k)
        if (f->id == MSID_CO_COB_TPDO1 + 0x100u * k + m->node) return (int)k;
    return -1;
}

void msid_co_map_offer(msid_co_map *m, const msid_can_frame *f, uint64_t now_ms)
{
    if (tpdo_index(m, f) >= 0) m->cnt.late++;
    else if (f->id != MSID_CO_COB_SYNC) watch(m, f, now_ms);
}

static uint64_t ms_of(int64_t ns) { return (uint64_t)(ns / 1000000); }

/* The heartbeat consumer's verdict now. */
static void check_heartbeat(msid_co_map *m, int64_t now)
{
    if (m->hb.time_ms && !m->fatal[0] && msid_co_hb_check(&m->hb, ms_of(now)) == MSID_CO_HB_LOST)
        snprintf(m->fatal, sizeof m->fatal, "node %u's heartbeat was lost: none for %u ms (heartbeat_ms)",
                 (unsigned)m->node, (unsigned)m->hb.time_ms);
}

/* One frame of the queue, in bus order: the echo of msid's own SYNC opens the answers to it; a TPDO before
 * it answers an older SYNC (late). Behind it, a TPDO answers that SYNC, unless the previous SYNC's answer of
 * that PDO was still owed when it was sent: a node that answers in order then sends the late one first (it
 * is dropped, and the sample whose answer it could be taken for is lost, never misplaced); a second one of
 * the same PDO replaces the first. */
static uint32_t all_tpdos(const msid_co_map *m) { return (1u << m->n_tpdo) - 1u; }

/* kernel_sync: the echo of the kernel's SYNC closes the last SYNC's window and opens this one's; an answer of
 * the last SYNC not in by now is owed (once, as for a SYNC the tick sent). */
static void take_kernel_echo(msid_co_map *m, const msid_can_frame *f)
{
    if (m->echoes) m->owed = (all_tpdos(m) & ~m->got) & ~m->owed_taken;
    m->owed_taken = 0;
    m->got = 0;
    m->echoes++;
    m->cnt.syncs++;
    m->echo_ns = f->t_ns;
    m->unechoed_since = 0;
}

static void take(msid_co_map *m, const msid_can_frame *f)
{
    if (f->id == MSID_CO_COB_SYNC && !(f->id & MSID_CAN_ERR_FLAG)) {
        if (m->kernel_sync) {
            take_kernel_echo(m, f);
            return;
        }
        if (m->echo_due) m->echo_due--;
        if (!m->echo_due) m->echo_ns = f->t_ns;
        return;
    }
    const int k = tpdo_index(m, f);
    if (k < 0) {
        watch(m, f, ms_of(msid_now_ns()));
        return;
    }
    const uint32_t bit = 1u << k;
    if (m->echo_due || (m->kernel_sync && !m->echoes)) {   /* an older SYNC's: the owed answer came before this SYNC */
        m->cnt.late++;
        m->owed &= ~bit;
        return;
    }
    if (m->owed & bit) {   /* the first behind the echo is the owed late answer */
        m->cnt.late++;
        m->owed &= ~bit;
        m->owed_taken |= bit;
        return;
    }
    if (f->len != m->tpdo_len[k]) { m->cnt.bad_tpdos++; return; }
    if (m->got & bit) m->cnt.late++;
    memcpy(m->buf[k], f->data, f->len);
    m->got |= bit;
    if (f->t_ns && m->echo_ns && f->t_ns >= m->echo_ns) {
        const double lat = 1e-9 * (double)(f->t_ns - m->echo_ns);
        m->cnt.latency_sum_s += lat;
        m->cnt.latency_n++;
        if (lat > m->cnt.latency_max_s) m->cnt.latency_max_s = lat;
    }
}

/* The last SYNC's answers are all in (or no SYNC was sent yet). */
static int complete(const msid_co_map *m)
{
    if (m->kernel_sync) return m->echoes && m->got == all_tpdos(m);
    return !m->syncs_sent || (!m->echo_due && m->got == all_tpdos(m));
}

/* Every frame already waiting, in order (msid_can_recv does not block with 0); then, while the last SYNC's
 * answers are not complete, frames as they come for at most wait_ns. */
static int collect(msid_co_map *m, int64_t wait_ns)
{
    msid_can_frame fr[16];
    const int64_t deadline = msid_now_ns() + wait_ns;
    for (int round = 0; round < 64; ++round) {   /* a bounded drain: a busy bus cannot hold the tick */
        const int n = msid_can_recv(m->t, fr, 16, 0);
        if (n == -MSID_DAQ_E_TIMEOUT) break;
        if (n < 0) return failv(m, n, "node %u: receive: %s", (unsigned)m->node, msid_can_error(m->t));
        for (int i = 0; i < n; ++i) take(m, &fr[i]);
    }
    while (!complete(m)) {
        const int64_t left = deadline - msid_now_ns();
        if (left <= 0) break;
        const int n = msid_can_recv(m->t, fr, 16, (int)((left + 999999) / 1000000));
        if (n == -MSID_DAQ_E_TIMEOUT) continue;
        if (n < 0) return failv(m, n, "node %u: receive: %s", (unsigned)m->node, msid_can_error(m->t));
        for (int i = 0; i < n; ++i) take(m, &fr[i]);
    }
    return 0;
}

/* RPDO1 with the drive values. */
static int rpdo_of(msid_co_map *m, const double *drive, msid_can_frame *rp)
{
    const msid_devdesc *d = m->d;
    memset(rp, 0, sizeof *rp);
    rp->id = MSID_CO_COB_RPDO1 + m->node;
    rp->len = m->rpdo_len;
    for (uint32_t i = 0; i < d->n_drive; ++i)
        if (msid_co_map_encode(&d->drive[i], drive[i], rp->data + m->rpdo_off[i]) != 0)
            return failv(m, -MSID_DAQ_E_ARG, "'%s' = %g does not fit object 0x%04X:%02X (%s)", d->drive[i].name,
                         drive[i], d->drive[i].co_index, d->drive[i].co_sub, msid_dev_type_name(d->drive[i].type));
    return 0;
}

/* One tick: the TPDOs of the previous tick's SYNC into `measure` (need_tpdo), then the RPDO of `drive` and
 * this tick's SYNC. A tick's samples are read one tick later, so the node has a whole tick to answer; the
 * demand and the actual values come from one TPDO set, so the FRF does not see the shift. */
static int tick(msid_co_map *m, const double *drive, double *measure, msid_devio_times *t, int need_tpdo)
{
    const msid_devdesc *d = m->d;
    int rc = collect(m, need_tpdo ? m->wait_ns : 0);
    if (rc < 0) return rc;
    check_heartbeat(m, msid_now_ns());
    /* after a way out was found only writes go on: the safe values still go to the node */
    if (m->fatal[0] && need_tpdo) return failv(m, -MSID_DAQ_E_DEVICE, "%s", m->fatal);
    if (m->echo_due > 3)
        return failv(m, -MSID_DAQ_E_IO, "node %u: msid's own SYNC frames do not come back from the bus (the socket "
                     "receives its own frames: is loopback off on %s?)", (unsigned)m->node, "the interface");
    msid_can_frame rp, sy;
    if ((rc = rpdo_of(m, drive, &rp)) < 0) return rc;
    /* the previous SYNC's answers, complete or not: this tick's SYNC opens new ones */
    const uint32_t want = all_tpdos(m);
    const int have = m->syncs_sent > 0 && m->echo_due == 0 && m->got == want;
    if (have)
        for (uint32_t i = 0; i < d->n_measure; ++i)
            m->value[i] = msid_co_map_decode(&d->measure[i], m->buf[m->tpdo_of[i]] + m->tpdo_off[i]);
    const uint32_t missing = want & ~(m->echo_due ? 0u : m->got);
    /* what the new SYNC's window owes first: an answer of the last SYNC not in yet (once: a window that took
       an owed answer and got none of its own owes nothing, so a node that dropped a TPDO is followed again) */
    m->owed = m->syncs_sent ? missing & ~m->owed_taken : 0;
    m->owed_taken = 0;
    m->got = 0;
    msid_co_sync_frame(&sy, 0);
    t->w0 = msid_now_ns();
    if ((rc = msid_can_send(m->t, &rp, m->send_timeout_ms)) < 0 ||
        ((void)m->cnt.rpdos++, (rc = msid_can_send(m->t, &sy, m->send_timeout_ms)) < 0)) {
        m->cnt.send_failures++;
        return failv(m, rc, "node %u: send: %s", (unsigned)m->node, msid_can_error(m->t));
    }
    t->w1 = msid_now_ns();
    t->transactions = 2;
    m->cnt.syncs++;
    m->syncs_sent++;
    m->echo_due++;
    if (!need_tpdo) return 0;
    if (!have) {
        m->cnt.lost++;
        return failv(m, -MSID_DAQ_E_TIMEOUT, "node %u: TPDO%s of the previous SYNC not received within the tick",
                     (unsigned)m->node, missing == 1u ? "1" : missing == 2u ? "2" : "1 and TPDO2");
    }
    m->cnt.tpdos += m->n_tpdo;
    if (measure) memcpy(measure, m->value, sizeof(double) * d->n_measure);
    m->err[0] = 0;
    return 0;
}

/* One tick on the kernel's SYNC (kernel_sync): the RPDO (taken by the next SYNC), then the answers of the last
 * SYNC the bus carried and its count. The count read before the RPDO goes out is counter_before: a SYNC between
 * the two may or may not have taken the write, and the tick loop marks that SYNC. */
static int tick_kernel(msid_co_map *m, const double *drive, double *measure, msid_devio_times *t, int need_tpdo)
{
    const msid_devdesc *d = m->d;
    int rc = collect(m, 0);
    if (rc < 0) return rc;
    check_heartbeat(m, msid_now_ns());
    if (m->fatal[0] && need_tpdo) return failv(m, -MSID_DAQ_E_DEVICE, "%s", m->fatal);
    if (m->unechoed_since && msid_now_ns() - m->unechoed_since > MSID_CO_MAP_ECHO_PERIODS * m->period_ns)
        return failv(m, -MSID_DAQ_E_IO, "node %u: no SYNC of the kernel's timer came back from the bus in %d periods "
                     "(is the SYNC producer running, and loopback on?)", (unsigned)m->node, MSID_CO_MAP_ECHO_PERIODS);
    msid_can_frame rp;
    if ((rc = rpdo_of(m, drive, &rp)) < 0) return rc;
    t->counter_before = (double)(uint32_t)m->echoes;
    t->has_counter_before = 1;
    t->w0 = msid_now_ns();
    if ((rc = msid_can_send(m->t, &rp, m->send_timeout_ms)) < 0) {
        m->cnt.send_failures++;
        return failv(m, rc, "node %u: send: %s", (unsigned)m->node, msid_can_error(m->t));
    }
    t->w1 = msid_now_ns();
    t->transactions = 1;
    m->cnt.rpdos++;
    if (!m->unechoed_since) m->unechoed_since = t->w1;
    if (!need_tpdo) return 0;
    t->r0 = t->w1;
    if ((rc = collect(m, m->wait_ns)) < 0) return rc;
    t->r1 = msid_now_ns();
    if (!complete(m)) {
        m->cnt.lost++;
        const uint32_t missing = all_tpdos(m) & ~m->got;
        return failv(m, -MSID_DAQ_E_TIMEOUT, "node %u: TPDO%s of SYNC %llu not received within %.3g ms", (unsigned)m->node,
                     missing == 1u ? "1" : missing == 2u ? "2" : "1 and TPDO2", (unsigned long long)m->echoes,
                     1e-6 * (double)m->wait_ns);
    }
    for (uint32_t i = 0; i < d->n_measure; ++i)
        m->value[i] = msid_co_map_decode(&d->measure[i], m->buf[m->tpdo_of[i]] + m->tpdo_off[i]);
    m->value[m->sync_ch] = (double)(uint32_t)m->echoes;
    if (m->echo_ns) {   /* the SYNC's receive time is CLOCK_REALTIME: the write's time since it, on that clock */
        const int64_t since = msid_realtime_ns() - (int64_t)m->echo_ns - (msid_now_ns() - t->w0);
        if (since >= 0) {
            t->phase_ns = since;
            t->has_phase = 1;
        }
    }
    m->cnt.tpdos += m->n_tpdo;
    if (measure) memcpy(measure, m->value, sizeof(double) * (d->n_measure + 1u));
    m->err[0] = 0;
    return 0;
}

static int be_exchange(void *ctx, const double *drive, double *measure, msid_devio_times *t)
{
    msid_co_map *m = ctx;
    return m->kernel_sync ? tick_kernel(m, drive, measure, t, 1) : tick(m, drive, measure, t, 1);
}

/* Ramps and the safe values: the node applies them on the SYNC; their TPDOs are taken, not required. */
static int be_write(void *ctx, const double *drive, msid_devio_times *t)
{
    msid_co_map *m = ctx;
    return m->kernel_sync ? tick_kernel(m, drive, NULL, t, 0) : tick(m, drive, NULL, t, 0);
}

static int be_read(void *ctx, double *measure, msid_devio_times *t)
{
    msid_co_map *m = ctx;
    (void)t;
    memcpy(measure, m->value, sizeof(double) * m->d->n_measure);
    return 0;
}

static int be_recover(void *ctx) { return collect(ctx, 0); }

static const char *be_error(void *ctx) { return ((msid_co_map *)ctx)->err; }

static const char *be_describe(void *ctx) { return ((msid_co_map *)ctx)->describe; }

static const msid_devio_backend BACKEND = {"canopen", be_exchange, be_write, be_read, be_recover, be_error, be_describe};

int msid_co_map_init(msid_co_map *m, const msid_devdesc *d, unsigned node, unsigned heartbeat_ms,
                     const msid_can_transport *t)
{
    if (!m) return -MSID_DAQ_E_ARG;
    memset(m, 0, sizeof *m);
    if (!d || !t || d->transport != MSID_DEV_CANOPEN) return failv(m, -MSID_DAQ_E_ARG, "not a CANopen description");
    if (!msid_co_node_valid(node)) return failv(m, -MSID_DAQ_E_ARG, "node id %u is outside 1..127", node);
    m->d = d;
    m->t = t;
    m->node = (uint8_t)node;
    m->send_timeout_ms = 100;
    unsigned off = 0;
    for (uint32_t i = 0; i < d->n_drive; ++i) {
        m->rpdo_off[i] = (uint8_t)off;
        off += msid_dev_co_bytes(&d->drive[i]);
    }
    if (off > 8) return failv(m, -MSID_DAQ_E_ARG, "the drive channels map %u bytes: an RPDO carries 8", off);
    m->rpdo_len = (uint8_t)off;
    m->n_tpdo = msid_devdesc_co_pack(d, m->tpdo_of);
    if (!m->n_tpdo) return failv(m, -MSID_DAQ_E_ARG, "the measure channels do not fit in two TPDOs");
    for (uint32_t i = 0; i < d->n_measure; ++i) {
        const uint8_t k = m->tpdo_of[i];
        m->tpdo_off[i] = m->tpdo_len[k];
        m->tpdo_len[k] = (uint8_t)(m->tpdo_len[k] + msid_dev_co_bytes(&d->measure[i]));
    }
    if (heartbeat_ms && msid_co_hb_init(&m->hb, node, heartbeat_ms) < 0)
        return failv(m, -MSID_DAQ_E_ARG, "heartbeat_ms %u is outside 1..65535", heartbeat_ms);
    for (uint32_t i = 0; i < MSID_DEV_MAX_MEASURE; ++i) m->value[i] = NAN;
    if (m->n_tpdo == 1)
        snprintf(m->describe, sizeof m->describe, "RPDO1 (%u bytes) + SYNC + TPDO1 (%u bytes)", m->rpdo_len,
                 m->tpdo_len[0]);
    else
        snprintf(m->describe, sizeof m->describe, "RPDO1 (%u bytes) + SYNC + TPDO1 (%u bytes) + TPDO2 (%u bytes)",
                 m->rpdo_len, m->tpdo_len[0], m->tpdo_len[1]);
    m->io.be = &BACKEND;
    m->io.ctx = m;
    return 0;
}

void msid_co_map_kernel_sync(msid_co_map *m, uint32_t period_us)
{
    m->kernel_sync = 1;
    m->period_ns = 1000 * (int64_t)(period_us ? period_us : 1);
    m->sync_ch = (int32_t)m->d->n_measure;
    m->value[m->sync_ch] = NAN;
    const int n = snprintf(m->describe, sizeof m->describe, "RPDO1 (%u bytes), the kernel's SYNC, TPDO1 (%u bytes)",
                           m->rpdo_len, m->tpdo_len[0]);
    if (m->n_tpdo == 2 && n > 0 && (size_t)n < sizeof m->describe)
        snprintf(m->describe + n, sizeof m->describe - (size_t)n, " + TPDO2 (%u bytes)", m->tpdo_len[1]);
}

static void fill_map(msid_co_pdo_cfg *c, const msid_dev_chan *ch)
{
    msid_co_pdo_entry *e = &c->e[c->n++];
    e->index = ch->co_index;
    e->sub = ch->co_sub;
    e->bits = (uint8_t)(8u * msid_dev_co_bytes(ch));
}

void msid_co_map_pdos(const msid_co_map *m, msid_co_pdo_cfg *rpdo, msid_co_pdo_cfg *tpdo)
{
    const msid_devdesc *d = m->d;
    memset(rpdo, 0, sizeof *rpdo);
    rpdo->tx = 0;
    rpdo->num = 1;
    rpdo->trans_type = MSID_CO_PDO_SYNC_EVERY;
    for (uint32_t i = 0; i < d->n_drive; ++i) fill_map(rpdo, &d->drive[i]);
    for (uint32_t k = 0; k < m->n_tpdo; ++k) {
        memset(&tpdo[k], 0, sizeof tpdo[k]);
        tpdo[k].tx = 1;
        tpdo[k].num = (uint16_t)(k + 1);
        tpdo[k].trans_type = MSID_CO_PDO_SYNC_EVERY;
    }
    for (uint32_t i = 0; i < d->n_measure; ++i) fill_map(&tpdo[m->tpdo_of[i]], &d->measure[i]);
}
