/* msid-devsim main loop: a CAN device that receives a design as parameters,
 * regenerates the multisine with lib/, drives a simulated plant and streams
 * [u; y] in msid-can/1 sample frames, with optional fault injection. */
#define _GNU_SOURCE
#include "devsim.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* ---- fixed memory ------------------------------------------------------ */
static _Alignas(64) uint8_t arena[48u << 20];
static size_t arena_used;
static void *take(size_t n)
{
    n = (n + 63u) / 64u * 64u;
    if (n == 0 || n > sizeof arena - arena_used) return NULL;
    void *p = arena + arena_used;
    arena_used += n;
    return p;
}

sim_opts O;
sim_plant_def PD;
msid_params CFG;
static sim_counts CNT;
static msid_socketcan CAN;
volatile sig_atomic_t stop_flag;

/* design state (rebuilt at every commit) */
int configured;
static msid_twiddle TW;
msid_design DES;
static msid_gen GEN;
static msid_plant PL;
static msid_cplx *GL;         /* [L * ny*nu] true response at each line (what the FRF file holds) */
static msid_cplx *PH;         /* [L * ny] output phasors of the running experiment (CT plant) */
static double ar_state[MSID_MAX_OUTPUTS];
static msid_rng RNG;

/* run state */
static int state = MSID_CAN_STATE_BOOT, running_exp = -1;
uint64_t n_sample, n_total;                /* sample index in the segment, samples per segment */
static uint64_t fc;                        /* frame counter */
static uint64_t busoff_left;
static int busoff_done, restart_done;
static msid_can_frame held;                /* reorder: frame held back */
static int have_held;
struct timespec t_start;
static double last_host_frame;

double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void die(const char *m)
{
    fprintf(stderr, "msid-devsim: error: %s\n", m);
    exit(1);
}

static void tx(const msid_can_frame *f)
{
    int r = CAN.tr.be->send(CAN.tr.ctx, f, 1000);
    if (r < 0) {
        CNT.tx_busy++;
        if (r != -MSID_DAQ_E_BUSY) {
            fprintf(stderr, "msid-devsim: error: send: %s\n", CAN.tr.be->error(CAN.tr.ctx));
            exit(1);
        }
        return;
    }
    CNT.frames_sent++;
}

static void tx8(uint32_t off, const uint8_t d[8])
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = O.base + off;
    f.len = 8;
    memcpy(f.data, d, 8);
    tx(&f);
}

static void send_state(uint32_t st, uint32_t e, uint32_t err, uint32_t val)
{
    uint8_t d[8];
    msid_can_encode_state(d, st, e, err, val);
    tx8(MSID_CAN_ID_STATUS, d);
}

static void send_info(void)
{
    uint8_t d[8];
    msid_can_encode_info(d, O.version, PD.nu, PD.ny, configured ? CFG.crc : 0);
    tx8(MSID_CAN_ID_STATUS, d);
}

static void send_counters(void)
{
    uint8_t d[8];
    msid_can_encode_counters(d, 0, 0, (uint32_t)CNT.restarts, (uint32_t)CNT.tx_busy);
    tx8(MSID_CAN_ID_STATUS, d);
}

static void send_error_frame(uint32_t cls, uint8_t ctrl, uint8_t prot)
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = MSID_CAN_ERR_FLAG | cls;
    f.len = 8;
    f.data[1] = ctrl;
    f.data[2] = prot;
    tx(&f);
    CNT.error_frames++;
}

/* ---- reports ------------------------------------------------------------ */
void sim_write_atomic(const char *path, void (*body)(FILE *))
{
    if (!path) return;
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp.%d", path, (int)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f) { fprintf(stderr, "msid-devsim: error: cannot write '%s': %s\n", path, strerror(errno)); exit(1); }
    body(f);
    if (fclose(f) != 0 || rename(tmp, path) != 0) {
        fprintf(stderr, "msid-devsim: error: cannot write '%s'\n", path);
        exit(1);
    }
}

