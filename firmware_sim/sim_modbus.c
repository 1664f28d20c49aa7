/* msid-devsim's Modbus front end: the same device core (design from parameter records,
 * excitation from lib/, plant, noise; sim_device.c) m->served as msid-modbus/1 over libmodbus TCP or
 * RTU, with fault injection. Fixed memory: the register map is static (a
 * modbus_mapping_t over static arrays). See docs/modbus-registers.md. */
#define _GNU_SOURCE
#include "sim_modbus.h"
#include "sim_estimate.h"
#include "sim_mb_server.h"

#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "msid_daq/msid_mb_est.h"
#include "msid_daq/msid_mb_proto.h"

#define MAX_RANGES 256

/* The Modbus front end's state: the register map (static storage: a modbus_mapping_t
   over the arrays) and the run. The device's state is the sim_device it points to. */
typedef struct sim_mb {
    sim_device *d;
    uint16_t hr[MSID_MB_HR_EXT_COUNT];   /* msid-modbus/1 and the estimate/1 extension (140..146) */
    uint16_t ir[65536];
    uint8_t served[65536];               /* ring slot read by the host since it was written */
    modbus_mapping_t map;
    sim_mb_server srv;
    modbus_t *mb;                        /* srv's */
    int rtu;
    uint32_t mstate, merr, mdetail, mexp;
    uint32_t enc, word_order, R, W;      /* latched at commit: encoding, word order, ring samples, registers per sample */
    uint64_t w, s0, overruns;            /* write index and segment start (run), overruns (run) */
    uint32_t segment, restarts_total, cfg_records;
    uint16_t cmd_done, cfg_done;
    int restart_done, drop_done, stall_done;
    uint64_t stall_force;
    double stall_until, silent_until, last_request;
    struct {
        uint64_t requests, replies, unanswered, delayed, dropped, exceptions, corrupted, stalls, stall_samples;
        uint64_t restarts, overrun_samples, samples, experiments_done;
        uint64_t garbage_tid, dripped, truncated, oversized, absurd_header, duplicated;   /* adversarial replies */
        uint64_t paced_waits, late_samples;   /* --rate: the next sample not yet due / written > 1 period late */
    } mc;
    struct { uint32_t e; uint64_t a, b; } ranges[MAX_RANGES];   /* overwritten unread: [a, b) of experiment e */
    int n_ranges;
    /* on-device estimation (extension estimate/1, msid_mb_est.h), latched at COMMIT */
    uint32_t est_mode, est_state, est_addr, est_regs, est_solved;
    msid_mb_est_layout est_lo;
    sim_est est;
} sim_mb;

static void sleep_s(const sim_mb *m, double s) { sim_sleep_s(m->d->stop, s); }

/* ---- reports -------------------------------------------------------------- */
static void report_body(FILE *f, const void *ctx)
{
    const sim_mb *m = ctx;
    fprintf(f, "{\"format\": \"msid-devsim-modbus-report/1\", \"transport\": \"%s\", \"config_crc\": %u,\n",
            m->rtu ? "m->rtu" : "tcp", m->d->configured ? m->d->cfg.crc : 0);
    fprintf(f, " \"requests\": %llu, \"replies\": %llu, \"unanswered\": %llu, \"samples\": %llu, "
               "\"experiments_done\": %llu, \"ring_samples\": %u, \"sample_regs\": %u,\n",
            (unsigned long long)m->mc.requests, (unsigned long long)m->mc.replies, (unsigned long long)m->mc.unanswered,
            (unsigned long long)m->mc.samples, (unsigned long long)m->mc.experiments_done, m->R, m->W);
    fprintf(f, " \"injected\": {\"delayed\": %llu, \"dropped\": %llu, \"exceptions\": %llu, \"corrupted\": %llu, "
               "\"stalls\": %llu, \"stall_samples\": %llu, \"restarts\": %llu},\n",
            (unsigned long long)m->mc.delayed, (unsigned long long)m->mc.dropped, (unsigned long long)m->mc.exceptions,
            (unsigned long long)m->mc.corrupted, (unsigned long long)m->mc.stalls, (unsigned long long)m->mc.stall_samples,
            (unsigned long long)m->mc.restarts);
    fprintf(f, " \"adversarial\": {\"garbage_tid\": %llu, \"dripped\": %llu, \"truncated\": %llu, \"oversized\": %llu, "
               "\"absurd_header\": %llu, \"duplicated\": %llu},\n",
            (unsigned long long)m->mc.garbage_tid, (unsigned long long)m->mc.dripped, (unsigned long long)m->mc.truncated,
            (unsigned long long)m->mc.oversized, (unsigned long long)m->mc.absurd_header,
            (unsigned long long)m->mc.duplicated);
    fprintf(f, " \"rate_hz\": %u, \"paced_waits\": %llu, \"late_samples\": %llu,\n",
            m->d->configured ? m->d->cfg.rate_hz : 0, (unsigned long long)m->mc.paced_waits,
            (unsigned long long)m->mc.late_samples);
    fprintf(f, " \"overrun_samples\": %llu, \"overrun_ranges\": [", (unsigned long long)m->mc.overrun_samples);
    for (int i = 0; i < m->n_ranges; ++i)
        fprintf(f, "%s[%u, %llu, %llu]", i ? ", " : "", m->ranges[i].e, (unsigned long long)m->ranges[i].a,
                (unsigned long long)m->ranges[i].b);
    fprintf(f, "]}\n");
}

