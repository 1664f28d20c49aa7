/* The CAN device session: identify, upload with flow control, START, the DONE loop with QUERY recovery. */
#define _POSIX_C_SOURCE 200809L
#include "msid_daq/msid_can_session.h"

#include <stdio.h>
#include <string.h>
#include <time.h>

static uint32_t def(uint32_t v, uint32_t d) { return v ? v : d; }

static uint64_t now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u;
}

int msid_can_session_init(msid_can_session *s, const msid_can_session_cfg *c)
{
    if (!s || !c || !c->tr || !c->tr->be || c->base % 0x80u || c->base > 0x780u) return -MSID_DAQ_E_ARG;
    memset(s, 0, sizeof *s);
    s->cfg = *c;
    s->cfg.send_timeout_ms = def(c->send_timeout_ms, 2000);
    s->cfg.reply_timeout_ms = def(c->reply_timeout_ms, 5000);
    s->cfg.silence_ms = def(c->silence_ms, 10000);
    s->cfg.query_ms = def(c->query_ms, s->cfg.silence_ms / 4 ? s->cfg.silence_ms / 4 : 1);
    s->cfg.upload_block = def(c->upload_block, 16);
    return 0;
}

static int hook(msid_can_session *s, const msid_can_frame *f)
{
    if (s->cfg.on_frame && s->cfg.on_frame(s->cfg.user, f) != 0) {
        snprintf(s->err, sizeof s->err, "the frame hook failed");
        return -MSID_DAQ_E_HOOK;
    }
    return 0;
}

/* One CTRL or CFG frame to the device (through the hook, flagged as sent). */
static int send8(msid_can_session *s, uint32_t off, const uint8_t *d)
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = s->cfg.base + off;
    f.len = 8;
    memcpy(f.data, d, 8);
    const int r = msid_can_send(s->cfg.tr, &f, (int)s->cfg.send_timeout_ms);
    if (r < 0) {
        snprintf(s->err, sizeof s->err, "cannot send on the CAN bus: %s", msid_can_error(s->cfg.tr));
        return r;
    }
    s->cnt.frames_sent++;
    f.flags |= MSID_CANF_TX;
    return hook(s, &f);
}

static int send_ctrl(msid_can_session *s, uint32_t cmd, uint32_t e, uint32_t periods)
{
    uint8_t d[8];
    msid_can_encode_ctrl(d, cmd, e, periods);
    if (cmd == MSID_CAN_CMD_QUERY) s->cnt.queries++;
    return send8(s, MSID_CAN_ID_CTRL, d);
}

static int core_refused(msid_can_session *s, msid_status st)
{
    if (st == MSID_E_CAPACITY)
        snprintf(s->err, sizeof s->err, "more periods arrived than the measurement holds (device restarted too often?)");
    else
        snprintf(s->err, sizeof s->err, "decoder: %s", msid_strerror(st));
    return msid_daq_core(st);
}

/* A received frame: hook, device status, then the decoder (or the early buffer before attach). */
static int take(msid_can_session *s, const msid_can_frame *f)
{
    int r = hook(s, f);
    if (r < 0) return r;
    if (f->id == s->cfg.base + MSID_CAN_ID_STATUS && f->len == 8 && !(f->flags & MSID_CANF_FD))
        msid_can_device_update(&s->dev, f->data);
    if (s->dec) {
        const msid_status st = msid_can_decoder_feed(s->dec, f);
        return st == MSID_OK ? 0 : core_refused(s, st);
    }
    if (s->n_early < MSID_CAN_SESSION_EARLY) s->early[s->n_early++] = *f;
    else s->cnt.early_dropped++;
    return 0;
}

/* Receive one batch (at most wait_ms) and take every frame. Returns frames taken, 0 on a timeout, or < 0. */
static int pump(msid_can_session *s, int wait_ms)
{
    const int k = msid_can_recv(s->cfg.tr, s->rx, (int)(sizeof s->rx / sizeof s->rx[0]), wait_ms);
    if (k == -MSID_DAQ_E_TIMEOUT) return 0;
    if (k < 0) {
        snprintf(s->err, sizeof s->err, "CAN receive: %s", msid_can_error(s->cfg.tr));
        return k;
    }
    for (int i = 0; i < k; ++i) {   /* the whole batch is taken, even after an awaited frame */
        const int r = take(s, &s->rx[i]);
        if (r < 0) return r;
    }
    return k;
}

