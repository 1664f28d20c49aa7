/* The CAN device session (daq/src/msid_can_session.c) against a scripted msid-can/1 device behind an
 * in-memory loopback transport (the vcan VM test runs it against msid-devsim on real SocketCAN). The
 * device rebuilds the parameter set with msid_params_feed (the simulator's own code path) and streams
 * u and y = G u + e of a known static gain G through msid_can_encode_sample; the session's decoder feeds
 * a real msid_meas and msid_frf estimates G. Covered: identify, upload with flow control (every block
 * waits for the device's answer), the DONE loop, a lost DONE recovered by QUERY (and, as the negative
 * control, a device that ignores the QUERY fails as silent), device errors decoded by name, a refused
 * design with the core's reason, a version mismatch, no device, a core refusal carried as the core's
 * status, and a failing frame hook. On-device estimation (extension estimate/1) as a readout of the same
 * session: SETUP and its answer, experiments closed by the device's DONE without a decoder, the result
 * block collected bit for bit (values lost on the way asked for again while answers bring new values;
 * as the negative control, a device that always loses the same ones fails), and the device's refusals
 * (memory too small with both byte counts, a failed solve with its line, no extension, another size). */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <string.h>
#include <time.h>

#include "msid/msid.h"
#include "msid_daq/msid_can_est.h"
#include "msid_daq/msid_can_session.h"
#include "msid_daq/msid_params.h"

#define BASE 0x200u
#define P 32u
#define K 4u
#define GAIN 0.5
static const uint32_t BINS[3] = {1, 3, 5};

/* ---- the scripted device behind an in-memory transport ---- */
#define QCAP 4096
typedef struct dev {
    msid_can_frame q[QCAP];   /* device -> host */
    size_t head, tail;
    msid_params cfg;
    int present, version, configured, running;
    int drop_done;            /* 1: the DONE frame of an experiment is lost */
    int ignore_query;         /* 1: QUERY is not answered */
    int refuse_design;        /* COMMIT answered with ERR_DESIGN (value MSID_E_PERIOD) */
    uint32_t max_pending;     /* most host frames the device ever had to hold unanswered (flow control) */
    uint32_t pending;
    uint32_t state, exp, n_sent;
    uint64_t host_frames;
    uint32_t stops;           /* STOP commands received */
    /* extension estimate/1 */
    int est;                  /* 1: the device has it */
    uint32_t est_mode;        /* 1: estimate only (no sample frames) */
    uint32_t est_refuse;      /* msid_status SETUP answers with (0: accumulating) */
    uint32_t solve_fail, solve_bad1;   /* msid_status SOLVE answers with, bad line + 1 */
    uint32_t est_n;           /* doubles in the result block */
    int lose;                 /* SOLVE answers that lose every 7th value (-1: all of them) */
    int lose_shift;           /* 1: answer i loses the values k % 7 == (3 + i) % 7 (others each time) */
    uint32_t solves;
} dev;
static dev D;

static void put(dev *d, uint32_t off, const uint8_t *data, uint32_t len)
{
    assert_true(d->tail - d->head < QCAP);
    msid_can_frame *f = &d->q[d->tail++ % QCAP];
    memset(f, 0, sizeof *f);
    f->id = BASE + off;
    f->len = (uint8_t)len;
    memcpy(f->data, data, len);
}

static void put_state(dev *d, uint32_t state, uint32_t e, uint32_t err, uint32_t value)
{
    uint8_t b[8];
    msid_can_encode_state(b, state, e, err, value);
    put(d, MSID_CAN_ID_STATUS, b, 8);
}

static void put_info(dev *d)
{
    uint8_t b[8];
    msid_can_encode_info(b, (uint32_t)d->version, 1, 1, d->configured ? d->cfg.crc : 0);
    put(d, MSID_CAN_ID_STATUS, b, 8);
}