/* ---- the register map ------------------------------------------------------ */
static void update_header(sim_mb *m)
{
    msid_mb_header h;
    memset(&h, 0, sizeof h);
    h.magic = MSID_MB_MAGIC;
    h.version = MSID_MB_PROTO_VERSION;
    h.state = m->mstate;
    h.experiment = m->mexp;
    h.error = m->merr;
    h.detail = m->mdetail;
    h.nu = m->d->pd.nu;
    h.ny = m->d->pd.ny;
    h.encoding = m->enc;
    h.word_order = m->word_order;
    h.sample_regs = m->W;
    h.ring_addr = MSID_MB_RING_ADDR;
    h.ring_samples = m->R;
    h.write_index = (uint32_t)(m->w - (m->d->o.back_exp == (int)m->mexp && m->d->n_sample >= m->d->o.back_at && m->w >= 16 ? 16 : 0));
    h.seg_start = (uint32_t)m->s0;
    h.segment = m->segment & 0xFFFFu;
    h.restarts = m->restarts_total & 0xFFFFu;
    h.overruns = (uint32_t)m->overruns;
    h.period_count = m->d->configured && m->d->des.period ? (uint32_t)((m->w - m->s0) / m->d->des.period) : 0;
    h.total = (uint32_t)m->d->n_total;
    if (m->d->o.absurd_exp == (int)m->mexp && (m->mstate == MSID_MB_STATE_RUNNING || m->mstate == MSID_MB_STATE_DONE) &&
        m->d->n_sample >= m->d->o.absurd_at) {
        h.total = 0xFFFFFFF0u;   /* adversarial: an absurd sample count */
        m->mc.absurd_header = 1;
    }
    h.crc = m->d->configured ? m->d->cfg.crc : 0;
    h.period = m->d->configured ? m->d->des.period : 0;
    h.cmd_done = m->cmd_done;
    h.cfg_done = m->cfg_done;
    h.cfg_records = m->cfg_records;
    h.rate = m->d->configured ? m->d->cfg.rate_hz : 0;
    h.lines = m->d->configured ? m->d->des.n_lines : 0;
    h.experiments = m->d->configured ? m->d->des.n_experiments : 0;
    h.periods = m->d->configured ? m->d->cfg.periods : 0;
    msid_mb_header_encode(m->ir, &h);
    uint16_t *x = m->ir;
    x[MSID_MB_IR_EXT] = MSID_MB_EXT_ESTIMATE;
    x[MSID_MB_IR_EST_VERSION] = MSID_MB_EST_VERSION;
    x[MSID_MB_IR_EST_MODE] = (uint16_t)m->est_mode;
    x[MSID_MB_IR_EST_STATE] = (uint16_t)m->est_state;
    x[MSID_MB_IR_EST_STATUS] = (uint16_t)m->est.status;
    x[MSID_MB_IR_EST_BAD] = (uint16_t)(m->est.bad + 1);
    msid_mb_put_u32(x + MSID_MB_IR_EST_NEED, m->est.need > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)m->est.need);
    msid_mb_put_u32(x + MSID_MB_IR_EST_HAVE, m->est.have > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)m->est.have);
    x[MSID_MB_IR_EST_ADDR] = (uint16_t)m->est_addr;
    msid_mb_put_u32(x + MSID_MB_IR_EST_REGS, m->est_regs);
    msid_mb_put_u32(x + MSID_MB_IR_EST_PERIODS, (uint32_t)m->est.periods);
    x[MSID_MB_IR_EST_SOLVED] = (uint16_t)m->est_solved;
}

