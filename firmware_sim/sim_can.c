/* msid-devsim's CAN front end: a device that receives a design as msid-can/1
 * parameters, regenerates the multisine through the device core and streams
 * [u; y] in sample frames over SocketCAN, with optional fault injection.
 * Its state is one sim_can; the device's is the sim_device it points to. */
#define _GNU_SOURCE
#include "sim_can.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "msid_daq/msid_can_decoder.h"
#include "msid_daq/msid_can_est.h"
#include "msid_daq/msid_mb_est.h"
#include "msid_daq/msid_socketcan.h"
#include "sim_estimate.h"

/* Counters of what the simulator did (written to the report). */
typedef struct sim_counts {
    uint64_t frames_sent, sample_frames, samples;
    uint64_t dropped, duplicated, reordered, malformed, error_frames, bus_off, restarts, tx_busy;
    uint64_t busoff_samples;         /* samples not sent while bus-off */
    uint64_t done_duplicated, done_replayed;   /* adversarial: DONE frames sent twice, or again later */
    uint64_t done_lost, done_queried;         /* --lose-done: DONE frames not sent; QUERY answered with DONE */
    uint64_t paced_waits, late_samples;  /* --rate: samples that waited for their deadline / found it passed */
    uint64_t early_samples;              /* --rate: samples sent before their deadline (never, if paced) */
    uint32_t experiments_done;
} sim_counts;

/* The CAN front end's state. */
typedef struct sim_can {
    sim_device *d;
    sim_counts cnt;
    msid_socketcan can;
    int state, running_exp;
    uint64_t fc;                     /* frame counter */
    uint64_t busoff_left;
    int busoff_done, restart_done, replay_done;
    uint32_t last_done_exp, last_done_val;   /* the last DONE frame sent (--replay-done-at) */
    int done_valid;                  /* the last experiment is done and nothing started or configured since */
    msid_can_frame held;             /* reorder: frame held back */
    int held_bad;                    /* the held frame was made malformed */
    int have_held;
    double last_host_frame;
    /* on-device estimation (extension estimate/1, msid_can_est.h) */
    uint32_t est_mode, est_state;
    double est_alpha, est_scale;        /* est_scale: the int16 step a host decodes with */
    sim_est est;
    msid_mb_est_layout est_lo;
    uint16_t est_block[65536];           /* the result block, encoded as the Modbus extension's */
} sim_can;

static void die(const char *m)
{
    fprintf(stderr, "msid-devsim: error: %s\n", m);
    exit(1);
}

static void tx(sim_can *c, const msid_can_frame *f)
{
    int r = msid_can_send(&c->can.tr, f, 1000);
    if (r < 0) {
        c->cnt.tx_busy++;
        if (r != -MSID_DAQ_E_BUSY) {
            fprintf(stderr, "msid-devsim: error: send: %s\n", msid_can_error(&c->can.tr));
            exit(1);
        }
        return;
    }
    c->cnt.frames_sent++;
}

static void tx8(sim_can *c, uint32_t off, const uint8_t d[8])
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = c->d->o.base + off;
    f.len = 8;
    memcpy(f.data, d, 8);
    tx(c, &f);
}

static void send_state(sim_can *c, uint32_t st, uint32_t e, uint32_t err, uint32_t val)
{
    uint8_t d[8];
    msid_can_encode_state(d, st, e, err, val);
    tx8(c, MSID_CAN_ID_STATUS, d);
}

static void send_info(sim_can *c)
{
    uint8_t d[8];
    msid_can_encode_info(d, c->d->o.version, c->d->pd.nu, c->d->pd.ny, c->d->configured ? c->d->cfg.crc : 0);
    tx8(c, MSID_CAN_ID_STATUS, d);
}

static void send_counters(sim_can *c)
{
    uint8_t d[8];
    msid_can_encode_counters(d, 0, 0, (uint32_t)c->cnt.restarts, (uint32_t)c->cnt.tx_busy);
    tx8(c, MSID_CAN_ID_STATUS, d);
}

static void send_error_frame(sim_can *c, uint32_t cls, uint8_t ctrl, uint8_t prot)
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = MSID_CAN_ERR_FLAG | cls;
    f.len = 8;
    f.data[1] = ctrl;
    f.data[2] = prot;
    tx(c, &f);
    c->cnt.error_frames++;
}