enum { WAIT_INFO, WAIT_STATE, WAIT_CONFIRM };

static int waited(const msid_can_session *s, int what)
{
    const msid_can_device *v = &s->dev;
    switch (what) {
    case WAIT_INFO: return v->have_info;
    case WAIT_STATE: return v->have_state;
    default: return v->have_state && (v->state == MSID_CAN_STATE_CONFIGURED || v->state == MSID_CAN_STATE_ERROR);
    }
}

/* Frames until `what` holds after a batch: 1, 0 after timeout_ms, or < 0. */
static int wait_for(msid_can_session *s, int what, uint32_t timeout_ms)
{
    const uint64_t t0 = now_ms();
    do {   /* at least one receive, however late this process was scheduled */
        const int k = pump(s, 50);
        if (k < 0) return k;
        if (k > 0 && waited(s, what)) return 1;
    } while (now_ms() - t0 <= timeout_ms);
    return 0;
}

int msid_can_session_identify(msid_can_session *s, uint32_t timeout_ms)
{
    int r = send_ctrl(s, MSID_CAN_CMD_QUERY, 0, 0);
    if (r < 0) return r;
    if ((r = wait_for(s, WAIT_INFO, timeout_ms)) < 0) return r;
    if (r == 0) {
        snprintf(s->err, sizeof s->err, "no msid-can device answered at base 0x%X within %g s", s->cfg.base,
                 (double)timeout_ms / 1000.0);
        return -MSID_DAQ_E_TIMEOUT;
    }
    if (s->dev.version != MSID_CAN_PROTO_VERSION) {
        snprintf(s->err, sizeof s->err, "protocol version mismatch: the device speaks msid-can/%u, this host msid-can/%u",
                 s->dev.version, MSID_CAN_PROTO_VERSION);
        return -MSID_DAQ_E_PROTOCOL;
    }
    return 0;
}

int msid_can_session_attach(msid_can_session *s, msid_can_decoder *dec)
{
    if (!s || !dec) return -MSID_DAQ_E_ARG;
    s->dec = dec;
    for (uint32_t i = 0; i < s->n_early; ++i) {
        const msid_status st = msid_can_decoder_feed(dec, &s->early[i]);
        if (st != MSID_OK) return core_refused(s, st);
    }
    s->n_early = 0;
    return 0;
}

/* The device's refusal of a configuration, decoded. */
static int refused(msid_can_session *s)
{
    const msid_can_device *v = &s->dev;
    if (v->error == MSID_CAN_ERR_VERSION) {
        snprintf(s->err, sizeof s->err, "protocol version mismatch: the device refused msid-can/%u (it speaks msid-can/%u)",
                 MSID_CAN_PROTO_VERSION, v->version);
        return -MSID_DAQ_E_PROTOCOL;
    }
    if (v->error == MSID_CAN_ERR_DESIGN)
        snprintf(s->err, sizeof s->err, "the device refused the configuration: %s (%s)",
                 msid_can_device_error_name(v->error), msid_strerror((msid_status)v->value));
    else
        snprintf(s->err, sizeof s->err, "the device refused the configuration: %s", msid_can_device_error_name(v->error));
    return -MSID_DAQ_E_DEVICE;
}