/* Estimation settings latched at COMMIT (holding registers 140..146; MODE is cleared so a
   host that knows nothing of the extension later gets a plain device). 0 or an
   MSID_CAN_ERR_* code; a design the device cannot estimate leaves the stream usable and
   reports EST_STATE error with its msid_status (and EST_NEED/EST_HAVE for memory). */
static uint32_t latch_estimation(sim_mb *m)
{
    const uint32_t mode = m->hr[MSID_MB_HR_EST_MODE], tr = m->hr[MSID_MB_HR_EST_TRANSIENT];
    const double alpha = msid_mb_get_f64(m->hr + MSID_MB_HR_EST_ALPHA);
    m->hr[MSID_MB_HR_EST_MODE] = MSID_MB_EST_OFF;
    memset(&m->est, 0, sizeof m->est);
    m->est.bad = -1;
    m->est_mode = m->est_state = m->est_addr = m->est_regs = 0;
    if (mode == MSID_MB_EST_OFF) return 0;
    if (mode > MSID_MB_EST_STREAM || tr > MSID_TRANSIENT_DROP || !(alpha >= 0 && alpha < 1)) return MSID_CAN_ERR_CFG;
    m->est_mode = mode;
    m->est_state = MSID_MB_EST_STATE_ERROR;
    const msid_design *des = &m->d->des;
    if (msid_mb_est_layout_init(&m->est_lo, m->d->pd.nu, m->d->pd.ny, des->n_experiments, des->n_lines) != 0) {
        m->est.status = MSID_E_DIMS;
        return 0;
    }
    m->est_regs = msid_mb_est_regs(&m->est_lo);
    /* the result block: after the header when there is no ring, else at the top of the map (the ring shrinks) */
    const uint32_t room = 65536u - MSID_MB_RING_ADDR;
    if (mode == MSID_MB_EST_ONLY) {
        if (m->est_regs > room) { m->est.status = MSID_E_DIMS; return 0; }
        m->est_addr = MSID_MB_RING_ADDR;
        m->R = 0;
    } else {
        if (m->est_regs + m->W > room) { m->est.status = MSID_E_DIMS; return 0; }
        m->est_addr = 65536u - m->est_regs;
        const uint32_t fit = (m->est_addr - MSID_MB_RING_ADDR) / m->W;
        if (fit < m->R) m->R = fit;
    }
    sim_est_cfg ec = {m->hr[MSID_MB_HR_EST_SKIP], (msid_transient_mode)tr, alpha, m->d->cfg.periods};
    if (sim_est_setup(&m->est, m->d, &ec) == MSID_OK) m->est_state = MSID_MB_EST_STATE_ACCUMULATING;
    return 0;
}

static void fail_state(sim_mb *m, uint32_t err, uint32_t detail)
{
    m->mstate = MSID_MB_STATE_ERROR;
    m->merr = err;
    m->mdetail = detail;
}

