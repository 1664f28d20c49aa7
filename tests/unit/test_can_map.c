/* A CAN description resolved against its DBC (daq/src/msid_can_map.c): payloads packed and decoded against
 * bytes written out by hand, every refusal of a description that cannot work, and the tick backend's samples,
 * gaps and counters against a scripted device behind an in-memory transport (no kernel needed; the real bus is
 * tested in the vcan VM). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "msid/msid.h"
#include "msid_daq/msid_can_map.h"
#include "msid_daq/msid_devdesc_file.h"
#include "msid_daq/msid_hx.h"

static const char DBC[] =
    "VERSION \"\"\n"
    "NS_ :\n\tSIG_VALTYPE_\n"
    "BS_:\n"
    "BU_: HOST DRIVE\n"
    "BO_ 257 Cmd: 8 HOST\n"
    " SG_ TorqueCmd : 0|16@1- (0.001,0) [-3|3] \"N m\" DRIVE\n"
    " SG_ Enable : 16|1@1+ (1,0) [0|1] \"\" DRIVE\n"
    " SG_ SpeedLim : 24|8@1+ (1,0) [0|0] \"rad/s\" DRIVE\n"
    "BO_ 258 MuxCmd: 8 HOST\n"
    " SG_ Sel M : 0|8@1+ (1,0) [0|0] \"\" DRIVE\n"
    " SG_ GainA m1 : 8|16@1+ (0.01,0) [0|0] \"\" DRIVE\n"
    " SG_ GainB m2 : 8|16@1+ (0.01,0) [0|0] \"\" DRIVE\n"
    "BO_ 385 Status: 8 DRIVE\n"
    " SG_ Speed : 7|16@0- (0.01,0) [0|0] \"rad/s\" HOST\n"
    " SG_ Torque : 16|32@1- (1,0) [0|0] \"N m\" HOST\n"
    " SG_ Count : 48|8@1+ (1,0) [0|0] \"\" HOST\n"
    "BO_ 386 Echo: 8 DRIVE\n"
    " SG_ EchoCmd : 0|16@1- (0.001,0) [0|0] \"N m\" HOST\n"
    "SIG_VALTYPE_ 385 Torque : 1;\n";

static uint64_t dbc_mem[4096];
static msid_dbc dbc;

static int setup(void **state)
{
    (void)state;
    assert_true(msid_dbc_mem_size(DBC, sizeof DBC - 1) <= sizeof dbc_mem);
    if (msid_dbc_init(&dbc, DBC, sizeof DBC - 1, dbc_mem, sizeof dbc_mem) != 0) fail_msg("%s", dbc.err);
    return 0;
}

static const char HEAD[] = "format = \"msid-device/1\"\ntransport = \"can\"\ndbc = \"dev.dbc\"\n";

static const char GOOD[] =
    "[[drive]]\nname = \"Torque command\"\nunit = \"N m\"\nmessage = \"Cmd\"\nsignal = \"TorqueCmd\"\n"
    "min = -2.0\nmax = 2.0\nsafe = 0.0\n"
    "[[measure]]\nname = \"Torque\"\nrole = \"input\"\nmessage = \"Status\"\nsignal = \"Torque\"\n"
    "[[measure]]\nname = \"Speed\"\nrole = \"output\"\nmessage = \"Status\"\nsignal = \"Speed\"\nscale = 2.0\n"
    "offset = 1.0\n"
    "[[measure]]\nname = \"Count\"\nrole = \"counter\"\nmessage = \"Status\"\nsignal = \"Count\"\n";

static msid_devdesc desc;
static msid_can_map map;

/* Parse HEAD + body; return msid_can_map_init's code (map.err says why). */
static int resolve(const char *body)
{
    char text[4096], err[512];
    snprintf(text, sizeof text, "%s%s", HEAD, body);
    if (msid_devdesc_parse(text, strlen(text), "dev.toml", &desc, err, sizeof err) != 0) fail_msg("%s", err);
    return msid_can_map_init(&map, &desc, &dbc, NULL);
}

