/* The Modbus client and ring poller (daq/src/msid_mb_acq.c) against the real device simulator over
 * Modbus TCP on 127.0.0.1 (msid-devsim --modbus-tcp, libmodbus on both ends): identify, configure,
 * START, poll every experiment of a 2x2 design into a real msid_meas, and the FRF from msid_frf equals
 * the simulator's true FRF (its --truth file, noise off) to float32 resolution; the transposed truth
 * (negative control) does not. Device errors come back decoded (-MSID_DAQ_E_DEVICE and the device's
 * error name), and a measurement that refuses samples comes back as the core's own status
 * (msid_daq_core(MSID_E_CAPACITY)), not as a bad argument. MSID_DEVSIM names the simulator (ctest sets it). */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "msid/msid.h"
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_modbus.h"
#include "msid_daq/msid_params.h"

extern char **environ;

#define P 128u
#define K 4u
#define NU 2u
#define NY 2u
#define L 4u
static const uint32_t BINS[L] = {1, 3, 5, 7};

/* ---- the simulator ---- */
typedef struct sim {
    pid_t pid;
    int port;
    char truth[256];
} sim;

static int sim_start(sim *s, const char *extra)
{
    const char *bin = getenv("MSID_DEVSIM");
    if (!bin) { fprintf(stderr, "MSID_DEVSIM is not set\n"); return -1; }
    snprintf(s->truth, sizeof s->truth, "/tmp/test_mb_acq.%d.truth.json", (int)getpid());
    int fd[2];
    if (pipe(fd) != 0) return -1;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fd[1], 1);
    posix_spawn_file_actions_addclose(&fa, fd[0]);
    /* a cross build runs the simulator through MSID_EMULATOR ("qemu-aarch64 -L ..."): its words first */
    char emu[256] = "";
    const char *e = getenv("MSID_EMULATOR");
    if (e) snprintf(emu, sizeof emu, "%s", e);
    char *argv[32];
    int n = 0;
    for (char *w = strtok(emu, " "); w && n < 8; w = strtok(NULL, " ")) argv[n++] = w;
    const char *prog = n ? argv[0] : bin;
    argv[n++] = (char *)bin;
    argv[n++] = "--modbus-tcp"; argv[n++] = "127.0.0.1:0";
    argv[n++] = "--noise-y"; argv[n++] = "0";
    argv[n++] = "--noise-u"; argv[n++] = "0";
    argv[n++] = "--idle-exit"; argv[n++] = "30";
    argv[n++] = "--truth"; argv[n++] = s->truth;
    if (extra) { argv[n++] = (char *)extra; }
    argv[n] = NULL;
    const int r = posix_spawnp(&s->pid, prog, &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    close(fd[1]);
    if (r != 0) { close(fd[0]); return -1; }
    /* the ready line, within 20 s */
    char line[512];
    size_t k = 0;
    struct pollfd p = {fd[0], POLLIN, 0};
    while (k + 1 < sizeof line && poll(&p, 1, 20000) == 1) {
        if (read(fd[0], line + k, 1) != 1) break;
        if (line[k++] == '\n') break;
    }
    line[k] = 0;
    close(fd[0]);
    const char *at = strstr(line, "127.0.0.1:");
    if (!strstr(line, "ready") || !at) { fprintf(stderr, "msid-devsim did not start: %s\n", line); return -1; }
    s->port = atoi(at + 10);
    return 0;
}

static void sim_stop(sim *s)
{
    kill(s->pid, SIGTERM);
    int st;
    waitpid(s->pid, &st, 0);
    unlink(s->truth);
}

