/* The CAN map as a tick-loop backend (msid_can_map.h): each exchange takes the status frames that arrived since
 * the previous one, waiting a bounded time for a fresh frame of every measure channel, then sends the command
 * frames; a channel with no fresh frame is a missing sample, never a held value. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "can_map_internal.h"
#include "msid_daq/msid_tick.h"

#define fail msid_can_map_fail

/* The monotonic instant of a frame: its kernel receive stamp (CLOCK_REALTIME) moved onto the monotonic clock,
 * else the instant it was read. */
static int64_t arrival_ns(const msid_can_frame *f, int64_t mono_now, int64_t real_minus_mono)
{
    if (!f->t_ns) return mono_now;
    const int64_t t = (int64_t)f->t_ns - real_minus_mono;
    return t < mono_now ? t : mono_now;
}

static int64_t real_minus_mono(void)
{
    struct timespec r;
    clock_gettime(CLOCK_REALTIME, &r);
    return (int64_t)r.tv_sec * 1000000000LL + r.tv_nsec - msid_now_ns();
}

static int all_fresh(const msid_can_map *m)
{
    for (uint32_t i = 0; i < m->desc->n_measure; ++i)
        if (!m->fresh[i]) return 0;
    return 1;
}

/* The channels without a fresh frame, named (at most three). */
static void stale_names(const msid_can_map *m, char *out, size_t cap)
{
    size_t len = 0;
    uint32_t n = 0;
    out[0] = 0;
    for (uint32_t i = 0; i < m->desc->n_measure && len < cap; ++i) {
        if (m->fresh[i]) continue;
        if (n++ == 3) {
            snprintf(out + len, cap - len, ", ...");
            return;
        }
        const msid_dbc_message *msg = m->st[m->st_of[i]].m;
        len += (size_t)snprintf(out + len, cap - len, "%s'%s' (%s, 0x%X)", n > 1 ? ", " : "", m->desc->measure[i].name,
                                msg->name, msg->id & 0x1FFFFFFFu);
    }
}

/* Take what the bus holds, waiting until every channel is fresh or wait_ns has passed; then what is queued still
 * (the newest frame of each message is the sample). */
static int collect(msid_can_map *m, int64_t wait_ns)
{
    msid_can_frame f[16];
    const int64_t end = msid_now_ns() + wait_ns;
    const int64_t off = real_minus_mono();
    for (;;) {
        const int64_t now = msid_now_ns();
        int tmo = 0;
        if (!all_fresh(m) && end > now) tmo = (int)((end - now) / 1000000);   /* whole ms: never past the end */
        const int n = msid_can_recv(m->tr, f, 16, tmo);
        if (n == -MSID_DAQ_E_TIMEOUT) {
            if (all_fresh(m) || msid_now_ns() >= end) return 0;
            continue;
        }
        if (n < 0) return fail(m, n, "receiving the status frames: %s", msid_can_error(m->tr));
        const int64_t t = msid_now_ns();
        for (int k = 0; k < n; ++k) msid_can_map_take(m, &f[k], arrival_ns(&f[k], t, off));
    }
}

static int send_all(msid_can_map *m)
{
    for (uint32_t k = 0; k < m->n_cmd; ++k) {
        msid_can_frame f;
        memset(&f, 0, sizeof f);
        f.id = m->cmd[k].m->id;
        f.len = (uint8_t)m->cmd[k].m->dlc;
        if (f.len > 8) f.flags = MSID_CANF_FD;
        memcpy(f.data, m->cmd[k].data, f.len);
        const int rc = msid_can_send(m->tr, &f, m->send_timeout_ms);
        if (rc < 0) {
            m->cnt.send_failures++;
            return fail(m, rc, "sending '%s' (0x%X): %s", m->cmd[k].m->name, f.id & 0x1FFFFFFFu, msid_can_error(m->tr));
        }
        m->cmd[k].frames++;
        m->cnt.frames_sent++;
    }
    return 0;
}

