/* msid-devsim's CANopen node (firmware_sim/sim_co_node.h) driven with frames in memory through msid's own
   CANopen master (daq/: SDO client, NMT, PDO configuration, CiA 402 state machine): SDO sizes 0..31 each
   way, aborts by name, PDO configurations accepted and refused under CiA 301's rules, the CiA 402 walk and
   a fault, and a SYNC sequence whose TPDOs hold what the plant's step function gives for the targets. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <complex.h>
#include <math.h>
#include <cmocka.h>

#include "msid_daq/msid_co_402.h"
#include "msid_daq/msid_co_emcy.h"
#include "msid_daq/msid_co_nmt.h"
#include "msid_daq/msid_co_pdo.h"
#include "msid_daq/msid_co_sdo.h"
#include "sim_co_node.h"

#define NODE 5u
#define PI 3.14159265358979323846
#define QCAP 64

/* The bus: what the node sent, in order; the master's clock (ms) */
typedef struct bus {
    sim_co_node node;
    msid_can_frame q[QCAP];
    int head, n;
    msid_can_frame seen[256];     /* every frame the node sent that the master did not take (PDO, EMCY, ...) */
    int n_seen;
    double now;
} bus;

static bus B;
static msid_co_od_entry ENTRIES[SIM_CO_OD_MAX];
static msid_co_eds EDS;

static void node_send(void *ctx, const msid_can_frame *f)
{
    bus *b = ctx;
    assert_true(b->n < QCAP);
    b->q[(b->head + b->n++) % QCAP] = *f;
}

static int io_send(void *ctx, const msid_can_frame *f)
{
    bus *b = ctx;
    b->now += 0.1;
    sim_co_node_rx(&b->node, f, b->now);
    return 0;
}

static int io_recv(void *ctx, msid_can_frame *f, int timeout_ms)
{
    bus *b = ctx;
    if (!b->n) {
        b->now += timeout_ms;
        sim_co_node_poll(&b->node, b->now);
        if (!b->n) return -MSID_DAQ_E_TIMEOUT;
    }
    *f = b->q[b->head];
    b->head = (b->head + 1) % QCAP, b->n--;
    return 1;
}

static uint64_t io_now(void *ctx) { return (uint64_t)((bus *)ctx)->now; }

static void io_other(void *ctx, const msid_can_frame *f)
{
    bus *b = ctx;
    if (b->n_seen < 256) b->seen[b->n_seen++] = *f;
}

static const msid_co_io IO = {&B, io_send, io_recv, io_now, io_other};

/* take what the node sent (outside an SDO transfer) into seen[] */
static void drain(void)
{
    msid_can_frame f;
    while (B.n) {
        io_recv(&B, &f, 0);
        io_other(&B, &f);
    }
}

static void start(const sim_co_faults *f)
{
    memset(&B, 0, sizeof B);
    sim_co_faults none;
    memset(&none, 0, sizeof none);
    char err[256];
    B.now = 1000.0;
    assert_int_equal(sim_co_node_init(&B.node, &EDS, NODE, f ? f : &none, node_send, &B, B.now, err, sizeof err), 0);
}

static const sim_co_faults NO_FAULTS = {0, 0, 0, 0, 0, 0, 0, 0, 0};

static void sdo(msid_co_sdo *s)
{
    assert_int_equal(msid_co_sdo_init(s, &IO, NODE, 100), 0);
}

static int setup(void **state)
{
    (void)state;
    const char *path = MSID_SOURCE_DIR "/tests/vcan/in_vm/data/drive402.eds";
    if (msid_co_eds_load(path, &EDS, ENTRIES, SIM_CO_OD_MAX) != 0) {
        fprintf(stderr, "%s\n", EDS.err);
        return -1;
    }
    return 0;
}