static void report_body(FILE *f, const void *ctx)
{
    const sim_can *c = ctx;
    fprintf(f, "{\"format\": \"msid-devsim-report/1\", \"protocol_version\": %u, \"config_crc\": %u,\n", c->d->o.version,
            c->d->configured ? c->d->cfg.crc : 0);
    fprintf(f, " \"frames_sent\": %llu, \"sample_frames\": %llu, \"samples\": %llu, \"experiments_done\": %u,\n",
            (unsigned long long)c->cnt.frames_sent, (unsigned long long)c->cnt.sample_frames, (unsigned long long)c->cnt.samples,
            c->cnt.experiments_done);
    fprintf(f, " \"injected\": {\"dropped\": %llu, \"duplicated\": %llu, \"reordered\": %llu, \"malformed\": %llu, "
               "\"error_frames\": %llu, \"bus_off\": %llu, \"busoff_samples\": %llu, \"restarts\": %llu},\n",
            (unsigned long long)c->cnt.dropped, (unsigned long long)c->cnt.duplicated, (unsigned long long)c->cnt.reordered,
            (unsigned long long)c->cnt.malformed, (unsigned long long)c->cnt.error_frames, (unsigned long long)c->cnt.bus_off,
            (unsigned long long)c->cnt.busoff_samples, (unsigned long long)c->cnt.restarts);
    fprintf(f, " \"adversarial\": {\"done_duplicated\": %llu, \"done_replayed\": %llu, \"done_lost\": %llu, \"done_queried\": %llu},\n",
            (unsigned long long)c->cnt.done_duplicated, (unsigned long long)c->cnt.done_replayed,
            (unsigned long long)c->cnt.done_lost, (unsigned long long)c->cnt.done_queried);
    fprintf(f, " \"rate_hz\": %u, \"paced_waits\": %llu, \"late_samples\": %llu, \"early_samples\": %llu,\n",
            c->d->configured ? c->d->cfg.rate_hz : 0, (unsigned long long)c->cnt.paced_waits, (unsigned long long)c->cnt.late_samples,
            (unsigned long long)c->cnt.early_samples);
    fprintf(f, " \"tx_busy\": %llu, \"send_retries\": %llu}\n", (unsigned long long)c->cnt.tx_busy,
            (unsigned long long)c->can.st.send_retries);
}


static int start(sim_can *c, uint32_t e, uint32_t periods)
{
    const int err = sim_start(c->d, e, periods);
    if (err) return err;
    c->running_exp = (int)e;
    c->done_valid = 0;
    c->busoff_done = c->restart_done = c->replay_done = 0;
    c->busoff_left = 0;
    c->state = MSID_CAN_STATE_RUNNING;
    if (c->est.on) sim_est_begin(&c->est, e);
    send_state(c, MSID_CAN_STATE_RUNNING, e, 0, (uint32_t)c->d->n_total);
    return 0;
}

static void flush_held(sim_can *c)
{
    if (c->have_held) { tx(c, &c->held); c->have_held = 0; }
}

/* ---- on-device estimation (msid-can/1 extension estimate/1) ---------------- */
static void est_off(sim_can *c)
{
    memset(&c->est, 0, sizeof c->est);
    c->est.bad = -1;
    c->est_mode = c->est_state = MSID_CAN_EST_STATE_OFF;
}

static void send_est_state(sim_can *c)
{
    uint8_t d[8];
    msid_can_est_encode_state(d, c->est_state, c->est_mode, (uint32_t)c->est.status, (uint32_t)(c->est.bad + 1));
    tx8(c, MSID_CAN_ID_EST, d);
    const uint32_t v[3][2] = {{MSID_CAN_EST_MUX_NEED, (uint32_t)c->est.need}, {MSID_CAN_EST_MUX_HAVE, (uint32_t)c->est.have},
                              {MSID_CAN_EST_MUX_PERIODS, (uint32_t)c->est.periods}};
    for (int i = 0; i < 3; ++i) {
        msid_can_est_encode_u32(d, v[i][0], v[i][1]);
        tx8(c, MSID_CAN_ID_EST, d);
    }
}