int msid_can_session_upload(msid_can_session *s, const uint8_t (*rec)[8], size_t n)
{
    if (!s || !rec || n < 2) return -MSID_DAQ_E_ARG;
    const uint32_t crc = msid_can_get_u32(rec[n - 1] + 4);
    const size_t block = s->cfg.upload_block;
    int r;
    for (size_t i = 0; i < n; ++i) {
        /* flow control: before every block (and the COMMIT) a QUERY, and the device's answer */
        if (i == n - 1 || (i > 0 && i % block == 0)) {
            s->dev.have_state = 0;
            if ((r = send_ctrl(s, MSID_CAN_CMD_QUERY, 0, 0)) < 0) return r;
            if ((r = wait_for(s, WAIT_STATE, s->cfg.reply_timeout_ms)) < 0) return r;
            if (r == 0) {
                snprintf(s->err, sizeof s->err, "the device stopped answering during the design upload (after %zu of "
                         "%zu frames)", i, n);
                return -MSID_DAQ_E_TIMEOUT;
            }
            if (s->dev.state == MSID_CAN_STATE_ERROR) return refused(s);
        }
        if (i == n - 1) s->dev.have_state = 0;
        if ((r = send8(s, MSID_CAN_ID_CFG, rec[i])) < 0) return r;
    }
    if ((r = wait_for(s, WAIT_CONFIRM, s->cfg.reply_timeout_ms)) < 0) return r;
    if (r == 0) {
        snprintf(s->err, sizeof s->err, "the device did not confirm the configuration within %g s",
                 (double)s->cfg.reply_timeout_ms / 1000.0);
        return -MSID_DAQ_E_TIMEOUT;
    }
    if (s->dev.state == MSID_CAN_STATE_ERROR) return refused(s);
    if (s->dev.cfg_crc != crc) {
        snprintf(s->err, sizeof s->err, "the device confirmed configuration CRC %08X, the host sent %08X",
                 s->dev.cfg_crc, crc);
        return -MSID_DAQ_E_PROTOCOL;
    }
    s->crc = crc;
    return 0;
}

/* Frames that are not STATUS frames: the device is streaming (or the bus is talking). */
static uint64_t activity(const msid_can_decoder *d) { return d->cnt.frames - d->cnt.status_frames; }

/* The caller asked to stop: close the experiment in the decoder where it stands, STOP the device. */
static int stop_run(msid_can_session *s, uint32_t e)
{
    const msid_status st = msid_can_decoder_abort(s->dec);
    if (st != MSID_OK) return core_refused(s, st);
    (void)send_ctrl(s, MSID_CAN_CMD_STOP, e, 0);   /* best effort: the device may be gone */
    snprintf(s->err, sizeof s->err, "experiment %u stopped at the caller's request", e + 1);
    return -MSID_DAQ_E_STOPPED;
}

int msid_can_session_run(msid_can_session *s, uint32_t e, uint32_t periods)
{
    if (!s || !s->dec) return -MSID_DAQ_E_ARG;
    msid_can_decoder *d = s->dec;
    const uint64_t done_before = d->cnt.experiments_done;
    int r = send_ctrl(s, MSID_CAN_CMD_START, e, periods);
    if (r < 0) return r;
    uint64_t last = now_ms(), last_query = 0, seen = activity(d);
    int querying = 0;   /* a recovery QUERY is outstanding since the last activity */
    while (d->cnt.experiments_done == done_before) {
        const int k = pump(s, 100);
        if (s->cfg.on_poll && s->cfg.on_poll(s->cfg.poll_user)) return stop_run(s, e);
        if (k < 0) return k;
        const uint64_t t = now_ms();
        if (k > 0 && d->dev.have_state && d->dev.state == MSID_CAN_STATE_ERROR) {
            snprintf(s->err, sizeof s->err, "the device reported an error during experiment %u: %s", e + 1,
                     msid_can_device_error_name(d->dev.error));
            return -MSID_DAQ_E_DEVICE;
        }
        if (activity(d) != seen) {
            seen = activity(d);
            last = t;
            querying = 0;
        }
        if (d->cnt.experiments_done != done_before) {
            if (querying) s->cnt.done_recovered++;
            break;
        }
        if (t - last > s->cfg.silence_ms) {
            snprintf(s->err, sizeof s->err, "the device went silent for %g s during experiment %u",
                     (double)s->cfg.silence_ms / 1000.0, e + 1);
            return -MSID_DAQ_E_TIMEOUT;
        }
        /* quiet: a DONE frame may have been lost (the host stalled, the queue overflowed); ask */
        if (t - last >= s->cfg.query_ms && t - last_query >= s->cfg.query_ms) {
            if ((r = send_ctrl(s, MSID_CAN_CMD_QUERY, 0, 0)) < 0) return r;
            s->cnt.recovery_queries++;
            last_query = t;
            querying = 1;
        }
    }
    return 0;
}
