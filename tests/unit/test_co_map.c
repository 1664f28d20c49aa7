/* CANopen drives in msid-device/1 and their tick backend (msid_devdesc_file.h, msid_co_map.h): the presets'
 * channels and PDO packing, explicit objects, the refusals naming their key, the little-endian codec, and one
 * tick on frames in memory against a node written here: the RPDO and SYNC sent, the SYNC back first, the
 * TPDOs of that SYNC decoded at the next tick; a TPDO of an older SYNC dropped as late; a TPDO missing lost;
 * an EMCY fatal. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "msid_daq/msid_co_map.h"
#include "msid_daq/msid_devdesc_file.h"

static const char PRESET[] =
    "format = \"msid-device/1\"\n"
    "transport = \"canopen\"\n"
    "preset = \"cst\"\n"
    "rated_torque = 2.0\n"
    "velocity_scale = 0.001\n"
    "velocity_unit = \"rad/s\"\n"
    "[[drive]]\n"
    "safe = 0.0\n"
    "min = -1.0\n"
    "max = 1.0\n";

static const char EXPLICIT[] =
    "format = \"msid-device/1\"\n"
    "transport = \"canopen\"\n"
    "mode = \"csv\"\n"
    "[[drive]]\n"
    "name = \"v\"\n"
    "object = \"0x60FF:00\"\n"
    "type = \"int32\"\n"
    "scale = 0.001\n"
    "safe = 0.0\n"
    "[[measure]]\n"
    "name = \"w\"\n"
    "role = \"output\"\n"
    "object = \"0x606C:0\"\n"
    "type = \"int32\"\n"
    "scale = 0.001\n";

static int parse(const char *text, msid_devdesc *d, char *err, size_t cap)
{
    return msid_devdesc_parse(text, strlen(text), "d.toml", d, err, cap);
}

static void test_preset_cst(void **state)
{
    (void)state;
    static msid_devdesc d;
    char err[512];
    assert_int_equal(parse(PRESET, &d, err, sizeof err), 0);
    assert_int_equal(d.transport, MSID_DEV_CANOPEN);
    assert_int_equal(d.co_mode, 10);
    assert_int_equal(d.n_drive, 1);
    assert_int_equal(d.drive[0].co_index, 0x6071);
    assert_string_equal(d.drive[0].name, "Target torque");
    assert_true(fabs(d.drive[0].scale - 2e-3) < 1e-15);   /* per mille of 2 N m */
    assert_int_equal(d.n_measure, 4);
    const uint16_t want[] = {0x6074, 0x6077, 0x606C, 0x6064};
    for (int i = 0; i < 4; ++i) assert_int_equal(d.measure[i].co_index, want[i]);
    assert_int_equal(d.measure[0].role, MSID_DEV_ROLE_INPUT);
    assert_string_equal(d.measure[2].unit, "rad/s");
    uint8_t of[4];
    assert_int_equal(msid_devdesc_co_pack(&d, of), 2);
    assert_memory_equal(of, ((const uint8_t[]){0, 0, 0, 1}), 4);
}

/* the closed-loop preset: the velocity target read back is the FRF's input (the reference), the demand an output */
static void test_preset_csv_loop(void **state)
{
    (void)state;
    static msid_devdesc d;
    char err[512];
    static const char loop[] = "format = \"msid-device/1\"\ntransport = \"canopen\"\npreset = \"csv-loop\"\n"
                               "rated_torque = 2.0\nvelocity_scale = 0.001\n[[drive]]\nsafe = 0.0\noperating_point = 5\n"
                               "min = -10.0\nmax = 10.0\n";
    assert_int_equal(parse(loop, &d, err, sizeof err), 0);
    assert_int_equal(d.co_mode, 9);
    assert_int_equal(d.co_closed_loop, 1);
    assert_int_equal(d.drive[0].co_index, 0x60FF);
    assert_int_equal(d.n_measure, 5);
    const uint16_t want[] = {0x60FF, 0x6074, 0x6077, 0x606C, 0x6064};
    for (int i = 0; i < 5; ++i) assert_int_equal(d.measure[i].co_index, want[i]);
    assert_int_equal(d.measure[0].role, MSID_DEV_ROLE_INPUT);
    assert_int_equal(d.measure[1].role, MSID_DEV_ROLE_OUTPUT);
    assert_int_equal(msid_devdesc_readback(&d, 0), 0);
    assert_true(fabs(d.measure[0].scale - 1e-3) < 1e-15);   /* velocity_scale, as the target's */
    uint8_t of[5];
    assert_int_equal(msid_devdesc_co_pack(&d, of), 2);
    assert_memory_equal(of, ((const uint8_t[]){0, 0, 0, 1, 1}), 5);
    assert_int_equal(parse(PRESET, &d, err, sizeof err), 0);
    assert_int_equal(d.co_closed_loop, 0);
}