static void test_boot_and_heartbeat(void **state)
{
    (void)state;
    start(NULL);
    drain();
    assert_int_equal(B.n_seen, 1);
    assert_int_equal(B.seen[0].id, 0x700 + NODE);
    assert_int_equal(B.seen[0].len, 1);
    assert_int_equal(B.seen[0].data[0], 0x00);
    msid_co_sdo s;
    sdo(&s);
    assert_int_equal(msid_co_sdo_write_uint(&s, 0x1017, 0, 2, 100), 0);
    B.n_seen = 0;
    for (int k = 0; k < 10; ++k) { B.now += 50.0; sim_co_node_poll(&B.node, B.now); }
    drain();
    assert_int_equal(B.n_seen, 5);
    for (int k = 0; k < B.n_seen; ++k) assert_int_equal(B.seen[k].data[0], MSID_CO_STATE_PREOPERATIONAL);
    assert_int_equal(msid_co_nmt_send(&IO, MSID_CO_NMT_START, NODE), 0);
    B.n_seen = 0;
    B.now += 100.0;
    sim_co_node_poll(&B.node, B.now);
    drain();
    assert_int_equal(B.n_seen, 1);
    assert_int_equal(B.seen[0].data[0], MSID_CO_STATE_OPERATIONAL);
    /* stopped: heartbeats go on, SDO is not served */
    assert_int_equal(msid_co_nmt_send(&IO, MSID_CO_NMT_STOP, NODE), 0);
    uint32_t v;
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1017, 0, 2, &v), -MSID_DAQ_E_TIMEOUT);
    /* reset communication: boot-up again, 0x1017 back to its default (0: no heartbeat) */
    B.n_seen = 0;
    assert_int_equal(msid_co_nmt_send(&IO, MSID_CO_NMT_RESET_COMMUNICATION, NODE), 0);
    drain();
    assert_int_equal(B.n_seen, 1);
    assert_int_equal(B.seen[0].data[0], 0x00);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1017, 0, 2, &v), 0);
    assert_int_equal(v, 0);
}

static void test_heartbeat_stops(void **state)
{
    (void)state;
    sim_co_faults f = NO_FAULTS;
    f.hb_stop_after_s = 1.0;
    start(&f);
    msid_co_sdo s;
    sdo(&s);
    assert_int_equal(msid_co_sdo_write_uint(&s, 0x1017, 0, 2, 100), 0);
    B.n_seen = 0;
    for (int k = 0; k < 40; ++k) { B.now += 50.0; sim_co_node_poll(&B.node, B.now); }
    drain();
    /* beats at 100 .. 900 ms after boot (the write took a fraction of a ms), none from 1 s on */
    assert_int_equal(B.n_seen, 9);
}

static void test_sdo_sizes(void **state)
{
    (void)state;
    start(NULL);
    msid_co_sdo s;
    sdo(&s);
    for (size_t len = 0; len <= 31; ++len) {
        uint8_t w[31], r[64];
        for (size_t i = 0; i < len; ++i) w[i] = (uint8_t)(len * 7u + i * 13u + 1u);
        assert_int_equal(msid_co_sdo_download(&s, 0x2000, 0, w, len), 0);
        size_t got = 999;
        assert_int_equal(msid_co_sdo_upload(&s, 0x2000, 0, r, sizeof r, &got), 0);
        assert_int_equal(got, len);
        if (len) assert_memory_equal(w, r, len);
    }
    uint32_t v;
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1018, 1, 4, &v), 0);
    assert_int_equal(v, 0x4D534944u);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1800, 1, 4, &v), 0);
    assert_int_equal(v, 0x40000180u + NODE);   /* $NODEID in the EDS */
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1014, 0, 4, &v), 0);
    assert_int_equal(v, 0x80u + NODE);         /* added: the EDS has no 0x1014 */
}

static void expect_abort(msid_co_sdo *s, int rc, uint32_t code)
{
    assert_int_not_equal(rc, 0);
    assert_int_equal(s->abort_code, code);
    assert_int_equal(s->abort_by_node, 1);
    assert_non_null(strstr(s->err, msid_co_abort_name(code)));
}