static void expect_refused(const char *body, const char *needle)
{
    const int rc = resolve(body);
    if (rc != -MSID_DAQ_E_ARG) fail_msg("rc %d: %s\n%s", rc, map.err, body);
    if (!strstr(map.err, needle)) fail_msg("'%s' does not say '%s'", map.err, needle);
}

/* The drive value packed into its command message: Intel 16-bit signed, factor 0.001; the other signals raw 0. */
static void test_pack(void **state)
{
    (void)state;
    if (resolve(GOOD) != 0) fail_msg("%s", map.err);
    assert_int_equal(map.n_cmd, 1);
    assert_int_equal(map.n_st, 1);
    assert_int_equal(map.cmd[0].m->id, 257);
    double v = 1.234;
    assert_int_equal(msid_can_map_pack(&map, &v), 0);
    const uint8_t want[8] = {0xD2, 0x04, 0, 0, 0, 0, 0, 0};   /* 1234 */
    assert_memory_equal(map.cmd[0].data, want, 8);
    v = -0.5;   /* -500 = 0xFE0C */
    assert_int_equal(msid_can_map_pack(&map, &v), 0);
    assert_int_equal(map.cmd[0].data[0], 0x0C);
    assert_int_equal(map.cmd[0].data[1], 0xFE);
    /* outside the DBC's range [-3, 3]: refused, the payload as it was */
    v = 3.5;
    assert_int_equal(msid_can_map_pack(&map, &v), -MSID_DAQ_E_RANGE);
    assert_non_null(strstr(map.err, "Cmd.TorqueCmd"));
    assert_int_equal(map.cmd[0].data[0], 0x0C);
    assert_int_equal(map.cmd[0].data[1], 0xFE);
}

/* Status payload: Motorola 16-bit signed (then the description's scale and offset), Intel float32, a counter raw. */
static void test_decode(void **state)
{
    (void)state;
    if (resolve(GOOD) != 0) fail_msg("%s", map.err);
    /* Speed raw -300 = 0xFED4 big endian from bit 7; Torque 1.5f = 0x3FC00000 little endian; Count 200 */
    const uint8_t data[8] = {0xFE, 0xD4, 0x00, 0x00, 0xC0, 0x3F, 200, 0};
    double v[3] = {NAN, NAN, NAN};
    uint8_t got[3] = {0};
    assert_int_equal(msid_can_map_decode(&map, 0, data, 8, v, got), 3);
    assert_true(v[0] == 1.5);
    assert_true(fabs(v[1] - (-3.0 * 2.0 + 1.0)) < 1e-12);
    assert_true(v[2] == 200.0);
    assert_true(got[0] && got[1] && got[2]);
    assert_true(msid_can_map_modulus(&map, 2) == 256.0);
    /* a frame too short for its signals is counted, not decoded */
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = 385;
    f.len = 4;
    assert_int_equal(msid_can_map_take(&map, &f, 1), 1);
    assert_int_equal(map.cnt.short_frames, 1);
    assert_int_equal(map.cnt.status_frames, 0);
    assert_int_equal(map.fresh[0], 0);
}

/* A multiplexed command message: the switch carries the drive channel's multiplexer value. */
static void test_mux_drive(void **state)
{
    (void)state;
    const char body[] =
        "[[drive]]\nname = \"g\"\nmessage = \"MuxCmd\"\nsignal = \"GainB\"\nmin = 0.0\nmax = 10.0\nsafe = 1.0\n"
        "[[measure]]\nname = \"y\"\nrole = \"output\"\nmessage = \"Status\"\nsignal = \"Speed\"\n";
    if (resolve(body) != 0) fail_msg("%s", map.err);
    double v = 2.5;   /* raw 250 */
    assert_int_equal(msid_can_map_pack(&map, &v), 0);
    assert_int_equal(map.cmd[0].data[0], 2);
    assert_int_equal(map.cmd[0].data[1], 250);
    assert_int_equal(map.cmd[0].data[2], 0);
}