/* the torque-loop preset: the torque offset read back is the reference, the demand an output, the velocity held */
static void test_preset_csv_torque_loop(void **state)
{
    (void)state;
    static msid_devdesc d;
    char err[512];
    static const char loop[] = "format = \"msid-device/1\"\ntransport = \"canopen\"\npreset = \"csv-torque-loop\"\n"
                               "rated_torque = 2.0\nvelocity_scale = 0.001\nhold_velocity = 3.5\n[[drive]]\nsafe = 0.0\n"
                               "min = -0.5\nmax = 0.5\n";
    assert_int_equal(parse(loop, &d, err, sizeof err), 0);
    assert_int_equal(d.co_mode, 9);
    assert_int_equal(d.co_closed_loop, 2);
    assert_true(d.co_hold_velocity == 3.5);
    assert_int_equal(d.drive[0].co_index, 0x60B2);
    assert_int_equal(d.drive[0].type, MSID_DEV_INT16);
    assert_true(fabs(d.drive[0].scale - 2e-3) < 1e-15);   /* per mille of 2 N m */
    assert_int_equal(d.n_measure, 5);
    const uint16_t want[] = {0x60B2, 0x6074, 0x6077, 0x606C, 0x6064};
    for (int i = 0; i < 5; ++i) assert_int_equal(d.measure[i].co_index, want[i]);
    assert_string_equal(d.measure[0].name, "Torque reference");
    assert_int_equal(d.measure[0].role, MSID_DEV_ROLE_INPUT);
    assert_int_equal(d.measure[1].role, MSID_DEV_ROLE_OUTPUT);
    assert_int_equal(msid_devdesc_readback(&d, 0), 0);
    uint8_t of[5];
    assert_int_equal(msid_devdesc_co_pack(&d, of), 2);
    assert_memory_equal(of, ((const uint8_t[]){0, 0, 0, 1, 1}), 5);
}

static void test_explicit_objects(void **state)
{
    (void)state;
    static msid_devdesc d;
    char err[512];
    assert_int_equal(parse(EXPLICIT, &d, err, sizeof err), 0);
    assert_int_equal(d.co_mode, 9);
    assert_int_equal(d.drive[0].co_index, 0x60FF);
    assert_int_equal(d.measure[0].co_index, 0x606C);
    assert_int_equal(d.measure[0].co_sub, 0);
}

static void expect_refused(const char *text, const char *want)
{
    static msid_devdesc d;
    char err[512] = "";
    assert_int_not_equal(parse(text, &d, err, sizeof err), 0);
    if (!strstr(err, want)) fail_msg("'%s' does not say '%s'", err, want);
}