static void apply_records(sim_mb *m)
{
    uint32_t n = m->hr[MSID_MB_HR_CFG_COUNT];
    if (n > MSID_MB_CFG_RECORDS) n = MSID_MB_CFG_RECORDS;
    uint8_t rec[MSID_MB_CFG_RECORDS][8];
    msid_mb_unpack_records(rec, m->hr + MSID_MB_HR_CFG_REC, n);
    for (uint32_t i = 0; i < n; ++i) {
        if (rec[i][0] == MSID_CAN_P_BEGIN) m->cfg_records = 0, m->merr = m->mdetail = 0;
        const int r = msid_params_feed(&m->d->cfg, rec[i], 8, MSID_CAN_PROTO_VERSION);
        m->cfg_records++;
        if (r < 0) {
            m->d->configured = 0;
            fail_state(m, (uint32_t)-r, 0);
            return;
        }
        if (r == 1) {
            const uint32_t e = m->hr[MSID_MB_HR_ENCODING], wo = m->hr[MSID_MB_HR_WORD_ORDER];
            if (!msid_mb_value_regs(e) || wo > MSID_MB_DCBA) { m->d->configured = 0; fail_state(m, MSID_CAN_ERR_CFG, 0); return; }
            uint32_t ms;
            const uint32_t err = sim_configure(m->d, &ms);
            if (err) { fail_state(m, err, ms); return; }
            m->enc = e;
            m->word_order = wo;
            m->W = msid_mb_sample_regs(m->enc, m->d->pd.nu + m->d->pd.ny);
            m->R = msid_mb_ring_samples(m->W);
            if (m->d->o.ring && m->d->o.ring < m->R) m->R = m->d->o.ring;
            if (latch_estimation(m)) { m->d->configured = 0; fail_state(m, MSID_CAN_ERR_CFG, 0); return; }
            m->mstate = MSID_MB_STATE_CONFIGURED;
            m->merr = m->mdetail = 0;
        }
    }
}

/* SOLVE: the FRF from every experiment's statistics into the result block. */
static void solve(sim_mb *m)
{
    if (m->est_state != MSID_MB_EST_STATE_ACCUMULATING && m->est_state != MSID_MB_EST_STATE_READY) {
        if (m->est_state == MSID_MB_EST_STATE_OFF) { m->est_state = MSID_MB_EST_STATE_ERROR; m->est.status = MSID_E_STATE; }
        return;
    }
    if (m->mstate == MSID_MB_STATE_RUNNING) { m->est_state = MSID_MB_EST_STATE_ERROR; m->est.status = MSID_E_STATE; return; }
    if (m->est_state == MSID_MB_EST_STATE_ACCUMULATING) {
        const msid_status st = sim_est_solve(&m->est);
        if (st) m->est.status = st;
        msid_mb_est_encode(m->ir + m->est_addr, &m->est_lo, &m->est.ms, st ? NULL : &m->est.f);
        if (m->d->o.bad_result)   /* adversarial: the host must not write it */
            msid_mb_put_f64(m->ir + m->est_addr + 4u * (m->est_lo.lines + m->est_lo.G), NAN);
        m->est_state = st ? MSID_MB_EST_STATE_ERROR : MSID_MB_EST_STATE_READY;
    }
    m->est_solved++;
}

static void execute(sim_mb *m)
{
    const uint32_t cmd = m->hr[MSID_MB_HR_CMD], e = m->hr[MSID_MB_HR_CMD_EXP];
    const uint32_t periods = msid_mb_get_u32(m->hr + MSID_MB_HR_CMD_PERIODS);
    if (cmd == MSID_MB_CMD_START) {
        if (m->mstate == MSID_MB_STATE_RUNNING) return;
        if (!m->d->configured) { fail_state(m, MSID_CAN_ERR_NOT_CONFIGURED, 0); return; }
        const int err = sim_start(m->d, e, periods);
        if (err) { fail_state(m, (uint32_t)err, 0); return; }
        m->mexp = e;
        m->w = m->s0 = m->overruns = 0;
        m->segment = 0;
        m->restart_done = m->drop_done = m->stall_done = 0;
        m->stall_force = 0;
        memset(m->served, 0, sizeof m->served);
        if (m->est_state == MSID_MB_EST_STATE_ACCUMULATING) sim_est_begin(&m->est, e);
        m->mstate = MSID_MB_STATE_RUNNING;
        m->merr = m->mdetail = 0;
    } else if (cmd == MSID_MB_CMD_STOP) {
        if (m->mstate == MSID_MB_STATE_RUNNING) m->mstate = MSID_MB_STATE_CONFIGURED;
    } else if (cmd == MSID_MB_CMD_SOLVE) {
        solve(m);
    } else if (cmd == MSID_MB_CMD_RESET) {
        m->d->configured = 0;
        m->est_mode = m->est_state = 0;
        msid_params_reset(&m->d->cfg);
        m->mstate = MSID_MB_STATE_IDLE;
        m->merr = m->mdetail = 0;
    }
}