static void handle_est(sim_can *c, const uint8_t *d)
{
    if (c->state == MSID_CAN_STATE_RUNNING) return;   /* ignored while running, like CFG */
    switch (d[0]) {
    case MSID_CAN_EST_CMD_ALPHA: {
        uint64_t b;
        memcpy(&b, &c->est_alpha, sizeof b);
        const uint64_t w = msid_can_get_u32(d + 4);
        b = d[1] ? (b & 0xFFFFFFFFull) | w << 32 : (b & ~0xFFFFFFFFull) | w;
        memcpy(&c->est_alpha, &b, sizeof b);
        return;
    }
    case MSID_CAN_EST_CMD_SETUP: {
        est_off(c);
        const uint32_t mode = d[1], tr = d[2];
        if (!c->d->configured) c->est.status = MSID_E_STATE;
        else if (mode < MSID_MB_EST_ONLY || mode > MSID_MB_EST_STREAM || tr > MSID_TRANSIENT_DROP ||
                 !(c->est_alpha >= 0 && c->est_alpha < 1))
            c->est.status = MSID_E_ARG;
        else if (msid_mb_est_layout_init(&c->est_lo, c->d->pd.nu, c->d->pd.ny, c->d->des.n_experiments, c->d->des.n_lines) ||
                 msid_mb_est_regs(&c->est_lo) > 65536u || c->est_lo.doubles >= (1u << 24))
            c->est.status = MSID_E_DIMS;
        else {
            const sim_est_cfg ec = {(uint32_t)d[4] | (uint32_t)d[5] << 8, (msid_transient_mode)tr, c->est_alpha, c->d->cfg.periods};
            sim_est_setup(&c->est, c->d, &ec);
            c->est_scale = msid_can_step_decimal((double)c->d->cfg.scale);
        }
        c->est_mode = c->est.on ? mode : 0;
        c->est_state = c->est.on ? MSID_CAN_EST_STATE_ACCUMULATING : MSID_CAN_EST_STATE_ERROR;
        send_est_state(c);
        return;
    }
    case MSID_CAN_EST_CMD_SOLVE: {
        if (c->est_state == MSID_CAN_EST_STATE_ACCUMULATING) {
            const msid_status st = sim_est_solve(&c->est);
            if (st) c->est.status = st;
            c->est_state = st ? MSID_CAN_EST_STATE_ERROR : MSID_CAN_EST_STATE_READY;
            if (!st) msid_mb_est_encode(c->est_block, &c->est_lo, &c->est.ms, &c->est.f);
        } else if (c->est_state == MSID_CAN_EST_STATE_OFF) {
            c->est_state = MSID_CAN_EST_STATE_ERROR;
            c->est.status = MSID_E_STATE;
        }
        send_est_state(c);
        if (c->est_state != MSID_CAN_EST_STATE_READY) return;
        uint8_t f[8], g[8];
        msid_can_est_encode_u32(f, MSID_CAN_EST_MUX_SIZE, c->est_lo.doubles);
        tx8(c, MSID_CAN_ID_EST, f);
        for (uint32_t k = 0; k < c->est_lo.doubles; ++k) {
            msid_can_est_encode_value(f, g, k, msid_mb_est_value(c->est_block, k));
            tx8(c, MSID_CAN_ID_EST, f);
            tx8(c, MSID_CAN_ID_EST, g);
        }
        send_est_state(c);   /* the end of the block */
        return;
    }
    case MSID_CAN_EST_CMD_QUERY:
        send_est_state(c);
        return;
    default:
        return;
    }
}

