/* The CAN device session: identify, upload with flow control, START, the DONE loop with QUERY recovery. */
#define _POSIX_C_SOURCE 200809L
#include "msid_daq/msid_can_session.h"

#include "msid/msid_status.h"

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

/* A device STATE: DONE closes an experiment without a decoder, a new sample count is progress. */
static void state_seen(msid_can_session *s)
{
    const msid_can_device *v = &s->dev;
    if (v->state == MSID_CAN_STATE_DONE) {
        s->dones++;
        s->done_exp = v->experiment;
    } else if (v->state == MSID_CAN_STATE_RUNNING && v->value != s->last_count) {
        s->progress++;
        s->last_count = v->value;
    }
}

/* An EST frame (extension estimate/1): the estimator's state, or a value of the block being collected. */
static void est_frame(msid_can_session *s, const uint8_t *d)
{
    s->cnt.est_frames++;
    if (msid_can_est_update(&s->est, d) < 0 && s->est_vals) msid_can_est_collect(d, s->est_vals, s->est_got, s->est_n);
}

/* A received frame: hook, device status or estimator, then the decoder (or the early buffer before attach). */
static int take(msid_can_session *s, const msid_can_frame *f)
{
    int r = hook(s, f);
    if (r < 0) return r;
    const int classic8 = f->len == 8 && !(f->flags & MSID_CANF_FD);
    if (f->id == s->cfg.base + MSID_CAN_ID_STATUS && classic8) {
        if (msid_can_device_update(&s->dev, f->data) == MSID_CAN_ST_STATE) state_seen(s);
    } else if (f->id == s->cfg.base + MSID_CAN_ID_EST && classic8) {
        est_frame(s, f->data);
    } else if (f->id & MSID_CAN_ERR_FLAG) {
        s->cnt.error_frames++;
        s->bus = msid_can_bus_state_after(s->bus, f);
    } else {
        s->progress++;
    }
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

enum { WAIT_INFO, WAIT_STATE, WAIT_CONFIRM, WAIT_EST_ANSWER, WAIT_EST_BLOCK };

static int waited(const msid_can_session *s, int what)
{
    const msid_can_device *v = &s->dev;
    const msid_can_est_view *x = &s->est;
    switch (what) {
    case WAIT_INFO: return v->have_info;
    case WAIT_STATE: return v->have_state;
    case WAIT_EST_ANSWER: return x->answers > 0;   /* counters reset by the request */
    /* SOLVE: STATE (not ready: the end), or STATE, SIZE, the values, STATE */
    case WAIT_EST_BLOCK: return x->states >= 2 || (x->states == 1 && x->state != MSID_CAN_EST_STATE_READY);
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

/* With a decoder: frames that are not STATUS frames (the device is streaming, or the bus is talking).
   Without one (estimate only): new sample counts in the device's STATE answers, and other frames. */
static uint64_t activity(const msid_can_session *s)
{
    return s->dec ? s->dec->cnt.frames - s->dec->cnt.status_frames : s->progress;
}

/* Experiments closed: by the decoder, or (estimate only) the device's STATE DONE frames. */
static uint64_t closed(const msid_can_session *s) { return s->dec ? s->dec->cnt.experiments_done : s->dones; }

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
    if (!s) return -MSID_DAQ_E_ARG;
    msid_can_decoder *d = s->dec;
    const msid_can_device *v = d ? &d->dev : &s->dev;
    const uint64_t done_before = closed(s);
    int r = send_ctrl(s, MSID_CAN_CMD_START, e, periods);
    if (r < 0) return r;
    uint64_t last = now_ms(), last_query = 0, seen = activity(s);
    int querying = 0;   /* a recovery QUERY is outstanding since the last activity */
    for (;;) {
        const int k = pump(s, 100);
        if (s->cfg.on_poll && s->cfg.on_poll(s->cfg.poll_user)) return stop_run(s, e);
        if (k < 0) return k;
        const uint64_t t = now_ms();
        if (k > 0 && v->have_state && v->state == MSID_CAN_STATE_ERROR) {
            snprintf(s->err, sizeof s->err, "the device reported an error during experiment %u: %s", e + 1,
                     msid_can_device_error_name(v->error));
            return -MSID_DAQ_E_DEVICE;
        }
        if (activity(s) != seen) {
            seen = activity(s);
            last = t;
            querying = 0;
        }
        if (closed(s) != done_before && (d || s->done_exp == e)) {
            if (querying && d) s->cnt.done_recovered++;
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

/* ---- on-device estimation (extension estimate/1) ---------------------------- */

static int send_est(msid_can_session *s, const uint8_t *d) { return send8(s, MSID_CAN_ID_EST_CTRL, d); }

/* The device's estimator refused or failed: -MSID_DAQ_E_DEVICE with its status in s->err. */
static int est_failed(msid_can_session *s, const char *what)
{
    const msid_can_est_view *x = &s->est;
    const int n = snprintf(s->err, sizeof s->err, "%s: %s (msid_status %u)", what, msid_strerror((msid_status)x->status),
                           x->status);
    if (x->status == MSID_E_MEM_SIZE && n > 0 && (size_t)n < sizeof s->err)
        snprintf(s->err + n, sizeof s->err - (size_t)n, ": its estimator needs %u bytes of working memory, it has %u",
                 x->need, x->have);
    return -MSID_DAQ_E_DEVICE;
}

int msid_can_session_est_setup(msid_can_session *s, uint32_t mode, uint32_t transient, uint32_t skip, double alpha)
{
    if (!s || mode < 1 || mode > 2 || transient > 2 || skip > 0xFFFFu || !(alpha >= 0 && alpha < 1)) return -MSID_DAQ_E_ARG;
    uint64_t b;
    memcpy(&b, &alpha, sizeof b);
    uint8_t d[8];
    int r;
    for (uint32_t w = 0; w < 2; ++w) {   /* the transient test's level, a double in two words */
        memset(d, 0, sizeof d);
        d[0] = MSID_CAN_EST_CMD_ALPHA;
        d[1] = (uint8_t)w;
        msid_can_put_u32(d + 4, (uint32_t)(b >> (32 * w)));
        if ((r = send_est(s, d)) < 0) return r;
    }
    memset(d, 0, sizeof d);
    d[0] = MSID_CAN_EST_CMD_SETUP;
    d[1] = (uint8_t)mode;
    d[2] = (uint8_t)transient;
    d[4] = (uint8_t)skip;
    d[5] = (uint8_t)(skip >> 8);
    memset(&s->est, 0, sizeof s->est);
    if ((r = send_est(s, d)) < 0) return r;
    if ((r = wait_for(s, WAIT_EST_ANSWER, s->cfg.reply_timeout_ms)) < 0) return r;
    if (r == 0 || s->est.states == 0) {
        snprintf(s->err, sizeof s->err, "the device at base 0x%X does not estimate on board (no answer to the "
                 "estimate/%u SETUP within %g s: msid-can/1 without the extension)", s->cfg.base, MSID_CAN_EST_VERSION,
                 (double)s->cfg.reply_timeout_ms / 1000.0);
        return -MSID_DAQ_E_PROTOCOL;
    }
    if (s->est.version != MSID_CAN_EST_VERSION) {
        snprintf(s->err, sizeof s->err, "the device speaks extension estimate/%u, this host estimate/%u",
                 s->est.version, MSID_CAN_EST_VERSION);
        return -MSID_DAQ_E_PROTOCOL;
    }
    if (s->est.state != MSID_CAN_EST_STATE_ACCUMULATING) return est_failed(s, "the device cannot estimate on board");
    return 0;
}

/* One SOLVE and the device's answer; values go into s->est_vals. 0 ready, or < 0. */
static int solve_once(msid_can_session *s, uint32_t n)
{
    uint8_t d[8] = {MSID_CAN_EST_CMD_SOLVE, 0, 0, 0, 0, 0, 0, 0};
    s->est.states = 0;
    s->est.size = 0;
    s->cnt.est_solves++;
    int r = send_est(s, d);
    if (r < 0) return r;
    /* the block is 2 n frames: a millisecond per value on top of the reply time */
    if ((r = wait_for(s, WAIT_EST_BLOCK, s->cfg.reply_timeout_ms + n)) < 0) return r;
    if (r == 0 && s->est.states == 0) {
        snprintf(s->err, sizeof s->err, "the device did not answer SOLVE within %g s",
                 (double)(s->cfg.reply_timeout_ms + n) / 1000.0);
        return -MSID_DAQ_E_TIMEOUT;
    }
    if (s->est.state != MSID_CAN_EST_STATE_READY) return est_failed(s, "the device's estimate failed");
    if (s->est.size != n && s->est.size != 0) {   /* 0: the SIZE frame was lost (the values are counted) */
        snprintf(s->err, sizeof s->err, "the device's result block holds %u doubles, the design's holds %u",
                 s->est.size, n);
        return -MSID_DAQ_E_PROTOCOL;
    }
    return 0;
}

int msid_can_session_est_solve(msid_can_session *s, double *vals, uint8_t *got, uint32_t n)
{
    if (!s || !vals || !got || n == 0) return -MSID_DAQ_E_ARG;
    memset(got, 0, n);
    s->est_vals = vals;
    s->est_got = got;
    s->est_n = n;
    /* a host that reads slower than the device sends (a virtual bus) loses part of the burst: ask again
       while every answer brings values that were missing, at most MSID_CAN_EST_SOLVES times */
    uint32_t missing = n, before = n + 1;
    int r = 0;
    for (uint32_t attempt = 0; attempt < MSID_CAN_EST_SOLVES && missing && missing < before; ++attempt) {
        if ((r = solve_once(s, n)) < 0) break;
        before = missing;
        missing = 0;
        for (uint32_t k = 0; k < n; ++k) missing += got[k] != 3;
    }
    s->est_vals = NULL;
    s->est_got = NULL;
    s->est_n = 0;
    if (r < 0) return r;
    if (missing) {
        snprintf(s->err, sizeof s->err, "%u of the %u values of the device's result block were lost, after %llu "
                 "SOLVE requests", missing, n, (unsigned long long)s->cnt.est_solves);
        return -MSID_DAQ_E_PROTOCOL;
    }
    return 0;
}