/* Each description that cannot work is refused with one message naming the channel and what is wrong. */
static void test_refusals(void **state)
{
    (void)state;
    const char *y = "[[measure]]\nname = \"y\"\nrole = \"output\"\nmessage = \"Status\"\nsignal = \"Speed\"\n";
    char b[2048];
#define DRIVE(extra) "[[drive]]\nname = \"u\"\nmin = -1.0\nmax = 1.0\nsafe = 0.0\n" extra
    snprintf(b, sizeof b, DRIVE("message = \"Nope\"\nsignal = \"TorqueCmd\"\n") "%s", y);
    expect_refused(b, "has no message 'Nope'");
    snprintf(b, sizeof b, DRIVE("message = \"Cmd\"\nsignal = \"Torq\"\n") "%s", y);
    expect_refused(b, "no signal 'Torq' (its signals: TorqueCmd, Enable, SpeedLim)");
    snprintf(b, sizeof b, DRIVE("message = \"Cmd\"\nsignal = \"TorqueCmd\"\ntype = \"float32\"\n") "%s", y);
    expect_refused(b, "type = \"float32\", but Cmd.TorqueCmd is a 16-bit signed integer signal");
    snprintf(b, sizeof b, DRIVE("message = \"Cmd\"\nsignal = \"TorqueCmd\"\ntype = \"int16\"\n") "%s", y);
    assert_int_equal(resolve(b), 0);
    /* a limit the signal cannot carry: the DBC's range, then the signal's bits */
    snprintf(b, sizeof b, "[[drive]]\nname = \"u\"\nmin = -4.0\nmax = 1.0\nsafe = 0.0\nmessage = \"Cmd\"\n"
             "signal = \"TorqueCmd\"\n%s", y);
    expect_refused(b, "min -4 does not fit Cmd.TorqueCmd");
    snprintf(b, sizeof b, "[[drive]]\nname = \"u\"\nmin = 0.0\nmax = 300.0\nsafe = 0.0\nmessage = \"Cmd\"\n"
             "signal = \"SpeedLim\"\n%s", y);
    expect_refused(b, "max 300 does not fit Cmd.SpeedLim (a 8-bit unsigned integer signal");
    /* the description's scale: 1 description unit is 2 DBC units, so max 100 is raw 200 (fits) */
    snprintf(b, sizeof b, "[[drive]]\nname = \"u\"\nmin = 0.0\nmax = 100.0\nsafe = 0.0\nscale = 2.0\nmessage = \"Cmd\"\n"
             "signal = \"SpeedLim\"\n%s", y);
    assert_int_equal(resolve(b), 0);
    /* the device's own messages are read-only */
    snprintf(b, sizeof b, DRIVE("message = \"Status\"\nsignal = \"Count\"\n") "%s", y);
    expect_refused(b, "which the device sends (measure channel 'y' reads it)");
    snprintf(b, sizeof b, DRIVE("message = \"Echo\"\nsignal = \"EchoCmd\"\n") "%s", y);
    expect_refused(b, "sent by node DRIVE");
    snprintf(b, sizeof b, DRIVE("message = \"Cmd\"\nsignal = \"TorqueCmd\"\n")
             "[[drive]]\nname = \"v\"\nmin = -1.0\nmax = 1.0\nsafe = 0.0\nmessage = \"Cmd\"\nsignal = \"TorqueCmd\"\n%s", y);
    expect_refused(b, "both write Cmd.TorqueCmd");
    snprintf(b, sizeof b, "[[drive]]\nname = \"u\"\nmin = 0.0\nmax = 3.0\nsafe = 1.0\nmessage = \"MuxCmd\"\n"
             "signal = \"Sel\"\n%s", y);
    expect_refused(b, "multiplexer switch");
    snprintf(b, sizeof b, "[[drive]]\nname = \"u\"\nmin = 0.0\nmax = 3.0\nsafe = 1.0\nmessage = \"MuxCmd\"\nsignal = "
             "\"GainA\"\n[[drive]]\nname = \"v\"\nmin = 0.0\nmax = 3.0\nsafe = 1.0\nmessage = \"MuxCmd\"\nsignal = "
             "\"GainB\"\n%s", y);
    expect_refused(b, "one frame carries one multiplexer value");
    snprintf(b, sizeof b, DRIVE("message = \"Cmd\"\nsignal = \"TorqueCmd\"\n")
             "%s[[measure]]\nname = \"c\"\nrole = \"counter\"\nmessage = \"Status\"\nsignal = \"Torque\"\n", y);
    expect_refused(b, "a counter is an integer signal");
    /* the device's clock is seen only through its counter: refused by the description itself */
    {
        char text[4096], err[512];
        snprintf(text, sizeof text, "%sclock = \"device\"\n" DRIVE("message = \"Cmd\"\nsignal = \"TorqueCmd\"\n") "%s",
                 HEAD, y);
        if (msid_devdesc_parse(text, strlen(text), "dev.toml", &desc, err, sizeof err) == 0)
            fail_msg("clock = \"device\" without a counter was accepted");
        if (!strstr(err, "clock = \"device\" needs a channel with role = \"counter\"")) fail_msg("%s", err);
    }
#undef DRIVE
}