static void handle_host_frame(sim_can *c, const msid_can_frame *f)
{
    c->last_host_frame = sim_now_s();
    if (f->id == c->d->o.base + MSID_CAN_ID_CFG) {
        if (c->state == MSID_CAN_STATE_RUNNING) return;   /* ignored while running */
        const int r = msid_params_feed(&c->d->cfg, f->data, f->len, c->d->o.version);
        if (r < 0) {
            c->d->configured = 0;
            c->state = MSID_CAN_STATE_ERROR;
            send_state(c, MSID_CAN_STATE_ERROR, 0, (uint32_t)-r, 0);
            if (r == -MSID_CAN_ERR_VERSION) send_info(c);
        } else if (r == 1) {
            uint32_t ms = 0, err;
            if (c->d->cfg.fd && !c->can.fd_frames) { c->d->configured = 0; err = MSID_CAN_ERR_CFG; }   /* FD on a classic-only bus */
            else err = sim_configure(c->d, &ms);
            est_off(c);
            c->done_valid = 0;
            c->state = err ? MSID_CAN_STATE_ERROR : MSID_CAN_STATE_CONFIGURED;
            send_info(c);
            send_state(c, (uint32_t)c->state, 0, err, ms);
        }
        return;
    }
    if (f->id == c->d->o.base + MSID_CAN_ID_EST_CTRL && f->len == 8) { handle_est(c, f->data); return; }
    if (f->id != c->d->o.base + MSID_CAN_ID_CTRL || f->len != 8) return;
    const uint8_t *d = f->data;
    if (d[2] != c->d->o.version) {
        send_info(c);
        send_state(c, MSID_CAN_STATE_ERROR, 0, MSID_CAN_ERR_VERSION, d[2]);
        return;
    }
    switch (d[0]) {
    case MSID_CAN_CMD_START: {
        if (c->state == MSID_CAN_STATE_RUNNING) return;
        const int err = start(c, d[1], msid_can_get_u32(d + 4));
        if (err) send_state(c, MSID_CAN_STATE_ERROR, d[1], (uint32_t)err, 0);
        break;
    }
    case MSID_CAN_CMD_STOP:
        if (c->state == MSID_CAN_STATE_RUNNING) {
            flush_held(c);
            c->state = MSID_CAN_STATE_CONFIGURED;
            send_state(c, MSID_CAN_STATE_IDLE, (uint32_t)c->running_exp, 0, (uint32_t)c->d->n_sample);
        }
        break;
    case MSID_CAN_CMD_RESET:
        flush_held(c);
        est_off(c);
        c->d->configured = 0;
        msid_params_reset(&c->d->cfg);
        c->done_valid = 0;
        c->state = MSID_CAN_STATE_IDLE;
        send_state(c, MSID_CAN_STATE_IDLE, 0, 0, 0);
        break;
    case MSID_CAN_CMD_QUERY:
        send_info(c);
        if (c->state == MSID_CAN_STATE_CONFIGURED && c->done_valid) {
            /* after an experiment and before the next START: DONE(e, n) again, so a host that lost the
               DONE frame closes the experiment exactly as that frame would have (docs/can-protocol.md) */
            send_state(c, MSID_CAN_STATE_DONE, c->last_done_exp, 0, c->last_done_val);
            c->cnt.done_queried++;
        } else {
            send_state(c, (uint32_t)c->state, c->running_exp < 0 ? 0 : (uint32_t)c->running_exp, 0, (uint32_t)c->d->n_sample);
        }
        send_counters(c);
        break;
    default:
        break;
    }
}

static void poll_host(sim_can *c, int timeout_ms)
{
    msid_can_frame fr[16];
    int k = msid_can_recv(&c->can.tr, fr, 16, timeout_ms);
    if (k == -MSID_DAQ_E_TIMEOUT) return;
    if (k < 0) {
        fprintf(stderr, "msid-devsim: error: receive: %s\n", msid_can_error(&c->can.tr));
        exit(1);
    }
    for (int i = 0; i < k; ++i) handle_host_frame(c, &fr[i]);
}

/* ---- sample production ---------------------------------------------------- */
static void send_sample_frame(sim_can *c, msid_can_frame *f)
{
    ++c->fc;
    c->cnt.sample_frames++;
    if (c->busoff_left) return;   /* counted in busoff_samples */
    if ((c->d->o.drop_every && c->fc % c->d->o.drop_every == 0) ||
        (c->d->o.drop_frac > 0 && msid_rng_uniform(&c->d->rng) < c->d->o.drop_frac)) {
        c->cnt.dropped++;
        return;
    }
    int bad = 0;
    if (c->d->o.malformed_every && c->fc % c->d->o.malformed_every == 0) {
        f->len = (uint8_t)(c->d->cfg.fd ? 12 : 5);   /* wrong DLC for a sample frame */
        c->cnt.malformed++;
        bad = 1;
    }
    if (c->d->o.error_every && c->fc % c->d->o.error_every == 0) {
        static const uint32_t cls[4] = {0x004u, 0x004u, 0x008u, 0x020u};   /* CRTL warning, CRTL passive, PROT, ACK */
        static const uint8_t ctl[4] = {0x04u, 0x10u, 0, 0};
        const uint64_t k = (c->fc / c->d->o.error_every - 1) % 4;
        send_error_frame(c, cls[k], ctl[k], k == 2 ? 0x08u : 0);
        if (k == 3) send_error_frame(c, 0x004u, 0x40u, 0);   /* back to error-active */
    }
    if (c->have_held) {
        tx(c, f);
        /* a reorder is counted when it happened as a receiver can see it: a well-formed frame overtook a
           well-formed held one (a held frame flushed in order at a restart, bus-off, STOP or the end of the
           experiment was not reordered; a malformed frame is discarded, so it cannot overtake or be overtaken) */
        if (!bad && !c->held_bad) c->cnt.reordered++;
        flush_held(c);
        return;
    }
    if (c->d->o.reorder_every && c->fc % c->d->o.reorder_every == 0) {
        c->held = *f;
        c->held_bad = bad;
        c->have_held = 1;
        return;
    }
    tx(c, f);
    if (!bad && c->d->o.dup_every && c->fc % c->d->o.dup_every == 0) {   /* a malformed frame is not duplicated */
        tx(c, f);
        c->cnt.duplicated++;
    }
}