static void test_sdo_aborts(void **state)
{
    (void)state;
    sim_co_faults f = NO_FAULTS;
    f.abort_code = 0x08000020u, f.abort_index = 0x6077, f.abort_sub = 0;
    start(&f);
    msid_co_sdo s;
    sdo(&s);
    uint32_t v;
    uint8_t buf[8];
    expect_abort(&s, msid_co_sdo_read_uint(&s, 0x3000, 0, 4, &v), 0x06020000u);
    expect_abort(&s, msid_co_sdo_read_uint(&s, 0x1018, 9, 4, &v), 0x06090011u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x2001, 0, 4, 1), 0x06010002u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1017, 0, 4, 1), 0x06070012u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1000, 0, 4, 1), 0x06010002u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x6076, 0, 2, 1), 0x06070013u);
    expect_abort(&s, msid_co_sdo_download(&s, 0x6076, 0, buf, 6), 0x06070012u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x6060, 0, 1, 5), 0x06090030u);
    expect_abort(&s, msid_co_sdo_read_uint(&s, 0x6077, 0, 2, &v), 0x08000020u);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x6074, 0, 2, &v), 0);
    /* the toggle bit and the timeout, by raw frames: msid's client never sends them wrong */
    msid_can_frame q, r;
    memset(&q, 0, sizeof q);
    q.id = 0x600 + NODE, q.len = 8;
    q.data[0] = 0x21, q.data[1] = 0x00, q.data[2] = 0x20, q.data[4] = 10;   /* segmented download, 10 bytes */
    io_send(&B, &q);
    assert_int_equal(io_recv(&B, &r, 0), 1);
    assert_int_equal(r.data[0], 0x60);
    q.data[0] = 0x10;   /* toggle 1 where 0 is due */
    io_send(&B, &q);
    assert_int_equal(io_recv(&B, &r, 0), 1);
    assert_int_equal(r.data[0], 0x80);
    assert_int_equal(r.data[4] | r.data[5] << 8 | r.data[6] << 16 | (uint32_t)r.data[7] << 24, 0x05030000u);
    q.data[0] = 0x21;
    io_send(&B, &q);
    assert_int_equal(io_recv(&B, &r, 0), 1);
    B.now += 999.0;
    sim_co_node_poll(&B.node, B.now);
    assert_int_equal(B.n, 0);
    B.now += 2.0;
    sim_co_node_poll(&B.node, B.now);
    assert_int_equal(io_recv(&B, &r, 0), 1);
    assert_int_equal(r.data[0], 0x80);
    assert_int_equal(r.data[4] | r.data[5] << 8 | r.data[6] << 16 | (uint32_t)r.data[7] << 24, 0x05040000u);
    /* block download: not served */
    q.data[0] = 0xC0;
    io_send(&B, &q);
    assert_int_equal(io_recv(&B, &r, 0), 1);
    assert_int_equal(r.data[4] | r.data[5] << 8 | r.data[6] << 16 | (uint32_t)r.data[7] << 24, 0x05040001u);
}

static msid_co_pdo_cfg pdo(int tx, unsigned num, unsigned type, unsigned n, const msid_co_pdo_entry *e)
{
    msid_co_pdo_cfg c;
    memset(&c, 0, sizeof c);
    c.tx = (uint8_t)tx, c.num = (uint16_t)num, c.trans_type = (uint8_t)type, c.n = (uint8_t)n;
    memcpy(c.e, e, n * sizeof *e);
    return c;
}