/* The true G of the truth file: [L][NY][NU] (msid-devsim-truth/1: per line "re": [[..],[..]], "im": ...). */
static int read_truth(const char *path, msid_cplx *G)
{
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    static char text[1 << 16];
    const size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    const char *p = text;
    for (uint32_t l = 0; l < L; ++l) {
        for (int part = 0; part < 2; ++part) {
            p = strstr(p, part ? "\"im\": [" : "\"re\": [");
            if (!p) return -1;
            p += 7;
            for (uint32_t k = 0; k < NY * NU; ++k) {
                while (*p && strchr("[], ", *p)) ++p;
                char *end;
                const double v = strtod(p, &end);
                if (end == p) return -1;
                p = end;
                if (part) G[l * NY * NU + k].im = v;
                else G[l * NY * NU + k].re = v;
            }
        }
    }
    return 0;
}

/* ---- the host ---- */
static uint8_t TWM[1 << 16] __attribute__((aligned(64)));
static uint8_t MM[1 << 21] __attribute__((aligned(64)));
static uint8_t QM[1 << 16] __attribute__((aligned(64)));
static uint8_t FM[1 << 18] __attribute__((aligned(64)));
static msid_params CFG;
static uint8_t REC[1024][8];

typedef struct host {
    msid_modbus m;
    msid_mb_client cl;
    msid_twiddle tw;
    msid_meas ms;
    msid_mb_acq q;
} host;
static host H;

static void connect_to(const sim *s)
{
    msid_modbus_cfg c;
    memset(&c, 0, sizeof c);
    c.host = "127.0.0.1";
    c.port = s->port;
    c.unit = 1;
    c.response_timeout_ms = 2000;   /* generous: the machine may be busy */
    c.byte_timeout_ms = 500;
    assert_int_equal(msid_modbus_open(&H.m, &c), 0);
    msid_mb_client_init(&H.cl, &H.m.tr, 5, 20);
}

/* A fresh simulator, connected and identified. */
static void open_device_with(sim *s, const char *extra)
{
    assert_int_equal(sim_start(s, extra), 0);
    connect_to(s);
    assert_int_equal(msid_mb_identify(&H.cl), 0);
}

static void open_device(sim *s) { open_device_with(s, NULL); }

static void close_device(sim *s)
{
    msid_mb_close(&H.m.tr);
    sim_stop(s);
}

static size_t params(uint32_t n_inputs)
{
    memset(&CFG, 0, sizeof CFG);
    CFG.period = P; CFG.n_lines = L; CFG.n_inputs = n_inputs; CFG.n_experiments = NU;
    CFG.pattern = MSID_PATTERN_DFT; CFG.phase_mode = MSID_PHASE_RANDOM; CFG.seed = 11;
    for (uint32_t l = 0; l < L; ++l) CFG.bins[l] = BINS[l];
    CFG.encoding = MSID_CAN_ENC_F32; CFG.scale = 0.001f; CFG.periods = K;
    const size_t n = msid_params_frames(&CFG, REC, 1024);
    assert_true(n > 0 && n <= 1024);
    return n;
}

static int acq_setup(uint32_t hist, uint32_t skip)
{
    assert_int_equal(msid_twiddle_init(&H.tw, P, TWM, sizeof TWM), MSID_OK);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = NU; mc.n_outputs = NY; mc.n_experiments = NU; mc.n_lines = L; mc.bins = BINS;
    mc.twiddle = &H.tw; mc.path = MSID_DFT_STREAM; mc.transient = MSID_TRANSIENT_OFF; mc.max_periods = hist;
    mc.skip_periods = skip;
    assert_true(msid_meas_mem_size(&mc) <= sizeof MM);
    assert_int_equal(msid_meas_init(&H.ms, &mc, MM, sizeof MM), MSID_OK);
    msid_mb_acq_cfg qc;
    memset(&qc, 0, sizeof qc);
    qc.client = &H.cl; qc.n_inputs = NU; qc.n_outputs = NY; qc.encoding = MSID_MB_ENC_F32; qc.scale = 1.0;
    qc.meas = &H.ms; qc.period = P;
    return msid_mb_acq_init(&H.q, &qc, QM, sizeof QM);
}

/* Experiment e to its end through msid_mb_acq_run (10 s without a new sample is a failure). */
static int acquire(uint32_t e) { return msid_mb_acq_run(&H.q, e, K, 10000, 500); }