static void produce_sample(sim_can *c)
{
    const uint32_t C = c->d->pd.nu + c->d->pd.ny, P = c->d->des.period;
    double row[MSID_MAX_CHANNELS];
    sim_row(c->d, row);
    const uint32_t flags = (c->d->n_sample % P == 0 ? MSID_CAN_PSTART : 0u) | (c->d->n_sample == 0 ? MSID_CAN_SEGSTART : 0u);
    const uint32_t chunks = msid_can_chunks(C, c->d->cfg.encoding, c->d->cfg.fd);
    double codes[MSID_MAX_CHANNELS];   /* the row as a host decodes it: what the device estimates on */
    for (uint32_t k = 0; k < chunks; ++k) {
        msid_can_frame f;
        memset(&f, 0, sizeof f);
        f.id = c->d->o.base + msid_can_chunk_id(c->d->cfg.encoding, c->d->cfg.fd, k);
        f.len = (uint8_t)msid_can_sample_len(c->d->cfg.fd);
        f.flags = c->d->cfg.fd ? (MSID_CANF_FD | MSID_CANF_BRS) : 0;
        msid_can_encode_sample(f.data, c->d->cfg.encoding, c->d->cfg.fd, k, (uint32_t)c->d->n_sample, (uint32_t)c->running_exp, flags, row,
                               C, (double)c->d->cfg.scale);
        if (c->est.on)   /* with the host decoder's int16 step (msid_can_step_decimal): the same doubles */
            msid_can_decode_values(f.data, c->d->cfg.encoding, c->d->cfg.fd, k, codes, C, c->est_scale);
        if (c->est_mode != MSID_MB_EST_ONLY) send_sample_frame(c, &f);
    }
    if (c->est.on && c->d->n_sample < c->d->n_total) {
        sim_est_push(&c->est, codes);
        if (c->d->n_sample + 1 == c->d->n_total) sim_est_end(&c->est);
        if (!c->est.on) c->est_state = MSID_CAN_EST_STATE_ERROR;
    }
    if (c->busoff_left && --c->busoff_left == 0) send_error_frame(c, 0x100u, 0, 0);   /* CAN_ERR_RESTARTED */
    c->cnt.samples++;
    c->d->n_sample++;
}

static void run_step(sim_can *c)
{
    const int e = c->running_exp;
    if (c->d->o.restart_exp == e && !c->restart_done && c->d->n_sample == c->d->o.restart_at) {
        /* watchdog reset: the firmware reboots, keeps its configuration (retained RAM) and
           restarts the experiment from sample 0; the plant keeps its c->state */
        c->restart_done = 1;
        flush_held(c);
        c->cnt.restarts++;
        send_state(c, MSID_CAN_STATE_BOOT, (uint32_t)e, 0, 0);
        send_state(c, MSID_CAN_STATE_RUNNING, (uint32_t)e, 0, (uint32_t)c->d->n_total);
        sim_restart_segment(c->d);
        sim_est_begin(&c->est, (uint32_t)e);   /* a new segment: its skip periods apply again */
        clock_gettime(CLOCK_MONOTONIC, &c->d->t_start);
    }
    if (c->d->o.busoff_exp == e && !c->busoff_done && c->d->n_sample == c->d->o.busoff_at) {
        c->busoff_done = 1;
        flush_held(c);
        send_error_frame(c, 0x040u, 0, 0);   /* CAN_ERR_BUSOFF */
        c->cnt.bus_off++;
        c->busoff_left = c->d->o.busoff_len ? c->d->o.busoff_len : 1;
        c->cnt.busoff_samples += c->busoff_left;
    }
    if (c->d->o.replay_exp == e && !c->replay_done && c->d->n_sample == c->d->o.replay_at && c->cnt.experiments_done) {
        c->replay_done = 1;   /* adversarial: the last DONE frame again, in the middle of this experiment */
        send_state(c, MSID_CAN_STATE_DONE, c->last_done_exp, 0, c->last_done_val);
        c->cnt.done_replayed++;
    }
    produce_sample(c);
    if (c->d->n_sample >= c->d->n_total) {
        flush_held(c);
        c->state = MSID_CAN_STATE_DONE;
        c->cnt.experiments_done++;
        send_counters(c);
        if (c->d->o.lose_done_exp == e) c->cnt.done_lost++;   /* adversarial: the DONE frame is lost */
        else send_state(c, MSID_CAN_STATE_DONE, (uint32_t)e, 0, (uint32_t)c->d->n_sample);
        if (c->d->o.done_twice) {   /* adversarial: a duplicated DONE frame */
            send_state(c, MSID_CAN_STATE_DONE, (uint32_t)e, 0, (uint32_t)c->d->n_sample);
            c->cnt.done_duplicated++;
        }
        c->last_done_exp = (uint32_t)e;
        c->last_done_val = (uint32_t)c->d->n_sample;
        c->done_valid = 1;
        sim_write_atomic(c->d->o.report, report_body, c);
        c->state = MSID_CAN_STATE_CONFIGURED;
    }
}