/* After a collection: the sample, or a missing one when a channel had no fresh frame. */
static int sample(msid_can_map *m, double *measure, msid_devio_times *t)
{
    t->r0 = t->r1 = m->newest_ns;
    if (!all_fresh(m)) {
        char names[240];
        stale_names(m, names, sizeof names);
        m->cnt.stale++;
        memset(m->fresh, 0, sizeof m->fresh);
        return fail(m, -MSID_DAQ_E_TIMEOUT, "no fresh status frame for %s within %.3g ms", names,
                    1e-6 * (double)m->wait_ns);
    }
    memcpy(measure, m->value, m->desc->n_measure * sizeof *measure);
    memset(m->fresh, 0, sizeof m->fresh);
    return 0;
}

static int write_(void *ctx, const double *drive, msid_devio_times *t)
{
    msid_can_map *m = ctx;
    int rc = msid_can_map_pack(m, drive);
    if (rc < 0) return rc;
    t->w0 = msid_now_ns();
    rc = send_all(m);
    t->w1 = msid_now_ns();
    t->transactions = m->n_cmd;
    return rc;
}

/* The status frames first, then the command: the sample is the cycle the device published before this tick's
 * command (as a register read returns the cycle before a write), so that with a counter the write goes to the
 * cycle after the one read. A tick without a fresh frame still sends its command (the excitation goes on) and is
 * a missing sample. */
static int exchange_(void *ctx, const double *drive, double *measure, msid_devio_times *t)
{
    msid_can_map *m = ctx;
    m->cnt.exchanges++;
    int rc = collect(m, m->wait_ns);
    if (rc < 0) return rc;
    const int64_t r = m->newest_ns;
    rc = write_(ctx, drive, t);
    if (rc < 0) return rc;
    t->r0 = t->r1 = r;
    return sample(m, measure, t);
}

static int read_(void *ctx, double *measure, msid_devio_times *t)
{
    msid_can_map *m = ctx;
    memset(m->fresh, 0, sizeof m->fresh);
    const int rc = collect(m, m->read_wait_ns);
    if (rc < 0) return rc;
    const int64_t w = m->wait_ns;
    m->wait_ns = m->read_wait_ns;   /* the message names the wait this read had */
    const int q = sample(m, measure, t);
    m->wait_ns = w;
    return q;
}

/* Nothing to reconnect on a CAN bus. The frames queued since the failure stay: the next collection takes them all
 * and the newest of each message is its sample, which may be the frame that answered this very tick (dropping the
 * queue would lose it, and with a device that answers at once every tick after the first failure would fail). */
static int recover_(void *ctx)
{
    msid_can_map *m = ctx;
    memset(m->fresh, 0, sizeof m->fresh);
    return 0;
}

static const char *error_(void *ctx) { return ((msid_can_map *)ctx)->err; }

static const char *describe_(void *ctx)
{
    msid_can_map *m = ctx;
    size_t len = 0;
    m->how[0] = 0;
    for (uint32_t k = 0; k < m->n_cmd && len < sizeof m->how; ++k)
        len += (size_t)snprintf(m->how + len, sizeof m->how - len, "%sframe %s 0x%X", k ? " + " : "", m->cmd[k].m->name,
                                m->cmd[k].m->id & 0x1FFFFFFFu);
    for (uint32_t k = 0; k < m->n_st && len < sizeof m->how; ++k)
        len += (size_t)snprintf(m->how + len, sizeof m->how - len, " + status %s 0x%X", m->st[k].m->name,
                                m->st[k].m->id & 0x1FFFFFFFu);
    return m->how;
}

static const msid_devio_backend CAN_MAP = {"can", exchange_, write_, read_, recover_, error_, describe_};

void msid_can_map_attach(msid_can_map *m)
{
    m->io.be = &CAN_MAP;
    m->io.ctx = m;
}