static void test_refusals(void **state)
{
    (void)state;
    char t[2048];
    snprintf(t, sizeof t, "%s", EXPLICIT);
    *strstr(t, "0x606C:0") = 'Q';
    expect_refused(t, "object = \"Qx606C:0\"");
    expect_refused("format = \"msid-device/1\"\ntransport = \"canopen\"\n[[drive]]\nname = \"v\"\nobject = \"0x60FF:0\"\n"
                   "type = \"int32\"\nsafe = 0\n[[measure]]\nname = \"w\"\nrole = \"output\"\nobject = \"0x606C:0\"\n"
                   "type = \"int32\"\n", "(key mode)");
    char three[2048] = "format = \"msid-device/1\"\ntransport = \"canopen\"\nmode = \"csv\"\n";
    for (int i = 0; i < 3; ++i)
        snprintf(three + strlen(three), sizeof three - strlen(three),
                 "[[drive]]\nname = \"v%d\"\nobject = \"0x60FF:0\"\ntype = \"int32\"\nsafe = 0\n", i);
    strcat(three, "[[measure]]\nname = \"w\"\nrole = \"output\"\nobject = \"0x606C:0\"\ntype = \"int32\"\n");
    expect_refused(three, "the drive channels map 12 bytes");
    snprintf(t, sizeof t, "%sobject = \"0x6071:00\"\n", PRESET);
    expect_refused(t, "gives the limits only");
    snprintf(t, sizeof t, "%s", PRESET);
    *strstr(t, "cst\"") = 'x';
    expect_refused(t, "preset = \"xst\"");
    expect_refused("format = \"msid-device/1\"\ntransport = \"modbus\"\npreset = \"cst\"\n", "preset goes with");
    const char *rest = strstr(EXPLICIT, "[[drive]]");
    snprintf(t, sizeof t, "%.*sdbc = \"x.dbc\"\n%s", (int)(rest - EXPLICIT), EXPLICIT, rest);
    expect_refused(t, "key 'dbc' is not for transport = \"canopen\"");
    /* 5 x int32 = 20 bytes do not fit two TPDOs */
    char five[4096] = "format = \"msid-device/1\"\ntransport = \"canopen\"\nmode = \"csv\"\n"
                      "[[drive]]\nname = \"v\"\nobject = \"0x60FF:0\"\ntype = \"int32\"\nsafe = 0\n";
    for (int i = 0; i < 5; ++i)
        snprintf(five + strlen(five), sizeof five - strlen(five),
                 "[[measure]]\nname = \"w%d\"\nrole = \"output\"\nobject = \"0x606C:0\"\ntype = \"int32\"\n", i);
    expect_refused(five, "two TPDOs");
    /* hold_velocity is the torque-loop preset's alone, and its counts must fit 0x60FF */
    snprintf(t, sizeof t, "%.*shold_velocity = 1.0\n%s", (int)(strstr(PRESET, "[[drive]]") - PRESET), PRESET,
             strstr(PRESET, "[[drive]]"));
    expect_refused(t, "hold_velocity goes with preset = \"csv-torque-loop\"");
    expect_refused("format = \"msid-device/1\"\ntransport = \"canopen\"\npreset = \"csv-torque-loop\"\n"
                   "velocity_scale = 1e-6\nhold_velocity = 3000.0\n[[drive]]\nsafe = 0.0\n",
                   "outside INTEGER32");
    /* sync: "tick" or "kernel", nothing else */
    snprintf(t, sizeof t, "%.*ssync = \"bcm\"\n%s", (int)(strstr(PRESET, "[[drive]]") - PRESET), PRESET,
             strstr(PRESET, "[[drive]]"));
    expect_refused(t, "sync = \"bcm\": must be \"tick\"");
    static msid_devdesc d;
    char err[512];
    snprintf(t, sizeof t, "%.*ssync = \"kernel\"\n%s", (int)(strstr(PRESET, "[[drive]]") - PRESET), PRESET,
             strstr(PRESET, "[[drive]]"));
    assert_int_equal(parse(t, &d, err, sizeof err), 0);
    assert_int_equal(d.co_sync, MSID_DEV_SYNC_KERNEL);
    assert_int_equal(parse(PRESET, &d, err, sizeof err), 0);
    assert_int_equal(d.co_sync, MSID_DEV_SYNC_TICK);
}