static double max_err(const msid_cplx *G, const msid_cplx *T, int transpose)
{
    double m = 0;
    for (uint32_t l = 0; l < L; ++l)
        for (uint32_t i = 0; i < NY; ++i)
            for (uint32_t j = 0; j < NU; ++j) {
                const msid_cplx g = G[l * NY * NU + i * NU + j];
                const msid_cplx t = T[l * NY * NU + (transpose ? j * NU + i : i * NU + j)];
                const double d = hypot(g.re - t.re, g.im - t.im) / hypot(t.re, t.im);
                if (d > m) m = d;
            }
    return m;
}

static void frf_equals_the_simulators_truth(void **st)
{
    (void)st;
    sim s;
    open_device(&s);
    assert_int_equal(H.cl.h.nu, NU);
    assert_int_equal(H.cl.h.ny, NY);
    const size_t n = params(NU);
    assert_int_equal(msid_mb_configure(&H.cl, MSID_MB_ENC_F32, MSID_MB_ABCD, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(acq_setup(4 * K, 1), 0);
    for (uint32_t e = 0; e < NU; ++e) assert_int_equal(acquire(e), 0);
    assert_true(H.q.cnt.stream_ns > 0);
    assert_int_equal(H.q.cnt.done_missing, 0);
    assert_int_equal(H.q.cnt.experiments_done, NU);
    assert_int_equal(H.q.st.cnt.samples, NU * K * P);
    assert_int_equal(H.q.st.cnt.samples_lost, 0);
    for (uint32_t e = 0; e < NU; ++e)
        assert_int_equal(msid_pstats_get_counts(msid_meas_stats(&H.ms, e)).used, K - 1);
    msid_frf_cfg fc = {P, NU, NY, NU, L, 0, NULL};
    msid_frf f;
    assert_true(msid_frf_mem_size(&fc) <= sizeof FM);
    assert_int_equal(msid_frf_init(&f, &fc, FM, sizeof FM), MSID_OK);
    const msid_pstats *ps[NU] = {msid_meas_stats(&H.ms, 0), msid_meas_stats(&H.ms, 1)};
    assert_int_equal(msid_frf_compute(&f, ps), MSID_OK);
    static msid_cplx T[L * NY * NU];
    assert_int_equal(read_truth(s.truth, T), 0);
    const double e0 = max_err(f.G, T, 0), e1 = max_err(f.G, T, 1);
    printf("max relative |G - G_true| = %.3g (transposed truth, negative control: %.3g)\n", e0, e1);
    assert_true(e0 < 1e-6);   /* noise off: float32 samples (measured 9e-8), the transient gone after 1 skipped period */
    assert_true(e1 > 1e-2);
    close_device(&s);
}

static void device_errors_are_decoded(void **st)
{
    (void)st;
    sim s;
    open_device(&s);
    /* a design for 1 input on a 2-input device */
    size_t n = params(1);
    assert_int_equal(msid_mb_configure(&H.cl, MSID_MB_ENC_F32, MSID_MB_ABCD, (const uint8_t(*)[8])REC, n),
                     -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(H.cl.err, "the design's inputs do not match the device"));
    /* START of an experiment the design does not have */
    n = params(NU);
    assert_int_equal(msid_mb_configure(&H.cl, MSID_MB_ENC_F32, MSID_MB_ABCD, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(acq_setup(4 * K, 1), 0);
    assert_int_equal(msid_mb_acq_start(&H.q, 5, K), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(H.cl.err, "experiment index out of range"));
    close_device(&s);
}

static void core_refusal_carries_the_core_status(void **st)
{
    (void)st;
    sim s;
    open_device(&s);
    const size_t n = params(NU);
    assert_int_equal(msid_mb_configure(&H.cl, MSID_MB_ENC_F32, MSID_MB_ABCD, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(acq_setup(2, 0), 0);   /* history of 2 periods: the third of K = 4 does not fit */
    const int rc = acquire(0);
    assert_int_equal(rc, msid_daq_core(MSID_E_CAPACITY));
    assert_int_equal(msid_daq_core_status(rc), MSID_E_CAPACITY);
    assert_non_null(strstr(H.cl.err, "more periods arrived than the measurement holds"));
    /* init refusals are the core's reasons too */
    msid_mb_acq q;
    msid_mb_acq_cfg qc = H.q.cfg;
    assert_int_equal(msid_mb_acq_init(&q, &qc, QM + 1, sizeof QM - 1), msid_daq_core(MSID_E_MEM_ALIGN));
    assert_int_equal(msid_mb_acq_init(&q, &qc, QM, 16), msid_daq_core(MSID_E_MEM_SIZE));
    qc.meas = NULL;
    assert_int_equal(msid_mb_acq_init(&q, &qc, QM, sizeof QM), msid_daq_core(MSID_E_NULL));
    close_device(&s);
}

/* A device that writes past K P and never reports DONE: the run closes the experiment at K P and stops it. */
static void never_done_is_closed_and_stopped(void **st)
{
    (void)st;
    sim s;
    open_device_with(&s, "--never-done");
    const size_t n = params(NU);
    assert_int_equal(msid_mb_configure(&H.cl, MSID_MB_ENC_F32, MSID_MB_ABCD, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(acq_setup(4 * K, 1), 0);
    assert_int_equal(acquire(0), 0);
    assert_int_equal(H.q.cnt.done_missing, 1);
    assert_int_equal(H.q.st.cnt.samples, K * P);
    assert_int_equal(msid_mb_read_header(&H.cl), 0);
    assert_int_not_equal(H.cl.h.state, MSID_MB_STATE_RUNNING);   /* the STOP was obeyed */
    close_device(&s);
}

/* The caller's on_poll asks to stop in the third period: the run returns -MSID_DAQ_E_STOPPED with the
   experiment closed, every complete period kept, the partial one left over, and the device stopped. */
static uint32_t g_polls;
static int stop_in_third_period(void *user)
{
    const msid_mb_acq *q = user;
    g_polls++;
    return q->st.cnt.samples > 2 * P;
}

static void poll_hook_stops_and_keeps_complete_periods(void **st)
{
    (void)st;
    sim s;
    open_device(&s);
    const size_t n = params(NU);
    assert_int_equal(msid_mb_configure(&H.cl, MSID_MB_ENC_F32, MSID_MB_ABCD, (const uint8_t(*)[8])REC, n), 0);
    assert_int_equal(acq_setup(4 * K, 1), 0);
    g_polls = 0;
    H.q.cfg.on_poll = stop_in_third_period;
    H.q.cfg.user = &H.q;
    assert_int_equal(acquire(0), -MSID_DAQ_E_STOPPED);
    assert_true(g_polls >= 1);
    assert_int_equal(H.q.open, 0);
    const uint64_t got = H.ms.samples[0];
    const msid_pstats_counts c = msid_pstats_get_counts(msid_meas_stats(&H.ms, 0));
    assert_true(got > 2 * P && got < (uint64_t)K * P);
    assert_int_equal(c.offered, got / P);                 /* every complete period */
    assert_int_equal(msid_meas_leftover(&H.ms, 0), got % P);   /* the partial one left over, counted */
    assert_int_equal(msid_mb_read_header(&H.cl), 0);
    assert_int_not_equal(H.cl.h.state, MSID_MB_STATE_RUNNING);   /* the STOP was obeyed */
    /* negative control: the same run without the hook ends normally with all K periods */
    H.q.cfg.on_poll = NULL;
    assert_int_equal(acquire(1), 0);
    assert_int_equal(msid_pstats_get_counts(msid_meas_stats(&H.ms, 1)).offered, K);
    close_device(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(frf_equals_the_simulators_truth),
        cmocka_unit_test(device_errors_are_decoded),
        cmocka_unit_test(core_refusal_carries_the_core_status),
        cmocka_unit_test(never_done_is_closed_and_stopped),
        cmocka_unit_test(poll_hook_stops_and_keeps_complete_periods),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