static void truth_body(FILE *f)
{
    const uint32_t L = DES.n_lines, nu = PD.nu, ny = PD.ny;
    fprintf(f, "{\"format\": \"msid-devsim-truth/1\", \"period_samples\": %u, \"n_inputs\": %u, \"n_outputs\": %u,\n",
            DES.period, nu, ny);
    fprintf(f, " \"plant\": \"%s\", \"sigma_y\": %.17g, \"sigma_u\": %.17g, \"color\": %.17g, \"config_crc\": %u,\n \"lines\": [",
            PD.ct ? "ct" : "dt", O.sigma_y, O.sigma_u, O.color, CFG.crc);
    for (uint32_t l = 0; l < L; ++l) {
        fprintf(f, "%s\n  {\"bin\": %u, \"G\": {\"re\": [", l ? "," : "", DES.bins[l]);
        for (int part = 0; part < 2; ++part) {
            if (part) fprintf(f, "], \"im\": [");
            for (uint32_t i = 0; i < ny; ++i) {
                fprintf(f, "%s[", i ? ", " : "");
                for (uint32_t j = 0; j < nu; ++j) {
                    const msid_cplx g = GL[(size_t)l * ny * nu + i * nu + j];
                    fprintf(f, "%s%.17g", j ? ", " : "", part ? g.im : g.re);
                }
                fprintf(f, "]");
            }
        }
        fprintf(f, "]}}");
    }
    fprintf(f, "\n ]}\n");
}

static void report_body(FILE *f)
{
    fprintf(f, "{\"format\": \"msid-devsim-report/1\", \"protocol_version\": %u, \"config_crc\": %u,\n", O.version,
            configured ? CFG.crc : 0);
    fprintf(f, " \"frames_sent\": %llu, \"sample_frames\": %llu, \"samples\": %llu, \"experiments_done\": %u,\n",
            (unsigned long long)CNT.frames_sent, (unsigned long long)CNT.sample_frames, (unsigned long long)CNT.samples,
            CNT.experiments_done);
    fprintf(f, " \"injected\": {\"dropped\": %llu, \"duplicated\": %llu, \"reordered\": %llu, \"malformed\": %llu, "
               "\"error_frames\": %llu, \"bus_off\": %llu, \"busoff_samples\": %llu, \"restarts\": %llu},\n",
            (unsigned long long)CNT.dropped, (unsigned long long)CNT.duplicated, (unsigned long long)CNT.reordered,
            (unsigned long long)CNT.malformed, (unsigned long long)CNT.error_frames, (unsigned long long)CNT.bus_off,
            (unsigned long long)CNT.busoff_samples, (unsigned long long)CNT.restarts);
    fprintf(f, " \"rate_hz\": %u, \"paced_waits\": %llu, \"late_samples\": %llu, \"early_samples\": %llu,\n",
            configured ? CFG.rate_hz : 0, (unsigned long long)CNT.paced_waits, (unsigned long long)CNT.late_samples,
            (unsigned long long)CNT.early_samples);
    fprintf(f, " \"tx_busy\": %llu, \"send_retries\": %llu}\n", (unsigned long long)CNT.tx_busy,
            (unsigned long long)CAN.st.send_retries);
}

/* ---- configuration ------------------------------------------------------ */
uint32_t sim_configure(uint32_t *mstatus)
{
    configured = 0;
    arena_used = 0;
    *mstatus = 0;
    if (CFG.n_inputs != PD.nu) return MSID_CAN_ERR_DIMS;
    const uint32_t P = CFG.period;
    if (P < MSID_MIN_PERIOD || P > MSID_MAX_PERIOD) { *mstatus = MSID_E_PERIOD; return MSID_CAN_ERR_DESIGN; }
    size_t n = msid_twiddle_mem_size(P);
    void *m = take(n);
    if (!m) { *mstatus = MSID_E_MEM_SIZE; return MSID_CAN_ERR_DESIGN; }
    msid_status st = msid_twiddle_init(&TW, P, m, n);
    if (st) { *mstatus = st; return MSID_CAN_ERR_DESIGN; }
    msid_design_cfg dc;
    msid_params_design_cfg(&CFG, &dc, &TW);
    n = msid_design_mem_size(&dc);
    m = n ? take(n) : NULL;
    if (!m) { *mstatus = n ? MSID_E_MEM_SIZE : MSID_E_DIMS; return MSID_CAN_ERR_DESIGN; }
    st = msid_design_init(&DES, &dc, m, n);
    if (st) { *mstatus = st; return MSID_CAN_ERR_DESIGN; }
    const uint32_t L = DES.n_lines, nu = PD.nu, ny = PD.ny;
    GL = take(sizeof(msid_cplx) * L * nu * ny);
    PH = take(sizeof(msid_cplx) * L * ny);
    if (!GL || !PH) { *mstatus = MSID_E_MEM_SIZE; return MSID_CAN_ERR_DESIGN; }
    if (PD.ct && !DES.is_ct && !(PD.h > 0)) { *mstatus = MSID_E_SAMPLE_TIME; return MSID_CAN_ERR_DESIGN; }
    for (uint32_t l = 0; l < L; ++l) {
        /* CT plant: rad/s; DT plant: rad/sample (a folded CT line keeps its unfolded frequency) */
        double w;
        if (PD.ct) w = DES.is_ct ? DES.omega[l] : 2 * M_PI * DES.bins[l] / ((double)P * PD.h);
        else w = DES.is_ct ? DES.omega[l] * DES.sample_time : 2 * M_PI * DES.bins[l] / (double)P;
        if (sim_plant_response(&PD, w, GL + (size_t)l * nu * ny) != 0) { *mstatus = MSID_E_SINGULAR; return MSID_CAN_ERR_DESIGN; }
    }
    if (!PD.ct) {
        msid_plant_cfg pc = {PD.n, nu, ny, PD.A, PD.B, PD.C, PD.D};
        n = msid_plant_mem_size(&pc);
        m = take(n);
        if (!m || msid_plant_init(&PL, &pc, m, n) != MSID_OK) { *mstatus = MSID_E_DIMS; return MSID_CAN_ERR_DESIGN; }
    }
    configured = 1;
    sim_write_atomic(O.truth, truth_body);
    return MSID_CAN_ERR_NONE;
}