static void test_pdo_rules(void **state)
{
    (void)state;
    sim_co_faults f = NO_FAULTS;
    f.refuse_index = 0x606C, f.refuse_sub = 0;
    start(&f);
    msid_co_sdo s;
    sdo(&s);
    const msid_co_pdo_entry ok[] = {{0x6041, 0, 16}, {0x6064, 0, 32}, {0x6077, 0, 16}};
    msid_co_pdo_cfg c = pdo(1, 1, 1, 3, ok);
    assert_int_equal(msid_co_pdo_configure(&s, &c, NULL), 0);
    uint32_t v;
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1A00, 0, 1, &v), 0);
    assert_int_equal(v, 3);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1A00, 2, 4, &v), 0);
    assert_int_equal(v, 0x60640020u);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1800, 1, 4, &v), 0);
    assert_int_equal(v & 0x80000000u, 0);
    /* the PDO is valid: its mapping is not to be changed */
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1A00, 0, 1, 0), 0x08000022u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1800, 3, 2, 10), 0x06090030u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1800, 2, 1, 241), 0x06090030u);
    /* not mappable, the refused entry, an RPDO of a read-only object: refused, the old mapping back */
    const msid_co_pdo_entry bad1[] = {{0x1000, 0, 32}};
    msid_co_pdo_cfg saved;
    assert_int_equal(msid_co_pdo_save(&s, 1, 2, &saved), 0);
    c = pdo(1, 2, 1, 1, bad1);
    expect_abort(&s, msid_co_pdo_configure(&s, &c, &saved), 0x06040041u);
    const msid_co_pdo_entry bad2[] = {{0x606C, 0, 32}};
    c = pdo(1, 2, 1, 1, bad2);
    expect_abort(&s, msid_co_pdo_configure(&s, &c, &saved), 0x06040041u);
    const msid_co_pdo_entry bad3[] = {{0x6064, 0, 32}};
    c = pdo(0, 1, 1, 1, bad3);
    expect_abort(&s, msid_co_pdo_configure(&s, &c, NULL), 0x06040041u);
    const msid_co_pdo_entry bad4[] = {{0x3000, 0, 32}};
    c = pdo(1, 2, 1, 1, bad4);
    expect_abort(&s, msid_co_pdo_configure(&s, &c, &saved), 0x06020000u);
    /* more than 64 bits, written entry by entry (msid's own check refuses it before sending) */
    assert_int_equal(msid_co_sdo_write_uint(&s, 0x1801, 1, 4, 0x80000280u + NODE), 0);
    assert_int_equal(msid_co_sdo_write_uint(&s, 0x1A01, 0, 1, 0), 0);
    for (uint8_t k = 1; k <= 3; ++k) assert_int_equal(msid_co_sdo_write_uint(&s, 0x1A01, k, 4, 0x60640020u), 0);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1A01, 0, 1, 3), 0x06040042u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1A01, 0, 1, 9), 0x06090031u);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1801, 1, 4, 0x20000123u), 0x06090030u);
    /* operational: no mapping changes even of a PDO that is not valid */
    assert_int_equal(msid_co_nmt_send(&IO, MSID_CO_NMT_START, NODE), 0);
    expect_abort(&s, msid_co_sdo_write_uint(&s, 0x1A01, 1, 4, 0x60410010u), 0x08000022u);
}