/* Sample n of the bench: u a multisine of the design's lines, y = GAIN u + small deterministic noise. */
static void row_of(uint32_t n, double *r)
{
    const double ph = 6.283185307179586 * (double)(n % P) / P;
    r[0] = cos(ph) + cos(3 * ph + 1) + cos(5 * ph + 2);
    r[1] = GAIN * r[0] + 1e-3 * ((double)((n * 7919u) % 13u) - 6.0);
}

static void run_experiment(dev *d, uint32_t e, uint32_t periods)
{
    d->running = 1;
    d->exp = e;
    put_state(d, MSID_CAN_STATE_RUNNING, e, 0, 0);
    for (uint32_t n = 0; n < periods * P && d->est_mode != 1; ++n) {
        double r[2];
        row_of(n, r);
        for (uint32_t k = 0; k < msid_can_chunks(2, MSID_CAN_ENC_F32, 0); ++k) {
            uint8_t b[8];
            msid_can_encode_sample(b, MSID_CAN_ENC_F32, 0, k, n, e,
                                   (n % P == 0 ? MSID_CAN_PSTART : 0u) | (n == 0 ? MSID_CAN_SEGSTART : 0u), r, 2, 0.001);
            put(d, msid_can_chunk_id(MSID_CAN_ENC_F32, 0, k), b, 8);
        }
    }
    d->n_sent = periods * P;
    d->running = 0;
    d->state = MSID_CAN_STATE_DONE;
    if (!d->drop_done) put_state(d, MSID_CAN_STATE_DONE, e, 0, d->n_sent);
}

/* Value k of the scripted result block: exact binary fractions, negative ones and a subnormal. */
static double est_value(uint32_t k) { return k == 5 ? 4.9e-324 : 0.25 * (double)k - 3.0; }

static void put_est_state(dev *d, uint32_t state, uint32_t status, uint32_t bad1)
{
    uint8_t b[8];
    msid_can_est_encode_state(b, state, d->est_mode, status, bad1);
    put(d, MSID_CAN_ID_EST, b, 8);
}

static void est_rx(dev *d, const uint8_t *c)
{
    uint8_t b[8], h[8];
    if (c[0] == MSID_CAN_EST_CMD_SETUP) {
        d->est_mode = d->est_refuse ? 0 : c[1];
        put_est_state(d, d->est_refuse ? MSID_CAN_EST_STATE_ERROR : MSID_CAN_EST_STATE_ACCUMULATING, d->est_refuse, 0);
        const uint32_t v[3][2] = {{MSID_CAN_EST_MUX_NEED, 5000}, {MSID_CAN_EST_MUX_HAVE, 4096}, {MSID_CAN_EST_MUX_PERIODS, 0}};
        for (int i = 0; i < 3; ++i) {
            msid_can_est_encode_u32(b, v[i][0], v[i][1]);
            put(d, MSID_CAN_ID_EST, b, 8);
        }
    } else if (c[0] == MSID_CAN_EST_CMD_SOLVE) {
        d->solves++;
        if (d->solve_fail) { put_est_state(d, MSID_CAN_EST_STATE_ERROR, d->solve_fail, d->solve_bad1); return; }
        put_est_state(d, MSID_CAN_EST_STATE_READY, 0, 0);
        msid_can_est_encode_u32(b, MSID_CAN_EST_MUX_SIZE, d->est_n);
        put(d, MSID_CAN_ID_EST, b, 8);
        const int lose = d->lose < 0 || d->solves <= (uint32_t)d->lose;
        for (uint32_t k = 0; k < d->est_n; ++k) {
            msid_can_est_encode_value(b, h, k, est_value(k));
            if (lose && k % 7 == (d->lose_shift ? (3 + d->solves) % 7 : 3)) continue;
            put(d, MSID_CAN_ID_EST, b, 8);
            put(d, MSID_CAN_ID_EST, h, 8);
        }
        put_est_state(d, MSID_CAN_EST_STATE_READY, 0, 0);
    }
}