int sim_can_main(sim_device *d)
{
    static sim_can ctx;
    sim_can *c = &ctx;
    memset(c, 0, sizeof *c);
    c->d = d;
    est_off(c);
    c->est_alpha = 0.01;
    c->state = MSID_CAN_STATE_BOOT;
    c->running_exp = -1;
    msid_socketcan_cfg sc;
    memset(&sc, 0, sizeof sc);
    sc.iface = d->o.iface;
    sc.fd_frames = 1;
    sc.n_filters = 2;
    sc.filter_id[0] = d->o.base;                    /* CTRL and CFG */
    sc.filter_mask[0] = 0x7FEu | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
    sc.filter_id[1] = d->o.base + MSID_CAN_ID_EST_CTRL;   /* and EST_CTRL (extension estimate/1) */
    sc.filter_mask[1] = 0x7FFu | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
    sc.rcvbuf = d->o.rcvbuf;
    int r = msid_socketcan_open(&c->can, &sc);
    if (r == -MSID_DAQ_E_NOFD) { sc.fd_frames = 0; r = msid_socketcan_open(&c->can, &sc); }
    if (r < 0) die(c->can.err);
    printf("msid-devsim: ready on %s (base 0x%X, %s, %u input(s), %u output(s), %s plant)\n", c->d->o.iface, c->d->o.base,
           c->can.fd_frames ? "CAN FD" : "classic CAN", c->d->pd.nu, c->d->pd.ny, c->d->pd.ct ? "continuous-time" : "discrete-time");
    fflush(stdout);
    c->last_host_frame = sim_now_s();
    send_info(c);
    c->state = MSID_CAN_STATE_IDLE;
    send_state(c, MSID_CAN_STATE_IDLE, 0, 0, 0);
    while (!*c->d->stop) {
        if (c->state == MSID_CAN_STATE_RUNNING) {
            if (c->d->cfg.rate_hz) {
                struct timespec dl = c->d->t_start;
                const uint64_t ns = c->d->n_sample * 1000000000ull / c->d->cfg.rate_hz;
                dl.tv_sec += (time_t)(ns / 1000000000ull);
                dl.tv_nsec += (long)(ns % 1000000000ull);
                if (dl.tv_nsec >= 1000000000L) { dl.tv_sec++; dl.tv_nsec -= 1000000000L; }
                struct timespec now;
                clock_gettime(CLOCK_MONOTONIC, &now);
                if (now.tv_sec < dl.tv_sec || (now.tv_sec == dl.tv_sec && now.tv_nsec < dl.tv_nsec)) c->cnt.paced_waits++;
                else c->cnt.late_samples++;   /* behind its clock (a loaded machine): sent at once */
                while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &dl, NULL) == EINTR && !*c->d->stop) {}
                clock_gettime(CLOCK_MONOTONIC, &now);
                if (now.tv_sec < dl.tv_sec || (now.tv_sec == dl.tv_sec && now.tv_nsec < dl.tv_nsec)) c->cnt.early_samples++;
            }
            if ((c->d->n_sample & 63) == 0) poll_host(c, 0);
            if (c->state == MSID_CAN_STATE_RUNNING) run_step(c);
        } else {
            poll_host(c, 200);
            if (c->d->o.idle_exit > 0 && sim_now_s() - c->last_host_frame > c->d->o.idle_exit) break;
        }
    }
    sim_write_atomic(c->d->o.report, report_body, c);
    msid_can_close(&c->can.tr);
    return 0;
}