/* ---- the backend against a scripted device behind an in-memory transport ---- */

typedef struct device {
    msid_can_frame q[64];
    int head, n;
    uint32_t commands;        /* command frames received */
    int16_t last_raw;         /* the last command's raw TorqueCmd, the device's own state */
    uint32_t drop_every;      /* 0: answer every command; k: no answer to every k-th */
    uint32_t twice_every;     /* k: every k-th command that is answered is answered twice */
    uint32_t error_at;        /* command number after which an error frame is queued (0: never) */
    /* with a clock: the device runs one cycle per tick of that runner's clock (the cycles of ticks the host
       slept through run on the value they had), when a command arrives; the frames of the cycles
       drop_from, drop_from + drop_gap, .. (below drop_to) are lost, the cycles still run */
    const msid_hx *clock;
    uint64_t last_tick, cycle;
    uint32_t drop_from, drop_to, drop_gap;
    uint32_t dropped;         /* status frames lost so */
    uint32_t overflow;        /* frames the full queue lost (a socket's receive buffer) */
    uint8_t count;
} device;

static device dev;

static void push(const msid_can_frame *f)
{
    if (dev.n == 64) {
        dev.overflow++;
        return;
    }
    dev.q[(dev.head + dev.n++) % 64] = *f;
}

static void status(void)
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = 385;
    f.len = 8;
    /* Speed = command / 10 (raw in units of 0.01), the input read back as float32, the counter */
    const double u = 0.001 * dev.last_raw;
    const int16_t sp = (int16_t)lrint(100.0 * u / 10.0);
    f.data[0] = (uint8_t)((uint16_t)sp >> 8);
    f.data[1] = (uint8_t)sp;
    const float uf = (float)u;
    uint32_t bits;
    memcpy(&bits, &uf, 4);
    for (int k = 0; k < 4; ++k) f.data[2 + k] = (uint8_t)(bits >> (8 * k));
    f.data[6] = dev.count++;
    push(&f);
}

/* A device on its own clock (the runner's ticks): the cycles of the ticks since the last look run now, each on
 * the setpoint of its time, and each sends its status frame unless that frame is lost. Run when the host looks
 * at the bus, as if the cycles had run at their ticks (the host's exchange of tick n then reads cycle n). */
static void clocked_cycles(void)
{
    const uint64_t t = dev.clock->tick.next;   /* the tick being run is t - 1 */
    const uint64_t run = dev.cycle == 0 || t < dev.last_tick ? 1 : t - dev.last_tick;   /* t < last: restarted */
    dev.last_tick = t;
    for (uint64_t r = 0; r < run; ++r) {
        ++dev.cycle;
        const int lost = dev.drop_gap && dev.cycle >= dev.drop_from && dev.cycle < dev.drop_to &&
                         (dev.cycle - dev.drop_from) % dev.drop_gap == 0;
        dev.dropped += (uint32_t)lost;
        if (lost) dev.count++;   /* the cycle ran; only its frame is lost */
        else status();
    }
}