int sim_start(uint32_t e, uint32_t periods)
{
    if (!configured) return MSID_CAN_ERR_NOT_CONFIGURED;
    if (e >= DES.n_experiments) return MSID_CAN_ERR_EXPERIMENT;
    msid_gen_cfg gc = {&DES, &TW, e, 0};
    const size_t n = msid_gen_mem_size(&gc);
    static void *gm;
    static size_t gn;
    if (n > gn) { gm = take(n); gn = n; }
    if (!gm || msid_gen_init(&GEN, &gc, gm, gn) != MSID_OK) return MSID_CAN_ERR_DESIGN;
    const uint32_t L = DES.n_lines, nu = PD.nu, ny = PD.ny;
    if (PD.ct) {
        /* output phasor per line: G'(l) c_l, G' conjugated where the line folded */
        for (uint32_t l = 0; l < L; ++l)
            for (uint32_t i = 0; i < ny; ++i) {
                double re = 0, im = 0;
                for (uint32_t j = 0; j < nu; ++j) {
                    msid_cplx g = GL[(size_t)l * nu * ny + i * nu + j];
                    if (DES.is_ct && DES.folded[l]) g.im = -g.im;
                    const msid_cplx c = msid_design_coef(&DES, e, j, l);
                    re += g.re * c.re - g.im * c.im;
                    im += g.re * c.im + g.im * c.re;
                }
                PH[(size_t)l * ny + i].re = re;
                PH[(size_t)l * ny + i].im = im;
            }
    }
    msid_rng_seed(&RNG, O.seed * 0x9E3779B97F4A7C15ull + e + 1);
    memset(ar_state, 0, sizeof ar_state);
    n_sample = 0;
    n_total = (uint64_t)(periods ? periods : CFG.periods) * DES.period;
    clock_gettime(CLOCK_MONOTONIC, &t_start);
    return 0;
}

/* The device restarts (watchdog): it keeps its configuration (retained RAM) and the
   experiment starts again from sample 0; the plant keeps its state. */
void sim_restart_segment(void)
{
    msid_gen_seek(&GEN, 0);
    n_sample = 0;
}

static int start(uint32_t e, uint32_t periods)
{
    const int err = sim_start(e, periods);
    if (err) return err;
    running_exp = (int)e;
    busoff_done = restart_done = 0;
    busoff_left = 0;
    state = MSID_CAN_STATE_RUNNING;
    send_state(MSID_CAN_STATE_RUNNING, e, 0, (uint32_t)n_total);
    return 0;
}

static void flush_held(void)
{
    if (have_held) { tx(&held); have_held = 0; }
}