/* ---- sample production ------------------------------------------------------ */
/* On-device estimation: the row as the host would decode it from the link (the codes). */
static void estimate(sim_mb *m, const uint16_t *codes)
{
    if (!m->est.on || m->d->n_sample >= m->d->n_total) return;
    const uint32_t C = m->d->pd.nu + m->d->pd.ny, vr = msid_mb_value_regs(m->enc);
    double row[MSID_MAX_CHANNELS];
    for (uint32_t c = 0; c < C; ++c)
        row[c] = msid_mb_decode_value(codes + c * vr, m->enc, m->word_order, (double)m->d->cfg.scale);
    sim_est_push(&m->est, row);
    if (m->d->n_sample + 1 == m->d->n_total) sim_est_end(&m->est);
    if (!m->est.on && m->est_state == MSID_MB_EST_STATE_ACCUMULATING) m->est_state = MSID_MB_EST_STATE_ERROR;
}

static void sample_done(sim_mb *m)
{
    m->w++;
    m->d->n_sample++;
    m->mc.samples++;
    if (m->d->n_sample >= m->d->n_total && !m->d->o.never_done) {
        m->mstate = MSID_MB_STATE_DONE;
        m->mc.experiments_done++;
        sim_write_atomic(m->d->o.report, report_body, m);
    }
}

static void write_sample(sim_mb *m)
{
    const uint32_t C = m->d->pd.nu + m->d->pd.ny, vr = msid_mb_value_regs(m->enc);
    double row[MSID_MAX_CHANNELS];
    sim_row(m->d, row);
    if (m->R == 0) {   /* on-device estimation only: no ring, the codes go to the estimator */
        uint16_t s[2 * MSID_MAX_CHANNELS];
        for (uint32_t c = 0; c < C; ++c) msid_mb_encode_value(s + c * vr, row[c], m->enc, m->word_order, (double)m->d->cfg.scale);
        estimate(m, s);
        sample_done(m);
        return;
    }
    const uint32_t slot = (uint32_t)(m->w % m->R);
    if (m->w >= m->R && !m->served[slot]) {
        const uint64_t lost = m->w - m->R;
        m->overruns++;
        m->mc.overrun_samples++;
        if (m->n_ranges > 0 && m->ranges[m->n_ranges - 1].e == m->mexp && m->ranges[m->n_ranges - 1].b == lost) m->ranges[m->n_ranges - 1].b++;
        else if (m->n_ranges < MAX_RANGES) { m->ranges[m->n_ranges].e = m->mexp; m->ranges[m->n_ranges].a = lost; m->ranges[m->n_ranges].b = lost + 1; m->n_ranges++; }
    }
    uint16_t *s = m->ir + MSID_MB_RING_ADDR + (size_t)slot * m->W;
    s[0] = (uint16_t)m->w;
    for (uint32_t c = 0; c < C; ++c) msid_mb_encode_value(s + 1 + c * vr, row[c], m->enc, m->word_order, (double)m->d->cfg.scale);
    m->served[slot] = 0;
    estimate(m, s + 1);
    sample_done(m);
}

static void drop_connection(sim_mb *m)
{
    m->mc.dropped++;
    if (m->rtu) { m->silent_until = sim_now_s() + 1.0; return; }
    sim_mb_server_drop(&m->srv);
}

static double run_time(const sim_mb *m)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)(t.tv_sec - m->d->t_start.tv_sec) + 1e-9 * (double)(t.tv_nsec - m->d->t_start.tv_nsec);
}