static int lb_send(void *ctx, const msid_can_frame *f, int timeout_ms)
{
    (void)ctx;
    (void)timeout_ms;
    assert_int_equal(f->id, 257);
    dev.commands++;
    dev.last_raw = (int16_t)(f->data[0] | f->data[1] << 8);
    if (dev.clock) return 0;   /* the setpoint of the next cycle: answered on the device's clock */
    const int answered = !(dev.drop_every && dev.commands % dev.drop_every == 0);
    if (answered) status();
    if (answered && dev.twice_every && dev.commands % dev.twice_every == 0) status();
    if (dev.error_at && dev.commands == dev.error_at) {
        msid_can_frame e;
        memset(&e, 0, sizeof e);
        e.id = MSID_CAN_ERR_FLAG | 0x4u;
        e.len = 8;
        push(&e);
    }
    return 0;
}

static int lb_recv(void *ctx, msid_can_frame *f, int n, int timeout_ms)
{
    (void)ctx;
    (void)timeout_ms;
    if (dev.clock) clocked_cycles();
    if (!dev.n) return -MSID_DAQ_E_TIMEOUT;
    int k = 0;
    while (k < n && dev.n) {
        f[k++] = dev.q[dev.head];
        dev.head = (dev.head + 1) % 64;
        dev.n--;
    }
    return k;
}

static void lb_stats(void *ctx, msid_can_link_stats *s)
{
    (void)ctx;
    memset(s, 0, sizeof *s);
}
static const char *lb_error(void *ctx) { (void)ctx; return ""; }
static void lb_close(void *ctx) { (void)ctx; }
static const msid_can_backend LOOPBACK = {"loopback", lb_recv, lb_send, lb_stats, lb_error, lb_close};
static msid_can_transport tr = {&LOOPBACK, NULL};

/* The GOOD description over the scripted device, taking only what is queued (no wait). */
static void open_loopback_map(void)
{
    char text[4096], err[512];
    snprintf(text, sizeof text, "%s%s", HEAD, GOOD);
    if (msid_devdesc_parse(text, strlen(text), "dev.toml", &desc, err, sizeof err) != 0) fail_msg("%s", err);
    if (msid_can_map_init(&map, &desc, &dbc, &tr) != 0) fail_msg("%s", map.err);
    map.wait_ns = 0;
}

/* Every answered tick is a sample of that tick's device state; every unanswered one a missing sample, counted
 * exactly; a tick answered twice gives the newest frame; error frames counted. */
static void test_exchange(void **state)
{
    (void)state;
    open_loopback_map();
    memset(&dev, 0, sizeof dev);
    dev.drop_every = 7;
    dev.twice_every = 5;
    dev.error_at = 11;
    uint32_t gaps = 0, samples = 0;
    /* the sample of tick k is the status answering tick k - 1's command: tick 1 has none, and the ticks after
       the unanswered commands 7, 14, .. have none */
    for (uint32_t k = 1; k <= 70; ++k) {
        const double u = 0.001 * (double)(k * 10);   /* exact in the signal's raw units */
        const double prev = 0.001 * (double)((k - 1) * 10);
        double meas[3] = {NAN, NAN, NAN};
        msid_devio_times t;
        memset(&t, 0, sizeof t);
        const int rc = msid_devio_exchange(&map.io, &u, meas, &t);
        assert_int_equal(dev.commands, k);   /* the command is sent in every tick, a missing sample's too */
        if (k % 7 == 1) {
            if (rc != -MSID_DAQ_E_TIMEOUT) fail_msg("tick %u: %d, an unanswered tick not a missing sample", k, rc);
            assert_non_null(strstr(map.err, "'Torque' (Status, 0x181)"));
            assert_true(isnan(meas[0]));   /* nothing held over */
            ++gaps;
            continue;
        }
        if (rc) fail_msg("tick %u: %d %s", k, rc, map.err);
        ++samples;
        assert_int_equal(t.transactions, 1);
        assert_true(t.r1 <= t.w0);   /* read before the write */
        assert_true(fabs(meas[0] - prev) < 1e-6);   /* the read-back of the previous tick's command */
        assert_true(fabs(meas[1] - (2.0 * 0.01 * lrint(100.0 * prev / 10.0) + 1.0)) < 1e-9);
    }
    assert_int_equal(map.cnt.exchanges, 70);
    assert_int_equal(map.cnt.frames_sent, 70);
    assert_int_equal(map.cnt.stale, gaps);
    assert_int_equal(gaps, 10);
    assert_int_equal(samples, 60);
    /* answered twice: the ticks 5, 10, .., 70 not dropped (35 and 70 are): 12; the second frame supersedes */
    assert_int_equal(map.cnt.superseded, 12);
    assert_int_equal(map.cnt.status_frames, 60 + 12);
    assert_int_equal(map.cnt.bus_errors, 1);
    /* the description of an exchange names the frames */
    assert_non_null(strstr(msid_devio_describe(&map.io), "frame Cmd 0x101 + status Status 0x181"));
    /* the safe value written: the device's own state holds it */
    const double safe = 0.0;
    msid_devio_times t;
    memset(&t, 0, sizeof t);
    assert_int_equal(msid_devio_write(&map.io, &safe, &t), 0);
    assert_int_equal(dev.last_raw, 0);
}