static void handle_host_frame(const msid_can_frame *f)
{
    last_host_frame = now_s();
    if (f->id == O.base + MSID_CAN_ID_CFG) {
        if (state == MSID_CAN_STATE_RUNNING) return;   /* ignored while running */
        const int r = msid_params_feed(&CFG, f->data, f->len, O.version);
        if (r < 0) {
            configured = 0;
            state = MSID_CAN_STATE_ERROR;
            send_state(MSID_CAN_STATE_ERROR, 0, (uint32_t)-r, 0);
            if (r == -MSID_CAN_ERR_VERSION) send_info();
        } else if (r == 1) {
            uint32_t ms = 0, err;
            if (CFG.fd && !CAN.fd_frames) { configured = 0; err = MSID_CAN_ERR_CFG; }   /* FD on a classic-only bus */
            else err = sim_configure(&ms);
            state = err ? MSID_CAN_STATE_ERROR : MSID_CAN_STATE_CONFIGURED;
            send_info();
            send_state((uint32_t)state, 0, err, ms);
        }
        return;
    }
    if (f->id != O.base + MSID_CAN_ID_CTRL || f->len != 8) return;
    const uint8_t *d = f->data;
    if (d[2] != O.version) {
        send_info();
        send_state(MSID_CAN_STATE_ERROR, 0, MSID_CAN_ERR_VERSION, d[2]);
        return;
    }
    switch (d[0]) {
    case MSID_CAN_CMD_START: {
        if (state == MSID_CAN_STATE_RUNNING) return;
        const int err = start(d[1], msid_can_get_u32(d + 4));
        if (err) send_state(MSID_CAN_STATE_ERROR, d[1], (uint32_t)err, 0);
        break;
    }
    case MSID_CAN_CMD_STOP:
        if (state == MSID_CAN_STATE_RUNNING) {
            flush_held();
            state = MSID_CAN_STATE_CONFIGURED;
            send_state(MSID_CAN_STATE_IDLE, (uint32_t)running_exp, 0, (uint32_t)n_sample);
        }
        break;
    case MSID_CAN_CMD_RESET:
        flush_held();
        configured = 0;
        msid_params_reset(&CFG);
        state = MSID_CAN_STATE_IDLE;
        send_state(MSID_CAN_STATE_IDLE, 0, 0, 0);
        break;
    case MSID_CAN_CMD_QUERY:
        send_info();
        send_state((uint32_t)state, running_exp < 0 ? 0 : (uint32_t)running_exp, 0, (uint32_t)n_sample);
        send_counters();
        break;
    default:
        break;
    }
}

static void poll_host(int timeout_ms)
{
    msid_can_frame fr[16];
    int k = CAN.tr.be->recv(CAN.tr.ctx, fr, 16, timeout_ms);
    if (k == -MSID_DAQ_E_TIMEOUT) return;
    if (k < 0) {
        fprintf(stderr, "msid-devsim: error: receive: %s\n", CAN.tr.be->error(CAN.tr.ctx));
        exit(1);
    }
    for (int i = 0; i < k; ++i) handle_host_frame(&fr[i]);
}

/* ---- sample production ---------------------------------------------------- */
static void send_sample_frame(msid_can_frame *f)
{
    ++fc;
    CNT.sample_frames++;
    if (busoff_left) return;   /* counted in busoff_samples */
    if ((O.drop_every && fc % O.drop_every == 0) ||
        (O.drop_frac > 0 && msid_rng_uniform(&RNG) < O.drop_frac)) {
        CNT.dropped++;
        return;
    }
    if (O.malformed_every && fc % O.malformed_every == 0) {
        f->len = (uint8_t)(CFG.fd ? 12 : 5);   /* wrong DLC for a sample frame */
        CNT.malformed++;
    }
    if (O.error_every && fc % O.error_every == 0) {
        static const uint32_t cls[4] = {0x004u, 0x004u, 0x008u, 0x020u};   /* CRTL warning, CRTL passive, PROT, ACK */
        static const uint8_t ctl[4] = {0x04u, 0x10u, 0, 0};
        const uint64_t k = (fc / O.error_every - 1) % 4;
        send_error_frame(cls[k], ctl[k], k == 2 ? 0x08u : 0);
        if (k == 3) send_error_frame(0x004u, 0x40u, 0);   /* back to error-active */
    }
    if (have_held) {
        tx(f);
        flush_held();
        return;
    }
    if (O.reorder_every && fc % O.reorder_every == 0) {
        held = *f;
        have_held = 1;
        CNT.reordered++;
        return;
    }
    tx(f);
    if (O.dup_every && fc % O.dup_every == 0) {
        tx(f);
        CNT.duplicated++;
    }
}