static void test_codec(void **state)
{
    (void)state;
    msid_dev_chan c;
    msid_dev_chan_defaults(&c);
    c.type = MSID_DEV_INT16;
    c.scale = 1e-3;
    uint8_t b[4];
    assert_int_equal(msid_co_map_encode(&c, -0.002, b), 0);
    assert_memory_equal(b, ((const uint8_t[]){0xFE, 0xFF}), 2);
    assert_true(fabs(msid_co_map_decode(&c, b) + 0.002) < 1e-12);
    assert_int_equal(msid_co_map_encode(&c, 40.0, b), -1);   /* 40000 counts: not an INTEGER16 */
    c.type = MSID_DEV_INT32;
    c.scale = 1.0;
    assert_int_equal(msid_co_map_encode(&c, 0x12345678, b), 0);
    assert_memory_equal(b, ((const uint8_t[]){0x78, 0x56, 0x34, 0x12}), 4);
}

/* ---- a node in memory: answers each SYNC after its echo with TPDO1 (and TPDO2) ---- */

typedef struct node {
    msid_can_frame q[32];
    int n, at;
    msid_can_frame sent[32];
    int n_sent;
    int answer;          /* TPDOs answered per SYNC (0, 1, 2) */
    int late_first;      /* put a TPDO1 before the next SYNC's echo */
    int emcy;            /* answer the next SYNC with an EMCY */
    int count;           /* the demand is the SYNC's number (which SYNC a sample came from) */
    int hold;            /* hold the next SYNC's answers until after the echo of the one after it */
    int syncs;
    msid_can_frame held[2];
    int n_held;
} node;

static void push(node *s, uint32_t id, const uint8_t *data, uint8_t len)
{
    assert_true(s->n < 32);
    msid_can_frame *f = &s->q[s->n++];
    memset(f, 0, sizeof *f);
    f->id = id;
    f->len = len;
    if (len) memcpy(f->data, data, len);
}

static int nd_recv(void *ctx, msid_can_frame *f, int n, int timeout_ms)
{
    node *s = ctx;
    (void)timeout_ms;
    int k = 0;
    while (k < n && s->at < s->n) f[k++] = s->q[s->at++];
    if (s->at == s->n) s->at = s->n = 0;   /* all taken: the queue starts over */
    return k ? k : -MSID_DAQ_E_TIMEOUT;
}

/* A SYNC on the bus: its echo, then the node's answers as set. */
static void answer_sync(node *s)
{
    if (s->late_first) {
        push(s, 0x185, (const uint8_t[]){9, 9, 9, 9, 9, 9, 9, 9}, 8);
        s->late_first = 0;
    }
    push(s, 0x080, NULL, 0);   /* the own SYNC back */
    s->syncs++;
    if (s->emcy) push(s, 0x085, (const uint8_t[]){0x10, 0x23, 0x03, 0, 0, 0, 0, 0}, 8);
    for (int i = 0; i < s->n_held; ++i) s->q[s->n++] = s->held[i];   /* the late answers, in order */
    s->n_held = 0;
    const int at = s->n;
    /* demand 100 per mille (or the SYNC's number), torque 100, velocity -5000 counts; position 123456 */
    const uint8_t dem = (uint8_t)(s->count ? s->syncs : 100);
    if (s->answer >= 1) push(s, 0x185, (const uint8_t[]){dem, 0, 100, 0, 0x78, 0xEC, 0xFF, 0xFF}, 8);
    if (s->answer >= 2) push(s, 0x285, (const uint8_t[]){0x40, 0xE2, 0x01, 0x00}, 4);
    if (s->hold) {   /* this SYNC's answers come after the next SYNC */
        s->n_held = s->n - at;
        memcpy(s->held, &s->q[at], sizeof(msid_can_frame) * (size_t)s->n_held);
        s->n = at;
        s->hold = 0;
    }
}

static int nd_send(void *ctx, const msid_can_frame *f, int timeout_ms)
{
    node *s = ctx;
    (void)timeout_ms;
    s->sent[s->n_sent++ % 32] = *f;
    if (f->id == 0x080) answer_sync(s);
    return 0;
}