static void device_rx(dev *d, const msid_can_frame *f)
{
    d->host_frames++;
    if (!d->present) return;
    if (f->id == BASE + MSID_CAN_ID_EST_CTRL) {
        if (d->est) est_rx(d, f->data);   /* a device without the extension ignores the identifier */
        return;
    }
    if (f->id == BASE + MSID_CAN_ID_CFG) {
        d->pending++;
        if (d->pending > d->max_pending) d->max_pending = d->pending;
        const int r = msid_params_feed(&d->cfg, f->data, f->len, (uint32_t)d->version);
        if (r == 1) {
            d->configured = !d->refuse_design;
            d->state = d->refuse_design ? MSID_CAN_STATE_ERROR : MSID_CAN_STATE_CONFIGURED;
            put_info(d);
            put_state(d, d->state, 0, d->refuse_design ? MSID_CAN_ERR_DESIGN : 0,
                      d->refuse_design ? (uint32_t)MSID_E_PERIOD : 0);
        } else if (r < 0) {
            d->state = MSID_CAN_STATE_ERROR;
            put_state(d, d->state, 0, (uint32_t)-r, 0);
        }
        return;
    }
    if (f->id != BASE + MSID_CAN_ID_CTRL) return;
    d->pending = 0;   /* a CTRL frame: the device has consumed every CFG frame before it */
    switch (f->data[0]) {
    case MSID_CAN_CMD_QUERY:
        if (d->ignore_query) return;
        put_info(d);
        put_state(d, d->state, d->exp, 0, d->n_sent);
        return;
    case MSID_CAN_CMD_START: {
        const uint32_t e = f->data[1];
        if (!d->configured) { put_state(d, MSID_CAN_STATE_ERROR, e, MSID_CAN_ERR_NOT_CONFIGURED, 0); return; }
        if (e >= d->cfg.n_experiments) { put_state(d, MSID_CAN_STATE_ERROR, e, MSID_CAN_ERR_EXPERIMENT, 0); return; }
        run_experiment(d, e, msid_can_get_u32(f->data + 4));
        return;
    }
    case MSID_CAN_CMD_STOP:
        d->stops++;
        return;
    default:
        return;
    }
}

static int lb_recv(void *ctx, msid_can_frame *f, int n, int timeout_ms)
{
    dev *d = ctx;
    if (d->head == d->tail) {
        /* nothing queued: wait a little (bounded), as a socket would */
        const struct timespec t = {0, (timeout_ms > 0 ? (timeout_ms < 2 ? timeout_ms : 2) : 0) * 1000000L};
        nanosleep(&t, NULL);
        return -MSID_DAQ_E_TIMEOUT;
    }
    int k = 0;
    while (k < n && d->head != d->tail) f[k++] = d->q[d->head++ % QCAP];
    return k;
}
static int lb_send(void *ctx, const msid_can_frame *f, int timeout_ms)
{
    (void)timeout_ms;
    device_rx(ctx, f);
    return 0;
}
static void lb_stats(void *ctx, msid_can_link_stats *s) { (void)ctx; memset(s, 0, sizeof *s); }
static const char *lb_error(void *ctx) { (void)ctx; return "loopback"; }
static void lb_close(void *ctx) { (void)ctx; }
static const msid_can_backend LOOPBACK = {"loopback", lb_recv, lb_send, lb_stats, lb_error, lb_close};

/* ---- the host side ---- */
static uint8_t TWM[1 << 14] __attribute__((aligned(64)));
static uint8_t MM[1 << 20] __attribute__((aligned(64)));
static uint8_t DM[1 << 18] __attribute__((aligned(64)));
static uint8_t FM[1 << 18] __attribute__((aligned(64)));
static msid_can_session S;
static msid_params CFG;
static uint8_t REC[512][8];

typedef struct host {
    msid_can_transport tr;
    msid_twiddle tw;
    msid_meas ms;
    msid_can_decoder dec;
    uint64_t tx_seen, rx_seen;
    int fail_hook_after;      /* > 0: the hook fails at that frame */
} host;
static host H;

static int hook(void *user, const msid_can_frame *f)
{
    host *h = user;
    if (f->flags & MSID_CANF_TX) h->tx_seen++;
    else h->rx_seen++;
    return h->fail_hook_after && h->tx_seen + h->rx_seen >= (uint64_t)h->fail_hook_after ? -1 : 0;
}