/* Produce what is due; returns seconds until the next sample is due (-1: waiting for the host). */
static double produce(sim_mb *m)
{
    for (int k = 0; k < 65536 && m->mstate == MSID_MB_STATE_RUNNING && !*m->d->stop; ++k) {
        const int here = (int)m->mexp;
        if (m->d->o.restart_exp == here && !m->restart_done && m->d->n_sample == m->d->o.restart_at) {
            m->restart_done = 1;
            m->segment++;
            m->restarts_total++;
            m->mc.restarts++;
            m->s0 = m->w;
            sim_restart_segment(m->d);
            sim_est_begin(&m->est, m->mexp);   /* a new segment: its skip periods apply again */
        }
        if (m->d->o.drop_exp == here && !m->drop_done && m->d->n_sample == m->d->o.drop_at) { m->drop_done = 1; drop_connection(m); }
        if (m->d->o.stall_exp == here && !m->stall_done && m->d->n_sample == m->d->o.stall_at) {
            m->stall_done = 1;
            m->stall_until = sim_now_s() + 1e-3 * (double)m->d->o.stall_ms;
            m->stall_force = m->d->o.stall_samples;
            m->mc.stalls++;
        }
        if (m->stall_force) {
            m->stall_force--;
            m->mc.stall_samples++;
        } else if (m->d->cfg.rate_hz) {
            const double due = run_time(m) * m->d->cfg.rate_hz;
            if ((double)m->w >= due) {
                m->mc.paced_waits++;   /* waits for its clock: never a sample before its time */
                return ((double)m->w + 1 - due) / m->d->cfg.rate_hz;
            }
            if (due - (double)m->w > 2.0) m->mc.late_samples++;   /* behind its clock (a loaded machine) */
        } else if (m->R && m->w >= m->R && !m->served[m->w % m->R]) {
            return -1;
        }
        write_sample(m);
    }
    return m->mstate == MSID_MB_STATE_RUNNING ? 0 : -1;
}

/* ---- requests ------------------------------------------------------------------ */
static uint16_t crc16(const uint8_t *p, size_t n)
{
    uint16_t c = 0xFFFF;
    for (size_t i = 0; i < n; ++i) {
        c ^= p[i];
        for (int b = 0; b < 8; ++b) c = (c & 1) ? (uint16_t)((c >> 1) ^ 0xA001) : (uint16_t)(c >> 1);
    }
    return c;
}

/* A read reply (function 3 or 4) built here, TCP or RTU framed, with `extra` junk bytes counted in its
   byte count (and length) beyond the registers asked for; 0 when the request is not a valid read. */
static size_t read_reply(const sim_mb *m, const uint8_t *q, int hl, uint32_t addr, uint32_t cnt, uint32_t extra, uint8_t *f)
{
    const uint16_t *src = q[hl] == 4 ? m->ir : m->hr;
    const uint32_t lim = q[hl] == 4 ? 65536u : MSID_MB_HR_EXT_COUNT;
    if (cnt == 0 || cnt > 125 || addr + cnt > lim) return 0;
    const uint32_t bc = 2 * cnt + extra > 255 ? 255 : 2 * cnt + extra;
    size_t n = 0;
    if (!m->rtu) {   /* MBAP: the request's transaction id, protocol 0, length, unit */
        f[n++] = q[0]; f[n++] = q[1]; f[n++] = 0; f[n++] = 0;
        f[n++] = (uint8_t)((3 + bc) >> 8); f[n++] = (uint8_t)(3 + bc);
    }
    f[n++] = q[hl - 1];
    f[n++] = q[hl];
    f[n++] = (uint8_t)bc;
    for (uint32_t i = 0; i < cnt; ++i) { f[n++] = (uint8_t)(src[addr + i] >> 8); f[n++] = (uint8_t)src[addr + i]; }
    for (uint32_t i = 2 * cnt; i < bc; ++i) f[n++] = (uint8_t)(0xA5 ^ i);
    if (m->rtu) {
        const uint16_t c = crc16(f, n);
        f[n++] = (uint8_t)c;
        f[n++] = (uint8_t)(c >> 8);
    }
    return n;
}

/* RTU: the reply to a read, with one data bit flipped after the CRC was computed. */
static int send_corrupt(sim_mb *m, const uint8_t *q, int hl, uint32_t addr, uint32_t cnt)
{
    uint8_t f[MODBUS_MAX_ADU_LENGTH + 32];
    const size_t n = read_reply(m, q, hl, addr, cnt, 0, f);
    if (!n) return 0;
    f[3] ^= 0x01;
    return write(modbus_get_socket(m->mb), f, n) == (ssize_t)n;
}

enum { HOSTILE_SENT = 1, HOSTILE_UNUSABLE = 2 };