static void test_402_walk_and_fault(void **state)
{
    (void)state;
    sim_co_faults f = NO_FAULTS;
    f.emcy_at_sync = 3;
    start(&f);
    msid_co_sdo s;
    sdo(&s);
    msid_co402_state st;
    uint32_t v;
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x6041, 0, 2, &v), 0);
    assert_int_equal(msid_co402_decode((uint16_t)v), MSID_CO402_SWITCH_ON_DISABLED);
    assert_int_equal(msid_co402_set_mode(&s, MSID_CO402_MODE_CSV, 100), 0);
    assert_int_equal(msid_co402_goto(&s, 1, 0, 500, &st), 0);
    assert_int_equal(st, MSID_CO402_OPERATION_ENABLED);
    assert_int_equal(msid_co402_goto(&s, 0, 0, 500, &st), 0);
    assert_int_equal(st, MSID_CO402_SWITCH_ON_DISABLED);
    /* quick stop from operation enabled stays in quick stop active (option code 6) */
    assert_int_equal(msid_co402_goto(&s, 1, 0, 500, &st), 0);
    assert_int_equal(msid_co_sdo_write_uint(&s, 0x6040, 0, 2, MSID_CO402_CW_QUICK_STOP), 0);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x6041, 0, 2, &v), 0);
    assert_int_equal(msid_co402_decode((uint16_t)v), MSID_CO402_QUICK_STOP_ACTIVE);
    assert_int_equal(msid_co402_goto(&s, 1, 0, 500, &st), 0);
    /* the fault at the third SYNC: EMCY 0x2310 with the error register, statusword fault */
    B.n_seen = 0;
    msid_can_frame sync;
    msid_co_sync_frame(&sync, 0);
    for (int k = 0; k < 3; ++k) io_send(&B, &sync);
    drain();
    assert_int_equal(B.n_seen, 1);
    msid_co_emcy e;
    assert_int_equal(msid_co_emcy_decode(&B.seen[0], NODE, &e), 1);
    assert_int_equal(e.code, 0x2310);
    assert_int_equal(e.reg, 0x03);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x6041, 0, 2, &v), 0);
    assert_int_equal(msid_co402_decode((uint16_t)v), MSID_CO402_FAULT);
    assert_int_equal(msid_co402_goto(&s, 1, 0, 500, &st), -MSID_DAQ_E_DEVICE);
    B.n_seen = 0;
    assert_int_equal(msid_co402_goto(&s, 1, 1, 500, &st), 0);
    assert_int_equal(st, MSID_CO402_OPERATION_ENABLED);
    drain();
    assert_int_equal(B.n_seen, 1);
    assert_int_equal(msid_co_emcy_decode(&B.seen[0], NODE, &e), 1);
    assert_int_equal(e.code, 0x0000);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x1001, 0, 1, &v), 0);
    assert_int_equal(v, 0);
}

static int32_t le(const uint8_t *d, int n)
{
    uint32_t x = 0;
    for (int i = 0; i < n; ++i) x |= (uint32_t)d[i] << (8 * i);
    return n == 2 ? (int16_t)x : (int32_t)x;
}

/* CST: TPDO1 (position, velocity) and TPDO2 (torque demand, actual) every SYNC, the target by RPDO1 */
static void sync_setup(msid_co_sdo *s, unsigned tpdo2_type)
{
    const msid_co_pdo_entry t1[] = {{0x6064, 0, 32}, {0x606C, 0, 32}};
    const msid_co_pdo_entry t2[] = {{0x6074, 0, 16}, {0x6077, 0, 16}};
    const msid_co_pdo_entry r1[] = {{0x6071, 0, 16}};
    msid_co_pdo_cfg c = pdo(1, 1, 1, 2, t1);
    assert_int_equal(msid_co_pdo_configure(s, &c, NULL), 0);
    c = pdo(1, 2, tpdo2_type, 2, t2);
    assert_int_equal(msid_co_pdo_configure(s, &c, NULL), 0);
    c = pdo(0, 1, 1, 1, r1);
    assert_int_equal(msid_co_pdo_configure(s, &c, NULL), 0);
    assert_int_equal(msid_co_sdo_write_uint(s, 0x1006, 0, 4, 1000), 0);
    assert_int_equal(msid_co402_set_mode(s, MSID_CO402_MODE_CST, 100), 0);
    msid_co402_state st;
    assert_int_equal(msid_co402_goto(s, 1, 0, 500, &st), 0);
    assert_int_equal(msid_co_nmt_send(&IO, MSID_CO_NMT_START, NODE), 0);
    drain();
    B.n_seen = 0;
}

static void send_target(int16_t pm)
{
    msid_can_frame r;
    memset(&r, 0, sizeof r);
    r.id = 0x200 + NODE, r.len = 2;
    r.data[0] = (uint8_t)pm, r.data[1] = (uint8_t)((uint16_t)pm >> 8);
    io_send(&B, &r);
}