static void reset_all(void)
{
    memset(&D, 0, sizeof D);
    D.present = 1;
    D.version = MSID_CAN_PROTO_VERSION;
    D.state = MSID_CAN_STATE_IDLE;
    msid_params_reset(&D.cfg);
    memset(&H, 0, sizeof H);
    H.tr.be = &LOOPBACK;
    H.tr.ctx = &D;
    msid_can_session_cfg c;
    memset(&c, 0, sizeof c);
    c.tr = &H.tr;
    c.base = BASE;
    c.query_ms = 20;
    c.silence_ms = 10000;   /* a busy machine may stall this process: only the negative control waits it out */
    c.reply_timeout_ms = 500;
    c.upload_block = 8;
    c.on_frame = hook;
    c.user = &H;
    assert_int_equal(msid_can_session_init(&S, &c), 0);
}

/* The parameter set (1 input, 3 lines, random phases, 2 experiments) as CFG records; returns their count. */
static size_t params(void)
{
    memset(&CFG, 0, sizeof CFG);
    CFG.period = P; CFG.n_lines = 3; CFG.n_inputs = 1; CFG.n_experiments = 2;
    CFG.pattern = MSID_PATTERN_DFT; CFG.phase_mode = MSID_PHASE_RANDOM; CFG.seed = 7;
    for (uint32_t l = 0; l < 3; ++l) CFG.bins[l] = BINS[l];
    CFG.encoding = MSID_CAN_ENC_F32; CFG.scale = 0.001f; CFG.fd = 0; CFG.periods = K;
    const size_t n = msid_params_frames(&CFG, REC, 512);
    assert_true(n > 16 && n <= 512);
    return n;
}

/* Decoder and measurement for 1 x 1, m experiments, `hist` periods of history. */
static void attach(uint32_t m, uint32_t hist)
{
    assert_int_equal(msid_twiddle_init(&H.tw, P, TWM, sizeof TWM), MSID_OK);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = m; mc.n_lines = 3; mc.bins = BINS;
    mc.twiddle = &H.tw; mc.path = MSID_DFT_STREAM; mc.transient = MSID_TRANSIENT_OFF; mc.max_periods = hist;
    assert_int_equal(msid_meas_init(&H.ms, &mc, MM, sizeof MM), MSID_OK);
    msid_can_decoder_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.base = BASE; dc.n_inputs = 1; dc.n_outputs = 1; dc.encoding = MSID_CAN_ENC_F32; dc.fd = 0; dc.scale = 0.001;
    dc.period = P; dc.window = 16; dc.meas = &H.ms; dc.samples_total = (uint64_t)K * P;
    assert_int_equal(msid_can_decoder_init(&H.dec, &dc, DM, sizeof DM), MSID_OK);
    assert_int_equal(msid_can_session_attach(&S, &H.dec), 0);
}

/* The FRF of experiment 0 at every line: GAIN within 5e-3 (noise of std 3.7e-3 on a unit multisine, K = 4). */
static void frf_is_the_gain(void)
{
    msid_frf_cfg fc = {P, 1, 1, 1, 3, 0, NULL};
    msid_frf f;
    assert_int_equal(msid_frf_init(&f, &fc, FM, sizeof FM), MSID_OK);
    const msid_pstats *ps[1] = {msid_meas_stats(&H.ms, 0)};
    assert_int_equal(msid_frf_compute(&f, ps), MSID_OK);
    for (uint32_t l = 0; l < 3; ++l) {
        assert_true(fabs(f.G[l].re - GAIN) < 5e-3);
        assert_true(fabs(f.G[l].im) < 5e-3);
    }
}