/* The row [u; y] of sample n_sample: excitation from lib/, plant, noise. */
void sim_row(double *row)
{
    const uint32_t nu = PD.nu, ny = PD.ny, P = DES.period;
    double u[MSID_MAX_INPUTS];
    msid_gen_next(&GEN, u);
    if (PD.ct) {
        const uint32_t L = DES.n_lines;
        for (uint32_t i = 0; i < ny; ++i) row[nu + i] = 0;
        for (uint32_t l = 0; l < L; ++l) {
            const msid_cplx w = TW.w[(uint64_t)DES.bins[l] * (n_sample % P) % P];   /* e^{-j 2 pi b n / P} */
            for (uint32_t i = 0; i < ny; ++i) {
                const msid_cplx d = PH[(size_t)l * ny + i];
                row[nu + i] += d.re * w.re + d.im * w.im;   /* Re{d e^{+j 2 pi b n / P}} */
            }
        }
    } else {
        msid_plant_step(&PL, u, row + nu);
    }
    for (uint32_t i = 0; i < ny; ++i) {
        ar_state[i] = O.color * ar_state[i] + O.sigma_y * msid_rng_normal(&RNG);
        row[nu + i] += ar_state[i];
    }
    for (uint32_t j = 0; j < nu; ++j) row[j] = u[j] + (O.sigma_u > 0 ? O.sigma_u * msid_rng_normal(&RNG) : 0.0);
}

static void produce_sample(void)
{
    const uint32_t C = PD.nu + PD.ny, P = DES.period;
    double row[MSID_MAX_CHANNELS];
    sim_row(row);
    const uint32_t flags = (n_sample % P == 0 ? MSID_CAN_PSTART : 0u) | (n_sample == 0 ? MSID_CAN_SEGSTART : 0u);
    const uint32_t chunks = msid_can_chunks(C, CFG.encoding, CFG.fd);
    for (uint32_t k = 0; k < chunks; ++k) {
        msid_can_frame f;
        memset(&f, 0, sizeof f);
        f.id = O.base + msid_can_chunk_id(CFG.encoding, CFG.fd, k);
        f.len = (uint8_t)msid_can_sample_len(CFG.fd);
        f.flags = CFG.fd ? (MSID_CANF_FD | MSID_CANF_BRS) : 0;
        msid_can_encode_sample(f.data, CFG.encoding, CFG.fd, k, (uint32_t)n_sample, (uint32_t)running_exp, flags, row,
                               C, (double)CFG.scale);
        send_sample_frame(&f);
    }
    if (busoff_left && --busoff_left == 0) send_error_frame(0x100u, 0, 0);   /* CAN_ERR_RESTARTED */
    CNT.samples++;
    n_sample++;
}

static void run_step(void)
{
    const int e = running_exp;
    if (O.restart_exp == e && !restart_done && n_sample == O.restart_at) {
        /* watchdog reset: the firmware reboots, keeps its configuration (retained RAM) and
           restarts the experiment from sample 0; the plant keeps its state */
        restart_done = 1;
        flush_held();
        CNT.restarts++;
        send_state(MSID_CAN_STATE_BOOT, (uint32_t)e, 0, 0);
        send_state(MSID_CAN_STATE_RUNNING, (uint32_t)e, 0, (uint32_t)n_total);
        sim_restart_segment();
        clock_gettime(CLOCK_MONOTONIC, &t_start);
    }
    if (O.busoff_exp == e && !busoff_done && n_sample == O.busoff_at) {
        busoff_done = 1;
        flush_held();
        send_error_frame(0x040u, 0, 0);   /* CAN_ERR_BUSOFF */
        CNT.bus_off++;
        busoff_left = O.busoff_len ? O.busoff_len : 1;
        CNT.busoff_samples += busoff_left;
    }
    produce_sample();
    if (n_sample >= n_total) {
        flush_held();
        state = MSID_CAN_STATE_DONE;
        CNT.experiments_done++;
        send_counters();
        send_state(MSID_CAN_STATE_DONE, (uint32_t)e, 0, (uint32_t)n_sample);
        sim_write_atomic(O.report, report_body);
        state = MSID_CAN_STATE_CONFIGURED;
    }
}