static void test_sync_plant(void **state)
{
    (void)state;
    start(NULL);
    msid_co_sdo s;
    sdo(&s);
    sync_setup(&s, 1);
    sim_twomass ref;
    const sim_twomass_par p = sim_twomass_default();
    assert_int_equal(sim_twomass_init(&ref, &p, 1e-3), 0);
    msid_can_frame sync;
    msid_co_sync_frame(&sync, 0);
    int16_t prev = 0;
    for (int j = 0; j < 200; ++j) {
        /* a target sequence: steps and a chirp-like swing, per mille of the rated 1 N m */
        const int16_t t = (int16_t)(j < 20 ? 0 : j < 60 ? 300 : (int)lround(500.0 * sin(0.002 * j * j)));
        send_target(t);
        B.n_seen = 0;
        io_send(&B, &sync);
        drain();
        assert_int_equal(B.n_seen, 2);
        assert_int_equal(B.seen[0].id, 0x180 + NODE);
        assert_int_equal(B.seen[1].id, 0x280 + NODE);
        /* the TPDO of SYNC j holds x after j steps and the demand of the step before */
        assert_int_equal(le(&B.seen[0].data[0], 4), sim_co402_pos_to_bus(ref.x[0]));
        assert_int_equal(le(&B.seen[0].data[4], 4), sim_co402_vel_to_bus(ref.x[1]));
        assert_int_equal(le(&B.seen[1].data[0], 2), prev);
        assert_int_equal(le(&B.seen[1].data[2], 2), prev);
        sim_twomass_step(&ref, t * 1e-3);
        prev = t;
    }
    assert_true(fabs(ref.x[1]) > 1.0);   /* the plant moved */
}

/* the torque offset 0x60B2 is added to the demand (CST here; CSV and CSP alike): the TPDO after the SYNC that took
 * target and offset shows their sum, and the offset alone once the target is 0 */
static void test_torque_offset(void **state)
{
    (void)state;
    start(NULL);
    msid_co_sdo s;
    sdo(&s);
    sync_setup(&s, 1);
    assert_int_equal(msid_co_sdo_write_uint(&s, 0x60B2, 0, 2, (uint16_t)-120), 0);
    drain();
    msid_can_frame sync;
    msid_co_sync_frame(&sync, 0);
    const int16_t target[] = {300, 0, 0};
    const int16_t shown[] = {0, 180, -120};   /* each TPDO2: the demand of the SYNC before */
    for (int j = 0; j < 3; ++j) {
        send_target(target[j]);
        B.n_seen = 0;
        io_send(&B, &sync);
        drain();
        assert_int_equal(B.n_seen, 2);
        assert_int_equal(le(&B.seen[1].data[0], 2), shown[j]);
    }
}

static void test_sync_every_n_and_drops(void **state)
{
    (void)state;
    sim_co_faults f = NO_FAULTS;
    f.drop_every = 5;
    start(&f);
    msid_co_sdo s;
    sdo(&s);
    sync_setup(&s, 3);
    msid_can_frame sync;
    msid_co_sync_frame(&sync, 0);
    int n1 = 0, n2 = 0;
    for (int j = 0; j < 30; ++j) io_send(&B, &sync);
    drain();
    for (int k = 0; k < B.n_seen; ++k) {
        n1 += B.seen[k].id == 0x180 + NODE;
        n2 += B.seen[k].id == 0x280 + NODE;
    }
    /* due: 30 TPDO1 and 10 TPDO2, 40 in all; every 5th of those dropped */
    assert_int_equal(n1 + n2, 40 - 8);
    assert_int_equal(B.node.cnt.tpdo_dropped, 8);
    assert_true(n2 >= 7 && n2 <= 10);
    /* not in operational: no PDOs */
    assert_int_equal(msid_co_nmt_send(&IO, MSID_CO_NMT_PREOPERATIONAL, NODE), 0);
    B.n_seen = 0;
    for (int j = 0; j < 5; ++j) io_send(&B, &sync);
    drain();
    assert_int_equal(B.n_seen, 0);
}