static void full_session(void **st)
{
    (void)st;
    reset_all();
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    assert_int_equal(S.dev.version, MSID_CAN_PROTO_VERSION);
    assert_int_equal(S.dev.nu, 1);
    assert_int_equal(S.dev.ny, 1);
    attach(2, 2 * K);
    assert_int_equal(H.dec.cnt.status_frames, 2);   /* the identification frames (INFO, STATE) were fed to the decoder */
    const size_t n = params();
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(S.crc, D.cfg.crc);
    assert_true(D.max_pending <= 8);                 /* flow control: never more than a block unanswered */
    for (uint32_t e = 0; e < 2; ++e) assert_int_equal(msid_can_session_run(&S, e, K), 0);
    assert_int_equal(H.dec.cnt.experiments_done, 2);
    assert_int_equal(H.dec.cnt.samples, 2 * K * P);
    assert_int_equal(H.dec.cnt.samples_lost, 0);
    assert_int_equal(S.cnt.done_recovered, 0);
    assert_int_equal(msid_pstats_get_counts(msid_meas_stats(&H.ms, 0)).used, K);
    frf_is_the_gain();
    /* the hook saw every frame: what the session sent, what the device sent */
    assert_int_equal(H.tx_seen, S.cnt.frames_sent);
    assert_int_equal(H.tx_seen, D.host_frames);
    assert_int_equal(H.rx_seen, D.tail);
}

static void lost_done_is_recovered_by_query(void **st)
{
    (void)st;
    reset_all();
    D.drop_done = 1;
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    attach(2, 2 * K);
    const size_t n = params();
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(msid_can_session_run(&S, 0, K), 0);
    assert_int_equal(S.cnt.done_recovered, 1);
    assert_true(S.cnt.recovery_queries >= 1);
    assert_int_equal(H.dec.cnt.experiments_done, 1);
    assert_int_equal(H.dec.cnt.samples, K * P);
    assert_int_equal(H.dec.cnt.samples_lost, 0);
    assert_int_equal(msid_pstats_get_counts(msid_meas_stats(&H.ms, 0)).used, K);
    frf_is_the_gain();

    /* negative control: the same lost DONE with a device that does not answer QUERY is a silent device */
    reset_all();
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    attach(2, 2 * K);
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), 0);
    D.drop_done = 1;
    D.ignore_query = 1;
    S.cfg.silence_ms = 300;
    assert_int_equal(msid_can_session_run(&S, 0, K), -MSID_DAQ_E_TIMEOUT);
    assert_non_null(strstr(S.err, "went silent"));
    assert_non_null(strstr(S.err, "experiment 1"));
    assert_int_equal(S.cnt.done_recovered, 0);
    assert_true(S.cnt.recovery_queries >= 2);
}

static void device_errors_are_decoded(void **st)
{
    (void)st;
    /* START of an experiment the device does not have */
    reset_all();
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    attach(3, 2 * K);
    size_t n = params();
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(msid_can_session_run(&S, 2, K), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(S.err, "experiment index out of range"));
    assert_non_null(strstr(S.err, "experiment 3"));

    /* a refused design: the device's reason and the core's */
    reset_all();
    D.refuse_design = 1;
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    attach(2, 2 * K);
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(S.err, "the device refused the design"));
    assert_non_null(strstr(S.err, msid_strerror(MSID_E_PERIOD)));

    /* a lost CFG frame: the device's CRC check refuses, the session names it */
    reset_all();
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    attach(2, 2 * K);
    memcpy(REC[5], REC[6], 8);   /* frame 5 replaced: the running CRC differs */
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(S.err, "configuration CRC mismatch"));
}

static void identify_failures(void **st)
{
    (void)st;
    reset_all();
    D.version = 2;
    assert_int_equal(msid_can_session_identify(&S, 2000), -MSID_DAQ_E_PROTOCOL);
    assert_non_null(strstr(S.err, "msid-can/2"));
    reset_all();
    D.present = 0;
    assert_int_equal(msid_can_session_identify(&S, 50), -MSID_DAQ_E_TIMEOUT);
    assert_non_null(strstr(S.err, "no msid-can device answered at base 0x200"));
    msid_can_session_cfg c;
    memset(&c, 0, sizeof c);
    c.tr = &H.tr;
    c.base = 0x201;
    assert_int_equal(msid_can_session_init(&S, &c), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_can_session_run(NULL, 0, K), -MSID_DAQ_E_ARG);
}