static void nd_stats(void *ctx, msid_can_link_stats *st) { (void)ctx; memset(st, 0, sizeof *st); }
static const char *nd_error(void *ctx) { (void)ctx; return ""; }
static void nd_close(void *ctx) { (void)ctx; }
static const msid_can_backend NODE = {"node", nd_recv, nd_send, nd_stats, nd_error, nd_close};

/* The preset's map of node 5 on the node in memory, which answers each SYNC with both TPDOs. */
static void map_on_node(msid_devdesc *d, node *s, msid_can_transport *t, msid_co_map *m)
{
    char err[512];
    assert_int_equal(parse(PRESET, d, err, sizeof err), 0);
    memset(s, 0, sizeof *s);
    s->answer = 2;
    t->be = &NODE;
    t->ctx = s;
    assert_int_equal(msid_co_map_init(m, d, 5, 0, t), 0);
}

static void test_one_tick(void **state)
{
    (void)state;
    static msid_devdesc d;
    static node s;
    static msid_co_map m;
    msid_can_transport t;
    map_on_node(&d, &s, &t, &m);
    msid_co_pdo_cfg rp, tp[2];
    msid_co_map_pdos(&m, &rp, tp);
    assert_int_equal(rp.n, 1);
    assert_int_equal(rp.e[0].index, 0x6071);
    assert_int_equal(tp[0].n, 3);
    assert_int_equal(tp[1].n, 1);
    assert_int_equal(tp[1].e[0].bits, 32);
    double drive = 0.5, y[4];
    msid_devio_times tm;
    memset(&tm, 0, sizeof tm);
    /* a write: the RPDO first (0.5 N m = 250 per mille of 2 N m), then the SYNC; nothing is read yet */
    assert_int_equal(msid_devio_write(&m.io, &drive, &tm), 0);
    assert_int_equal(s.sent[0].id, 0x205);
    assert_memory_equal(s.sent[0].data, ((const uint8_t[]){250, 0}), 2);
    assert_int_equal(s.sent[1].id, 0x080);
    /* the next tick returns the answers to that SYNC, and sends its own */
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_true(fabs(y[0] - 0.2) < 1e-12 && fabs(y[2] + 5.0) < 1e-12 && y[3] == 123456.0);
    assert_int_equal(s.n_sent, 4);
    /* a TPDO of an older SYNC before the echo: dropped as late, the SYNC's own taken */
    s.late_first = 1;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_int_equal(m.cnt.late, 1);
    assert_true(fabs(y[0] - 0.2) < 1e-12);
    /* TPDO2 not sent on a SYNC: the next tick's sample is lost, and that tick's write still goes out */
    s.answer = 1;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    s.answer = 2;
    const int sent = s.n_sent;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_TIMEOUT);
    assert_int_equal(m.cnt.lost, 1);
    assert_non_null(strstr(m.err, "TPDO2"));
    assert_int_equal(s.n_sent, sent + 2);
    /* the next SYNC's TPDO2 could be that late answer (it is not: the node dropped it): taken for it and lost,
       never placed as the next sample; the SYNC after it is followed again */
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_TIMEOUT);
    assert_int_equal(m.cnt.lost, 2);
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    /* an EMCY answers a SYNC: the next tick is refused, and every one after it */
    s.emcy = 1;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    s.emcy = 0;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(m.fatal, "EMCY 0x2310"));
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_DEVICE);
    /* the safe values still go out after it */
    assert_int_equal(msid_devio_write(&m.io, &drive, &tm), 0);
    /* a SYNC answered only after the next SYNC's echo (and that one's answers behind it): the late answers
       are taken for what they are, the sample is lost, and the next sample is the next SYNC's own */
    m.fatal[0] = 0;
    s.count = 1;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    s.hold = 1;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);   /* sends SYNC h, its answers held */
    const int h = s.syncs;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_TIMEOUT);   /* h's: not in */
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);   /* h's late, then h + 1's */
    assert_true(fabs(y[0] - (h + 1) * 2e-3) < 1e-12);
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_true(fabs(y[0] - (h + 2) * 2e-3) < 1e-12);
    /* a value the target's type cannot carry: refused before anything is sent */
    const int before = s.n_sent;
    m.fatal[0] = 0;
    drive = 100.0;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_ARG);
    assert_int_equal(s.n_sent, before);
}