/* ---- the backend in the tick loop, placed by the device's counter ---------------------------------------
 * The scripted device cycles on its own clock (the runner's ticks) and sends its status (counter included) each
 * cycle, except for chosen cycles whose frame is lost while the cycle still runs. msid_hx reads cycle j at each
 * tick and writes for cycle j + 1; a lost frame makes that cycle, the next (written before the host knew which
 * cycle it would reach) and the one after (written for the wrong cycle) missing samples: exactly three per
 * isolated loss inside the measured periods when no tick was slept through. */
#define HP 64u
#define HK 4u
static const uint32_t HBINS[3] = {1, 5, 11};
static uint8_t TWM[1 << 14] __attribute__((aligned(64)));
static uint8_t DMEM[1 << 16] __attribute__((aligned(64)));
static uint8_t MMEM[1 << 20] __attribute__((aligned(64)));
static uint8_t HMEM[1 << 20] __attribute__((aligned(64)));

static msid_twiddle tw;
static msid_design d;
static msid_meas ms;
static msid_hx h;

/* The tick loop over the scripted device, placed by its counter: HK measured periods after the approach and a
   fade-in period, at 500 Hz. */
static void counter_runner(void)
{
    open_loopback_map();
    memset(&dev, 0, sizeof dev);
    dev.clock = &h;
    assert_int_equal(msid_twiddle_init(&tw, HP, TWM, sizeof TWM), MSID_OK);
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = HP; dc.n_lines = 3; dc.bins = HBINS; dc.phase_mode = MSID_PHASE_SCHROEDER; dc.n_inputs = 1;
    dc.n_experiments = 1; dc.twiddle = &tw;
    assert_int_equal(msid_design_init(&d, &dc, DMEM, sizeof DMEM), MSID_OK);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = HP; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = 1; mc.n_lines = 3; mc.bins = HBINS;
    mc.twiddle = &tw; mc.path = MSID_DFT_STREAM; mc.transient = MSID_TRANSIENT_OFF; mc.max_periods = 4 * HK;
    assert_int_equal(msid_meas_init(&ms, &mc, MMEM, sizeof MMEM), MSID_OK);
    msid_hx_cfg c;
    memset(&c, 0, sizeof c);
    c.design = &d; c.twiddle = &tw; c.periods = HK; c.fade_periods = 1; c.n_measure = 3;
    c.drive[0] = (msid_hx_drive){.op = 0.0, .gain = 0.5, .min = -2, .max = 2, .max_step = NAN, .safe = 0.0,
                                 .name = "Torque command"};
    c.input_of[0] = 0;
    c.n_outputs = 1;
    c.output_of[0] = 1;
    c.counter = 2;
    c.counter_modulus = msid_can_map_modulus(&map, 2);
    c.index_by_counter = 1;
    c.io = &map.io;
    c.meas = &ms;
    c.tick.rate_hz = 500;
    assert_true(c.counter_modulus == 256);
    assert_true(msid_hx_mem_size(&c) <= sizeof HMEM);
    assert_int_equal(msid_hx_init(&h, &c, HMEM, sizeof HMEM), 0);
}