static void core_refusal_carries_the_core_status(void **st)
{
    (void)st;
    reset_all();
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    attach(2, 2);   /* history of 2 periods: the third period of K = 4 does not fit */
    const size_t n = params();
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), 0);
    const int rc = msid_can_session_run(&S, 0, K);
    assert_int_equal(rc, msid_daq_core(MSID_E_CAPACITY));
    assert_int_equal(msid_daq_core_status(rc), MSID_E_CAPACITY);
    assert_string_equal(msid_daq_message(rc), msid_strerror(MSID_E_CAPACITY));
    assert_non_null(strstr(S.err, "more periods arrived than the measurement holds"));
    /* the daq space keeps its own statuses apart */
    assert_int_equal(msid_daq_core_status(-MSID_DAQ_E_TIMEOUT), MSID_OK);
    assert_int_equal(msid_daq_core(MSID_OK), 0);
    assert_string_equal(msid_daq_message(-MSID_DAQ_E_DEVICE), "the device reported an error");
}

static void failing_hook_stops_the_session(void **st)
{
    (void)st;
    reset_all();
    H.fail_hook_after = 2;   /* the QUERY is logged, the first answer cannot be */
    assert_int_equal(msid_can_session_identify(&S, 2000), -MSID_DAQ_E_HOOK);
}

/* The caller's on_poll asks to stop once a period and a bit arrived: -MSID_DAQ_E_STOPPED, the experiment
   closed in the decoder, every complete period kept, the device sent STOP. */
static uint32_t g_polls;
static int stop_after_a_period(void *user)
{
    const host *h = user;
    g_polls++;
    return h->dec.cnt.samples > P;
}

static void poll_hook_stops_the_experiment(void **st)
{
    (void)st;
    reset_all();
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    attach(2, 2 * K);
    const size_t n = params();
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), 0);
    g_polls = 0;
    S.cfg.on_poll = stop_after_a_period;
    S.cfg.poll_user = &H;
    assert_int_equal(msid_can_session_run(&S, 0, K), -MSID_DAQ_E_STOPPED);
    assert_true(g_polls >= 1);
    assert_int_equal(H.dec.open, 0);
    assert_int_equal(D.stops, 1);
    const uint64_t got = H.ms.samples[0];
    assert_true(got > P && got < (uint64_t)K * P);
    assert_int_equal(msid_pstats_get_counts(msid_meas_stats(&H.ms, 0)).offered, got / P);
    assert_int_equal(msid_meas_leftover(&H.ms, 0), got % P);
    /* negative control: without the hook the next experiment runs to its DONE (the scripted device queued
       all of experiment 1 at START; a real one stops sending: its queue is dropped here) */
    D.head = D.tail;
    S.cfg.on_poll = NULL;
    assert_int_equal(msid_can_session_run(&S, 1, K), 0);
    assert_int_equal(msid_pstats_get_counts(msid_meas_stats(&H.ms, 1)).offered, K);
}

/* Identify and upload, no decoder (estimate only). */
static void est_device(void)
{
    reset_all();
    D.est = 1;
    D.est_n = 50;
    assert_int_equal(msid_can_session_identify(&S, 2000), 0);
    const size_t n = params();
    assert_int_equal(msid_can_session_upload(&S, (const uint8_t(*)[8])REC, n), 0);
}