/* The adversarial replies (tests of the host's defences): HOSTILE_SENT when a reply was sent in place of the honest one
   (a write was still applied to the map), HOSTILE_UNUSABLE when the host cannot use what it got (the
   ring slots it asked for are not marked read). At most one per request. */
static int hostile_reply(sim_mb *m, const uint8_t *q, int len, int hl, uint64_t k, uint32_t fc, uint32_t addr, uint32_t cnt)
{
    const sim_opts *o = &m->d->o;
    const int fd = modbus_get_socket(m->mb);
    if (!m->rtu && o->garbage_tid_every && k % o->garbage_tid_every == 0) {
        uint8_t g[MODBUS_MAX_ADU_LENGTH];
        memcpy(g, q, (size_t)len);
        g[0] ^= 0x5A;   /* a transaction id the host never sent */
        g[1] ^= 0xC3;
        if (modbus_reply(m->mb, g, len, &m->map) < 0) return HOSTILE_SENT | HOSTILE_UNUSABLE;
        m->mc.garbage_tid++;
        return HOSTILE_SENT | HOSTILE_UNUSABLE;
    }
    if (fc != 3 && fc != 4) return 0;
    const int cut = o->truncate_every && k % o->truncate_every == 0;
    const int big = !cut && o->oversize_every && k % o->oversize_every == 0;
    const int drip = !cut && !big && o->drip_every && k % o->drip_every == 0;
    if (!cut && !big && !drip) return 0;
    uint8_t f[MODBUS_MAX_ADU_LENGTH + 32];
    size_t n = read_reply(m, q, hl, addr, cnt, big ? 16u : 0u, f);
    if (!n) return 0;
    if (drip) {
        m->mc.dripped++;
        for (size_t i = 0; i < n; ++i) {
            if (write(fd, f + i, 1) != 1) break;
            sleep_s(m, 1e-3 * (double)o->drip_ms);
        }
        return HOSTILE_SENT;
    }
    if (cut) {
        m->mc.truncated++;
        n /= 2;
    } else {
        m->mc.oversized++;
    }
    if (write(fd, f, n) != (ssize_t)n) {}
    return HOSTILE_SENT | HOSTILE_UNUSABLE;
}

static void serve(sim_mb *m, const uint8_t *q, int len)
{
    m->mc.requests++;
    m->last_request = sim_now_s();
    const int hl = modbus_get_header_length(m->mb);
    const uint32_t fc = q[hl], addr = (uint32_t)q[hl + 1] << 8 | q[hl + 2], cnt = (uint32_t)q[hl + 3] << 8 | q[hl + 4];
    if (m->last_request < m->stall_until || m->last_request < m->silent_until) { m->mc.unanswered++; return; }
    const uint64_t k = m->mc.requests;
    if (m->d->o.die_after && k > m->d->o.die_after) {   /* a device that dies: gone, no goodbye */
        sim_write_atomic(m->d->o.report, report_body, m);
        _exit(9);
    }
    update_header(m);
    if (m->d->o.exc_every && k % m->d->o.exc_every == 0) {
        m->mc.exceptions++;
        modbus_reply_exception(m->mb, q, (unsigned)m->d->o.exc_code);
        return;
    }
    if (m->d->o.delay_every && k % m->d->o.delay_every == 0) {
        m->mc.delayed++;
        sleep_s(m, 1e-3 * (double)m->d->o.delay_ms);
    }
    if (m->rtu && m->d->o.emulate_baud) {
        const double rq = fc == 16 ? 9.0 + 2 * cnt : 8.0, rp = (fc == 3 || fc == 4) ? 5.0 + 2 * cnt : 8.0;
        const double t35 = m->d->o.baud > 19200 ? 1.75e-3 : 35.0 / m->d->o.baud;
        sleep_s(m, (rq + rp) * 10.0 / m->d->o.baud + 2 * t35);
    }
    if (m->rtu && m->d->o.corrupt_every && k % m->d->o.corrupt_every == 0 && (fc == 3 || fc == 4) && send_corrupt(m, q, hl, addr, cnt)) {
        m->mc.corrupted++;
        return;
    }
    const int hostile = hostile_reply(m, q, len, hl, k, fc, addr, cnt);
    if (!hostile && modbus_reply(m->mb, q, len, &m->map) < 0) return;
    m->mc.replies++;
    if (m->d->o.answer_twice && modbus_reply(m->mb, q, len, &m->map) >= 0) {   /* adversarial: a duplicate */
        m->mc.replies++;
        m->mc.duplicated++;
    }
    if (fc == 4 && !(hostile & HOSTILE_UNUSABLE) && addr + cnt > MSID_MB_RING_ADDR && m->W && m->R) {
        const uint32_t a = addr > MSID_MB_RING_ADDR ? addr - MSID_MB_RING_ADDR : 0;
        const uint32_t b = addr + cnt - MSID_MB_RING_ADDR;
        for (uint32_t slot = a / m->W; slot < m->R && slot * m->W < b; ++slot)
            if (slot * m->W >= a && (slot + 1) * m->W <= b) m->served[slot] = 1;   /* whole samples only */
    }
    if (fc == 16 || fc == 6) {
        const uint32_t end = fc == 6 ? addr + 1 : addr + cnt;
        if (addr <= MSID_MB_HR_CMD_SEQ && end > MSID_MB_HR_CMD_SEQ && m->hr[MSID_MB_HR_CMD_SEQ] != m->cmd_done) {
            m->cmd_done = m->hr[MSID_MB_HR_CMD_SEQ];
            execute(m);
        }
        if (addr <= MSID_MB_HR_CFG_SEQ && end > MSID_MB_HR_CFG_SEQ && m->hr[MSID_MB_HR_CFG_SEQ] != m->cfg_done) {
            m->cfg_done = m->hr[MSID_MB_HR_CFG_SEQ];
            if (m->mstate != MSID_MB_STATE_RUNNING) apply_records(m);
        }
    }
}