/* ---- command line ------------------------------------------------------- */
static const char *USAGE =
    "usage: msid-devsim --iface IF [options]\n"
    "  --iface IF            CAN interface (vcan0)\n"
    "  --base ID             base identifier, a multiple of 0x80 (default 0x200)\n"
    "  --plant FILE|builtin  plant (default: the built-in 4-state 2x2 DT plant)\n"
    "  --noise-y S           output noise std (default 0.05)   --noise-u S  input measurement noise std (0.002)\n"
    "  --noise-color A       AR(1) pole of the output noise, [0, 1) (0: white)\n"
    "  --seed N              noise seed (default 1)\n"
    "  --truth FILE          write the true FRF at the excited lines after each configuration\n"
    "  --report FILE         write counters (and injected faults) after each experiment and at exit\n"
    "  --drop-every K | --drop-frac F   drop every K-th sample frame, or each with probability F\n"
    "  --dup-every K         send every K-th sample frame twice\n"
    "  --reorder-every K     send every K-th sample frame after the next one\n"
    "  --malformed-every K   send every K-th sample frame with a wrong DLC\n"
    "  --error-every K       send an error frame (warning, passive, protocol, ack) after every K-th frame\n"
    "  --bus-off-at E:N[:D]  go bus-off at sample N of experiment E (0-based) for D samples (default 1), then restart\n"
    "  --restart-at E:N      restart the device at sample N of experiment E\n"
    "  --protocol-version V  pretend to speak protocol version V (tests)\n"
    "  --idle-exit S         exit after S seconds without host frames (default 0: never)\n"
    "  --rcvbuf BYTES        socket receive buffer\n"
    "Modbus device (msid-modbus/1, docs/modbus-registers.md) instead of CAN:\n"
    "  --modbus-tcp HOST:PORT | --modbus-rtu DEVICE   serve over Modbus TCP, or RTU on a serial port/pty\n"
    "  --baud N              RTU baud rate (default 115200)   --unit N  unit id (default 1)\n"
    "  --no-baud-emulation   RTU: reply at once (default: after the frames' wire time at --baud)\n"
    "  --ring N              ring capacity in samples (default: as many as the register map holds)\n"
    "  --delay-every K:MS    answer every K-th request MS ms late\n"
    "  --exception-every K[:CODE]  answer every K-th request with exception CODE (default 6, busy)\n"
    "  --corrupt-every K     RTU: send every K-th reply with a bad CRC\n"
    "  --drop-at E:N         drop the connection (RTU: 1 s of silence) at sample N of experiment E\n"
    "  --stall-at E:N:D[:MS] at sample N of experiment E stop answering for MS ms (default 300) and write\n"
    "                        D samples regardless of the host, so the ring overruns\n"
    "  --never-done          (adversarial) write samples past K P and never report DONE\n"
    "  --answer-twice        (adversarial) send every reply twice\n"
    "  --index-back-at E:N   (adversarial) from sample N of experiment E report a write index 16 samples back\n"
    "  --restart-at E:N, --seed, --noise-*, --plant, --truth, --report, --idle-exit: as for CAN\n";

static uint64_t num_u(const char *opt, const char *v)
{
    char *e;
    errno = 0;
    const unsigned long long x = strtoull(v, &e, 0);
    if (!*v || *e || errno || v[0] == '-') {
        fprintf(stderr, "msid-devsim: error: %s: '%s' is not a non-negative integer\n", opt, v);
        exit(2);
    }
    return x;
}

static double num_d(const char *opt, const char *v, double lo, double hi)
{
    char *e;
    const double x = strtod(v, &e);
    if (!*v || *e || !(x >= lo && x <= hi)) {
        fprintf(stderr, "msid-devsim: error: %s: '%s' must be a number in [%g, %g]\n", opt, v, lo, hi);
        exit(2);
    }
    return x;
}

static void pair(const char *opt, const char *v, int *e, uint64_t *n, uint64_t *d)
{
    char buf[64];
    snprintf(buf, sizeof buf, "%s", v);
    char *a = strtok(buf, ":"), *b = strtok(NULL, ":"), *c = strtok(NULL, ":");
    if (!a || !b || (!d && c)) {
        fprintf(stderr, "msid-devsim: error: %s wants E:N%s (got '%s')\n", opt, d ? "[:D]" : "", v);
        exit(2);
    }
    *e = (int)num_u(opt, a);
    *n = num_u(opt, b);
    if (d) *d = c ? num_u(opt, c) : 1;
}