static void est_only_session(void **st)
{
    (void)st;
    est_device();
    D.lose = 1;   /* the first SOLVE's answer loses every 7th value */
    assert_int_equal(msid_can_session_est_setup(&S, 1, 1, 1, 0.01), 0);
    assert_int_equal(S.est.state, MSID_CAN_EST_STATE_ACCUMULATING);
    assert_int_equal(S.est.version, MSID_CAN_EST_VERSION);
    assert_int_equal(S.est.need, 5000);
    for (uint32_t e = 0; e < 2; ++e) assert_int_equal(msid_can_session_run(&S, e, K), 0);   /* closed by DONE */
    assert_int_equal(S.dones, 2);
    assert_int_equal(S.cnt.done_recovered, 0);
    double v[50];
    uint8_t got[50];
    assert_int_equal(msid_can_session_est_solve(&S, v, got, 50), 0);
    assert_int_equal(S.cnt.est_solves, 2);   /* the lost values were asked for again */
    for (uint32_t k = 0; k < 50; ++k) assert_memory_equal(&v[k], &(double){est_value(k)}, sizeof(double));
    /* a device losing other values on each of the first 5 answers: asked again while answers bring new values */
    D.lose = 5;
    D.solves = 0;
    D.lose_shift = 1;
    S.cnt.est_solves = 0;
    memset(v, 0, sizeof v);
    assert_int_equal(msid_can_session_est_solve(&S, v, got, 50), 0);
    assert_int_equal(S.cnt.est_solves, 2);   /* the second answer lost other values than the first */
    for (uint32_t k = 0; k < 50; ++k) assert_memory_equal(&v[k], &(double){est_value(k)}, sizeof(double));
    /* negative control: a device that loses the same values on every answer fails once an answer brings none */
    D.lose = -1;
    D.lose_shift = 0;
    S.cnt.est_solves = 0;
    assert_int_equal(msid_can_session_est_solve(&S, v, got, 50), -MSID_DAQ_E_PROTOCOL);
    assert_int_equal(S.cnt.est_solves, 2);
    assert_non_null(strstr(S.err, "7 of the 50 values"));
}

static void est_refusals(void **st)
{
    (void)st;
    /* the estimator's memory is too small: the status and both byte counts */
    est_device();
    D.est_refuse = MSID_E_MEM_SIZE;
    assert_int_equal(msid_can_session_est_setup(&S, 1, 0, 0, 0.01), -MSID_DAQ_E_DEVICE);
    assert_int_equal(S.est.status, MSID_E_MEM_SIZE);
    assert_non_null(strstr(S.err, "msid_status 2"));
    assert_non_null(strstr(S.err, "needs 5000 bytes of working memory, it has 4096"));
    /* a failed solve: its status and line */
    est_device();
    D.solve_fail = MSID_E_SINGULAR;
    D.solve_bad1 = 2;
    assert_int_equal(msid_can_session_est_setup(&S, 1, 0, 0, 0.01), 0);
    double v[50];
    uint8_t got[50];
    assert_int_equal(msid_can_session_est_solve(&S, v, got, 50), -MSID_DAQ_E_DEVICE);
    assert_int_equal(S.est.status, MSID_E_SINGULAR);
    assert_int_equal(S.est.bad1, 2);
    /* a block of another size than the design's */
    est_device();
    assert_int_equal(msid_can_session_est_setup(&S, 1, 0, 0, 0.01), 0);
    assert_int_equal(msid_can_session_est_solve(&S, v, got, 49), -MSID_DAQ_E_PROTOCOL);
    assert_non_null(strstr(S.err, "holds 50 doubles, the design's holds 49"));
    /* a device without the extension does not answer SETUP */
    est_device();
    D.est = 0;
    assert_int_equal(msid_can_session_est_setup(&S, 1, 0, 0, 0.01), -MSID_DAQ_E_PROTOCOL);
    assert_non_null(strstr(S.err, "does not estimate on board"));
    assert_int_equal(msid_can_session_est_setup(&S, 3, 0, 0, 0.01), -MSID_DAQ_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(full_session),
        cmocka_unit_test(lost_done_is_recovered_by_query),
        cmocka_unit_test(device_errors_are_decoded),
        cmocka_unit_test(identify_failures),
        cmocka_unit_test(core_refusal_carries_the_core_status),
        cmocka_unit_test(failing_hook_stops_the_session),
        cmocka_unit_test(poll_hook_stops_the_experiment),
        cmocka_unit_test(est_only_session),
        cmocka_unit_test(est_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