static void open_server(sim_mb *m)
{
    m->map.nb_registers = MSID_MB_HR_EXT_COUNT;
    m->map.tab_registers = m->hr;
    m->map.nb_input_registers = 65536;
    m->map.tab_input_registers = m->ir;
    static uint8_t bits[1];
    m->map.tab_bits = m->map.tab_input_bits = bits;
    sim_mb_server_open(&m->srv, &m->d->o, m->d->o.unit);
    m->mb = m->srv.mb;
    m->rtu = m->srv.rtu;
    if (m->rtu)
        printf("msid-devsim: ready on modbus-rtu %s (%u baud%s, unit %u, %u input(s), %u output(s), %s plant)\n",
               m->d->o.mb_rtu, m->d->o.baud, m->d->o.emulate_baud ? " emulated" : "", m->d->o.unit, m->d->pd.nu, m->d->pd.ny,
               m->d->pd.ct ? "continuous-time" : "discrete-time");
    else
        printf("msid-devsim: ready on modbus-tcp %s:%u (%u input(s), %u output(s), %s plant)\n", m->srv.host,
               m->srv.port, m->d->pd.nu, m->d->pd.ny, m->d->pd.ct ? "continuous-time" : "discrete-time");
    fflush(stdout);
}

static void serve_cb(void *ctx, const uint8_t *q, int len) { serve(ctx, q, len); }

int sim_modbus_main(sim_device *d)
{
    static sim_mb ctx;
    sim_mb *m = &ctx;
    memset(m, 0, sizeof *m);
    m->d = d;
    m->est.bad = -1;
    signal(SIGPIPE, SIG_IGN);
    open_server(m);
    m->last_request = sim_now_s();
    m->mstate = MSID_MB_STATE_IDLE;
    while (!*m->d->stop) {
        const double next = produce(m);
        int tmo = next < 0 ? 200 : (int)(next * 1000.0);
        if (m->mstate == MSID_MB_STATE_RUNNING && next < 0) tmo = 20;
        if (tmo > 200) tmo = 200;
        sim_mb_server_poll(&m->srv, tmo, serve_cb, m);
        if (m->d->o.idle_exit > 0 && sim_now_s() - m->last_request > m->d->o.idle_exit) break;
    }
    sim_write_atomic(m->d->o.report, report_body, m);
    sim_mb_server_close(&m->srv);
    return 0;
}