/* The kernel's SYNC (kernel_sync): the tick sends the RPDO alone and returns the answers of the last SYNC the
 * bus carried with its count; a SYNC whose answers come after the next one's echo is a lost sample, the next
 * SYNC's own answers placed at its own count. */
static void test_kernel_sync_tick(void **state)
{
    (void)state;
    static msid_devdesc d;
    static node s;
    static msid_co_map m;
    msid_can_transport t;
    map_on_node(&d, &s, &t, &m);
    s.count = 1;
    msid_co_map_kernel_sync(&m, 100000);   /* 0.1 s: a test on a loaded machine never waits that long */
    assert_int_equal(m.sync_ch, 4);
    assert_non_null(strstr(m.describe, "the kernel's SYNC"));
    double drive = 0.5, y[5];
    msid_devio_times tm;
    memset(&tm, 0, sizeof tm);
    /* a write is the RPDO alone */
    assert_int_equal(msid_devio_write(&m.io, &drive, &tm), 0);
    assert_int_equal(s.n_sent, 1);
    assert_int_equal(s.sent[0].id, 0x205);
    /* no SYNC on the bus yet: nothing to return */
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_TIMEOUT);
    assert_int_equal(s.n_sent, 2);
    assert_int_equal(s.sent[1].id, 0x205);
    /* SYNC 1: its answers with its count */
    answer_sync(&s);
    memset(&tm, 0, sizeof tm);
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_true(y[4] == 1.0 && fabs(y[0] - 2e-3) < 1e-12 && y[3] == 123456.0);
    assert_true(tm.has_counter_before && tm.counter_before == 1.0 && tm.transactions == 1);
    /* no SYNC since: the same SYNC again (the tick loop drops a SYNC read twice) */
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_true(y[4] == 1.0);
    /* two SYNCs since: the last one's */
    answer_sync(&s);
    answer_sync(&s);
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_true(y[4] == 3.0 && fabs(y[0] - 3 * 2e-3) < 1e-12);
    assert_int_equal(m.cnt.syncs, 3);
    /* SYNC 4 answered after SYNC 5's echo: lost at 4, the late answers dropped, 5 placed at 5 */
    s.hold = 1;
    answer_sync(&s);
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_TIMEOUT);
    assert_non_null(strstr(m.err, "SYNC 4"));
    answer_sync(&s);
    const uint64_t late = m.cnt.late;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), 0);
    assert_true(y[4] == 5.0 && fabs(y[0] - 5 * 2e-3) < 1e-12);
    assert_int_equal(m.cnt.late, late + 2);
    /* an EMCY with the SYNC: the tick is refused, the safe values still go out */
    s.emcy = 1;
    answer_sync(&s);
    s.emcy = 0;
    assert_int_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(m.fatal, "EMCY 0x2310"));
    assert_int_equal(msid_devio_write(&m.io, &drive, &tm), 0);
    m.fatal[0] = 0;
    /* ticks back to back within a period are no sign of a stopped SYNC */
    for (int k = 0; k < 20; ++k) assert_int_not_equal(msid_devio_exchange(&m.io, &drive, y, &tm), -MSID_DAQ_E_IO);
    /* the kernel's SYNC stopped coming back: refused once ten periods passed without one, naming it */
    m.period_ns = 1000;
    int rc = 0;
    for (int k = 0; k < 100000 && rc != -MSID_DAQ_E_IO; ++k) rc = msid_devio_exchange(&m.io, &drive, y, &tm);
    assert_int_equal(rc, -MSID_DAQ_E_IO);
    assert_non_null(strstr(m.err, "no SYNC of the kernel's timer"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_preset_cst), cmocka_unit_test(test_preset_csv_loop), cmocka_unit_test(test_preset_csv_torque_loop), cmocka_unit_test(test_explicit_objects), cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_codec),      cmocka_unit_test(test_one_tick),
        cmocka_unit_test(test_kernel_sync_tick),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