static void test_counter_run_with_lost_frames(void **state)
{
    (void)state;
    counter_runner();
    /* The first tick reads cycle 1: sample k of the timeline is cycle k + 3, the measured periods start at sample
       A + F = 2 P (the approach and the fade-in), so cycle 2 P + 3 + i is measured sample i (when no tick is
       slept through before them). Lost: the frames of cycles 2 P + 13 and 2 P + 103. */
    const uint32_t first = 2 * HP + 3;
    dev.drop_from = first + 10;
    dev.drop_gap = 90;
    dev.drop_to = first + 171;
    const int rc = msid_hx_run(&h, 0);
    if (rc) fail_msg("run: %d %s", rc, h.err);
    assert_int_equal(msid_hx_finish(&h), 0);
    assert_int_equal(dev.dropped, 2);
    const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(&ms, 0));
    /* whatever the host's timing (the samples follow the device's cycles, so the lost frames stay at measured
       samples 10 and 100): every measured sample is a row or a counted missing one, a lost cycle's sample is
       missing, and a period holding one is rejected. A tick slept through may take a later cycle's frame in the
       same look, so that a loss is not a stale tick then */
    assert_int_equal(h.cnt.samples + h.cnt.samples_lost, HK * HP);
    assert_true(h.cnt.samples_lost >= dev.dropped);
    assert_int_equal(k.offered, HK);
    assert_int_equal(k.used + k.gap, HK);
    assert_true(k.gap >= 2);
    if (h.tick.missed == 0) {
        /* no tick slept through: each lost frame costs exactly three samples, nothing else is lost */
        assert_int_equal(h.cnt.samples_lost, 3 * dev.dropped);
        assert_int_equal(h.cnt.cycles_not_read, 3 * dev.dropped);
        assert_int_equal(map.cnt.stale, dev.dropped);
        assert_int_equal(dev.overflow, 0);
        assert_int_equal(k.gap, 2);
    } else {
        print_message("note: %llu tick(s) missed on this machine: the exact losses are not checked\n",
                      (unsigned long long)h.tick.missed);
    }
    /* the safe value last, in the device's own state */
    assert_int_equal(dev.last_raw, 0);
    msid_hx_release(&h);
}

/* A socket queue that filled before the run (the host prepared the run while the device went on cycling): the
 * run's first exchange takes only frames from before, its newest 150 cycles behind the device, which the
 * kernel's full queue dropped. The read after shows the jump; the timeline restarts from it, and the run
 * measures every sample (without the restart the timeline's start lay 150 cycles back: its approach and most of
 * its fade-in had passed, and the run lost its first measured samples). */
static void test_counter_run_after_a_stale_queue(void **state)
{
    (void)state;
    counter_runner();
    for (int k = 0; k < 64; ++k) status();   /* the full queue: cycles 0..63 */
    dev.count = (uint8_t)(dev.count + 150);   /* cycles 64..213 ran; the full queue lost their frames */
    dev.cycle = 214;
    dev.last_tick = 0;                        /* the device's next look runs one cycle (its first tick) */
    const int rc = msid_hx_run(&h, 0);
    if (rc) fail_msg("run: %d %s", rc, h.err);
    assert_int_equal(msid_hx_finish(&h), 0);
    assert_int_equal(h.cnt.stale_anchors, 1);
    assert_int_equal(h.cnt.samples + h.cnt.samples_lost, HK * HP);
    if (h.tick.missed == 0) {
        assert_int_equal(h.cnt.samples_lost, 0);
        assert_int_equal(h.cnt.samples, HK * HP);
    } else {
        print_message("note: %llu tick(s) missed on this machine: the exact losses are not checked\n",
                      (unsigned long long)h.tick.missed);
    }
    assert_int_equal(dev.last_raw, 0);
    msid_hx_release(&h);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pack),
        cmocka_unit_test(test_decode),
        cmocka_unit_test(test_mux_drive),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_exchange),
        cmocka_unit_test(test_counter_run_with_lost_frames),
        cmocka_unit_test(test_counter_run_after_a_stale_queue),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