/* every 4th SYNC taken 30 ms late: no answer to it until then, the target and SYNC behind it held and taken
   in order after it, and the answers (the plant's steps) the same as a node without the fault gives */
static void late_sync_run(const sim_co_faults *f, int32_t vel[12], int *missing_at_once)
{
    start(f);
    msid_co_sdo s;
    sdo(&s);
    sync_setup(&s, 1);
    msid_can_frame sync;
    msid_co_sync_frame(&sync, 0);
    int got = 0;
    *missing_at_once = 0;
    for (int j = 0; j < 12; ++j) {
        send_target((int16_t)(j % 3 == 0 ? 400 : -200));
        B.n_seen = 0;
        io_send(&B, &sync);
        drain();
        if (B.n_seen == 0) (*missing_at_once)++;
        B.now += 10.0;   /* 10 ms to the next tick; a held SYNC is due 30 ms after it came */
        sim_co_node_poll(&B.node, B.now);
        drain();
        for (int k = 0; k < B.n_seen; ++k)
            if (B.seen[k].id == 0x180 + NODE && got < 12) vel[got++] = le(&B.seen[k].data[4], 4);
    }
    for (int k = 0; k < 4; ++k) { B.now += 10.0; sim_co_node_poll(&B.node, B.now); }
    B.n_seen = 0;
    drain();
    for (int k = 0; k < B.n_seen; ++k)
        if (B.seen[k].id == 0x180 + NODE && got < 12) vel[got++] = le(&B.seen[k].data[4], 4);
    assert_int_equal(got, 12);
}

static void test_late_sync(void **state)
{
    (void)state;
    int32_t on_time[12], late[12];
    int missing = 0;
    late_sync_run(NULL, on_time, &missing);
    assert_int_equal(missing, 0);
    sim_co_faults f = NO_FAULTS;
    f.late_sync_every = 4;
    f.late_sync_ms = 30;
    late_sync_run(&f, late, &missing);
    /* SYNCs 4, 8 and 12 (counted from the first after the setup's) held, and the ones behind them */
    assert_int_equal(B.node.cnt.late_syncs, 3);
    assert_true(missing >= 3);
    assert_memory_equal(on_time, late, sizeof late);
    assert_true(on_time[11] != on_time[10]);   /* the plant moved */
}

/* the continuous model's derivative, for an independent integration */
static void deriv(const sim_twomass_par *p, const double x[4], double tau, double dx[4])
{
    const double tw = p->k * (x[0] - x[2]) + p->d * (x[1] - x[3]);
    dx[0] = x[1];
    dx[1] = (tau - tw - p->bm * x[1]) / p->jm;
    dx[2] = x[3];
    dx[3] = (tw - p->bl * x[3]) / p->jl;
}

/* A and B of the step against 2000 RK4 sub-steps of the continuous model over one period */
static void test_plant_step_exact(void **state)
{
    (void)state;
    sim_twomass m;
    const sim_twomass_par p = sim_twomass_default();
    assert_int_equal(sim_twomass_init(&m, &p, 1e-3), 0);
    for (int col = 0; col <= 4; ++col) {
        double x[4] = {0, 0, 0, 0};
        const double tau = col == 4 ? 1.0 : 0.0;
        if (col < 4) x[col] = 1.0;
        const int n = 2000;
        const double h = 1e-3 / n;
        for (int i = 0; i < n; ++i) {
            double k1[4], k2[4], k3[4], k4[4], t[4];
            deriv(&p, x, tau, k1);
            for (int j = 0; j < 4; ++j) t[j] = x[j] + 0.5 * h * k1[j];
            deriv(&p, t, tau, k2);
            for (int j = 0; j < 4; ++j) t[j] = x[j] + 0.5 * h * k2[j];
            deriv(&p, t, tau, k3);
            for (int j = 0; j < 4; ++j) t[j] = x[j] + h * k3[j];
            deriv(&p, t, tau, k4);
            for (int j = 0; j < 4; ++j) x[j] += h / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
        }
        for (int i = 0; i < 4; ++i) {
            const double want = col < 4 ? m.a[i][col] : m.b[i];
            if (!(fabs(x[i] - want) <= 1e-9 * (1.0 + fabs(want))))
                fail_msg("column %d row %d: step %.12g, RK4 %.12g", col, i, want, x[i]);
        }
    }
}