/* K:V or K (V = def) */
static void kv(const char *opt, const char *v, uint64_t *k, uint64_t *val, uint64_t def)
{
    char buf[64];
    snprintf(buf, sizeof buf, "%s", v);
    char *a = strtok(buf, ":"), *b = strtok(NULL, ":"), *c = strtok(NULL, ":");
    if (!a || c || (!b && def == UINT64_MAX)) {
        fprintf(stderr, "msid-devsim: error: %s wants K:%s (got '%s')\n", opt, def == UINT64_MAX ? "V" : "[V]", v);
        exit(2);
    }
    *k = num_u(opt, a);
    *val = b ? num_u(opt, b) : def;
}

static void on_signal(int s) { (void)s; stop_flag = 1; }

static void load_plant(const char *plant)
{
    if (!strcmp(plant, "builtin")) sim_builtin_plant(&PD);
    else {
        char err[512];
        if (sim_parse_plant(plant, &PD, err, sizeof err) != 0) die(err);
    }
}

int main(int argc, char **argv)
{
    O.base = MSID_CAN_DEFAULT_BASE;
    O.version = MSID_CAN_PROTO_VERSION;
    O.seed = 1;
    O.sigma_y = 0.05;
    O.sigma_u = 0.002;
    O.busoff_exp = O.restart_exp = O.drop_exp = O.stall_exp = O.back_exp = -1;
    O.baud = 115200;
    O.unit = 1;
    O.emulate_baud = 1;
    const char *plant = "builtin";
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) { fputs(USAGE, stdout); return 0; }
        if (!strcmp(a, "--no-baud-emulation")) { O.emulate_baud = 0; continue; }
        if (!strcmp(a, "--never-done")) { O.never_done = 1; continue; }
        if (!strcmp(a, "--answer-twice")) { O.answer_twice = 1; continue; }
        if (i + 1 >= argc) { fprintf(stderr, "msid-devsim: error: unknown option or missing value: %s\n%s", a, USAGE); return 2; }
        const char *v = argv[++i];
        if (!strcmp(a, "--iface")) O.iface = v;
        else if (!strcmp(a, "--base")) O.base = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--plant")) plant = v;
        else if (!strcmp(a, "--noise-y")) O.sigma_y = num_d(a, v, 0, 1e6);
        else if (!strcmp(a, "--noise-u")) O.sigma_u = num_d(a, v, 0, 1e6);
        else if (!strcmp(a, "--noise-color")) O.color = num_d(a, v, 0, 0.999999);
        else if (!strcmp(a, "--seed")) O.seed = num_u(a, v);
        else if (!strcmp(a, "--truth")) O.truth = v;
        else if (!strcmp(a, "--report")) O.report = v;
        else if (!strcmp(a, "--drop-every")) O.drop_every = num_u(a, v);
        else if (!strcmp(a, "--drop-frac")) O.drop_frac = num_d(a, v, 0, 1);
        else if (!strcmp(a, "--dup-every")) O.dup_every = num_u(a, v);
        else if (!strcmp(a, "--reorder-every")) O.reorder_every = num_u(a, v);
        else if (!strcmp(a, "--malformed-every")) O.malformed_every = num_u(a, v);
        else if (!strcmp(a, "--error-every")) O.error_every = num_u(a, v);
        else if (!strcmp(a, "--bus-off-at")) pair(a, v, &O.busoff_exp, &O.busoff_at, &O.busoff_len);
        else if (!strcmp(a, "--restart-at")) pair(a, v, &O.restart_exp, &O.restart_at, NULL);
        else if (!strcmp(a, "--protocol-version")) O.version = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--idle-exit")) O.idle_exit = num_d(a, v, 0, 1e9);
        else if (!strcmp(a, "--rcvbuf")) O.rcvbuf = (int)num_u(a, v);
        else if (!strcmp(a, "--modbus-tcp")) O.mb_tcp = v;
        else if (!strcmp(a, "--modbus-rtu")) O.mb_rtu = v;
        else if (!strcmp(a, "--baud")) O.baud = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--unit")) O.unit = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--ring")) O.ring = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--delay-every")) kv(a, v, &O.delay_every, &O.delay_ms, UINT64_MAX);
        else if (!strcmp(a, "--exception-every")) kv(a, v, &O.exc_every, &O.exc_code, 6);
        else if (!strcmp(a, "--corrupt-every")) O.corrupt_every = num_u(a, v);
        else if (!strcmp(a, "--drop-at")) pair(a, v, &O.drop_exp, &O.drop_at, NULL);
        else if (!strcmp(a, "--index-back-at")) pair(a, v, &O.back_exp, &O.back_at, NULL);
        else if (!strcmp(a, "--stall-at")) {
            uint64_t d4[4] = {0, 0, 0, 300};
            char buf[64];
            snprintf(buf, sizeof buf, "%s", v);
            int k = 0;
            for (char *t = strtok(buf, ":"); t && k < 5; t = strtok(NULL, ":")) d4[k < 4 ? k : 3] = num_u(a, t), ++k;
            if (k < 3 || k > 4) { fprintf(stderr, "msid-devsim: error: --stall-at wants E:N:D[:MS] (got '%s')\n", v); return 2; }
            O.stall_exp = (int)d4[0]; O.stall_at = d4[1]; O.stall_samples = d4[2]; O.stall_ms = d4[3];
        }
        else { fprintf(stderr, "msid-devsim: error: unknown option %s\n%s", a, USAGE); return 2; }
    }
    if (O.mb_tcp || O.mb_rtu) {
        if (O.iface || (O.mb_tcp && O.mb_rtu)) die("give one of --iface, --modbus-tcp, --modbus-rtu");
        load_plant(plant);
        signal(SIGTERM, on_signal);
        signal(SIGINT, on_signal);
        return sim_modbus_main();
    }
    if (!O.iface) { fprintf(stderr, "msid-devsim: error: missing --iface\n%s", USAGE); return 2; }
    if ((O.base & 0x7F) || O.base > 0x780) die("--base must be a multiple of 0x80 up to 0x780");
    if (O.version > 255) die("--protocol-version must be 0..255");
    load_plant(plant);
    msid_socketcan_cfg sc;
    memset(&sc, 0, sizeof sc);
    sc.iface = O.iface;
    sc.fd_frames = 1;
    sc.n_filters = 1;
    sc.filter_id[0] = O.base;                       /* CTRL and CFG only */
    sc.filter_mask[0] = 0x7FEu | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
    sc.rcvbuf = O.rcvbuf;
    int r = msid_socketcan_open(&CAN, &sc);
    if (r == -MSID_DAQ_E_NOFD) { sc.fd_frames = 0; r = msid_socketcan_open(&CAN, &sc); }
    if (r < 0) die(CAN.err);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    printf("msid-devsim: ready on %s (base 0x%X, %s, %u input(s), %u output(s), %s plant)\n", O.iface, O.base,
           CAN.fd_frames ? "CAN FD" : "classic CAN", PD.nu, PD.ny, PD.ct ? "continuous-time" : "discrete-time");
    fflush(stdout);
    last_host_frame = now_s();
    send_info();
    state = MSID_CAN_STATE_IDLE;
    send_state(MSID_CAN_STATE_IDLE, 0, 0, 0);
    while (!stop_flag) {
        if (state == MSID_CAN_STATE_RUNNING) {
            if (CFG.rate_hz) {
                struct timespec dl = t_start;
                const uint64_t ns = n_sample * 1000000000ull / CFG.rate_hz;
                dl.tv_sec += (time_t)(ns / 1000000000ull);
                dl.tv_nsec += (long)(ns % 1000000000ull);
                if (dl.tv_nsec >= 1000000000L) { dl.tv_sec++; dl.tv_nsec -= 1000000000L; }
                struct timespec now;
                clock_gettime(CLOCK_MONOTONIC, &now);
                if (now.tv_sec < dl.tv_sec || (now.tv_sec == dl.tv_sec && now.tv_nsec < dl.tv_nsec)) CNT.paced_waits++;
                else CNT.late_samples++;   /* behind its clock (a loaded machine): sent at once */
                while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &dl, NULL) == EINTR && !stop_flag) {}
                clock_gettime(CLOCK_MONOTONIC, &now);
                if (now.tv_sec < dl.tv_sec || (now.tv_sec == dl.tv_sec && now.tv_nsec < dl.tv_nsec)) CNT.early_samples++;
            }
            if ((n_sample & 63) == 0) poll_host(0);
            if (state == MSID_CAN_STATE_RUNNING) run_step();
        } else {
            poll_host(200);
            if (O.idle_exit > 0 && now_s() - last_host_frame > O.idle_exit) break;
        }
    }
    sim_write_atomic(O.report, report_body);
    CAN.tr.be->close(CAN.tr.ctx);
    return 0;
}