/* The plant's exact FRF from the step function's A and B: resonance and antiresonance where the
   continuous model puts them, and low-frequency velocity gain 1 / (j w (Jm + Jl)). */
static void test_plant_frf(void **state)
{
    (void)state;
    sim_twomass m;
    const sim_twomass_par p = sim_twomass_default();
    const double ts = 1e-3;
    assert_int_equal(sim_twomass_init(&m, &p, ts), 0);
    double best = 0, f_peak = 0, low = INFINITY, f_notch = 0;
    for (double fh = 40.0; fh <= 300.0; fh += 0.05) {
        const double complex z = cexp(I * 2.0 * PI * fh * ts);
        /* (z I - A) g = B by Gaussian elimination, g[1] the velocity */
        double complex a[4][5];
        for (int i = 0; i < 4; ++i) {
            for (int j = 0; j < 4; ++j) a[i][j] = (i == j ? z : 0) - m.a[i][j];
            a[i][4] = m.b[i];
        }
        for (int c = 0; c < 4; ++c) {
            int piv = c;
            for (int r = c + 1; r < 4; ++r) if (cabs(a[r][c]) > cabs(a[piv][c])) piv = r;
            for (int j = 0; j < 5; ++j) { double complex t = a[c][j]; a[c][j] = a[piv][j]; a[piv][j] = t; }
            for (int r = 0; r < 4; ++r) {
                if (r == c) continue;
                const double complex q = a[r][c] / a[c][c];
                for (int j = c; j < 5; ++j) a[r][j] -= q * a[c][j];
            }
        }
        const double g = cabs(a[1][4] / a[1][1]);
        if (g > best) best = g, f_peak = fh;
        if (fh < 110.0 && g < low) low = g, f_notch = fh;   /* below the resonance: the antiresonance */
    }
    const double fr = sqrt(p.k * (p.jm + p.jl) / (p.jm * p.jl)) / (2.0 * PI);
    const double fa = sqrt(p.k / p.jl) / (2.0 * PI);
    assert_true(fabs(f_peak - fr) < 1.0);
    /* ZOH sampling moves the zeros: the discrete antiresonance is 81.3 Hz at 1 kHz (scipy's expm agrees) */
    if (!(fabs(f_notch - fa) < 2.5)) fail_msg("antiresonance at %g Hz, expected %g", f_notch, fa);
    if (!(fabs(f_peak - fr) < 1.0)) fail_msg("resonance at %g Hz, expected %g", f_peak, fr);
    /* a step of torque: after 1 s the velocity is near tau t / (Jm + Jl) less the viscous loss */
    sim_twomass_init(&m, &p, ts);
    for (int k = 0; k < 1000; ++k) sim_twomass_step(&m, 1e-3);
    const double b = p.bm + p.bl, jt = p.jm + p.jl;
    const double expect = 1e-3 / b * (1.0 - exp(-b / jt * 1.0));
    assert_true(fabs(m.x[1] - expect) < 1e-3 * expect);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_boot_and_heartbeat), cmocka_unit_test(test_heartbeat_stops),
        cmocka_unit_test(test_sdo_sizes),          cmocka_unit_test(test_sdo_aborts),
        cmocka_unit_test(test_pdo_rules),          cmocka_unit_test(test_402_walk_and_fault),
        cmocka_unit_test(test_sync_plant), cmocka_unit_test(test_torque_offset),         cmocka_unit_test(test_sync_every_n_and_drops), cmocka_unit_test(test_late_sync),
        cmocka_unit_test(test_plant_frf),          cmocka_unit_test(test_plant_step_exact),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
