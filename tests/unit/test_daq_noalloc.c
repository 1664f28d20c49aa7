/* After init, the daq hot path allocates nothing: malloc, calloc, realloc, aligned_alloc,
 * posix_memalign and free are interposed here and counted around (1) CAN frames -> decoder -> msid_meas
 * -> FRF, (2) the Modbus ring poller reading an in-memory device -> msid_meas, and (3) a DBC's receive
 * path (lookup by id, presence, decode, encode) after msid_dbc_init, and (4) the CANopen master: segmented
 * SDO transfers, a PDO configured and put back, a CiA 402 drive enabled and disabled over SDO, heartbeat and
 * EMCY frames decoded (against the test node of co_test_node.h). A negative control
 * proves the counter sees an allocation. Not built under ASan (it interposes the allocator itself). */
#define _GNU_SOURCE
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "msid/msid.h"
#include "msid_daq/msid_can_decoder.h"
#include "msid_daq/msid_dbc.h"
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_co_402.h"
#include "msid_daq/msid_co_emcy.h"
#include "msid_daq/msid_co_nmt.h"
#include "msid_daq/msid_co_pdo.h"
#include "co_test_node.h"

/* ---- the interposer: glibc's own entry points underneath ---- */
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void *__libc_memalign(size_t, size_t);
extern void __libc_free(void *);
static volatile long ALLOCS;
void *malloc(size_t n) { ALLOCS++; return __libc_malloc(n); }
void *calloc(size_t a, size_t b) { ALLOCS++; return __libc_calloc(a, b); }
void *realloc(void *p, size_t n) { ALLOCS++; return __libc_realloc(p, n); }
void *aligned_alloc(size_t al, size_t n) { ALLOCS++; return __libc_memalign(al, n); }
int posix_memalign(void **p, size_t al, size_t n) { ALLOCS++; *p = __libc_memalign(al, n); return *p ? 0 : 12; }
void free(void *p) { if (p) ALLOCS++; __libc_free(p); }

#define P 32u
static const uint32_t BINS[3] = {1, 3, 5};
static uint8_t TWM[1 << 16] __attribute__((aligned(64)));
static uint8_t MEM[3][1 << 20] __attribute__((aligned(64)));

static void meas_setup(msid_twiddle *tw, msid_meas *ms, uint32_t nu, uint32_t ny, uint32_t m)
{
    assert_int_equal(msid_twiddle_init(tw, P, TWM, sizeof TWM), MSID_OK);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = nu; mc.n_outputs = ny; mc.n_experiments = m; mc.n_lines = 3; mc.bins = BINS;
    mc.twiddle = tw; mc.path = MSID_DFT_STREAM; mc.transient = MSID_TRANSIENT_FLAG; mc.max_periods = 16;
    assert_true(msid_meas_mem_size(&mc) <= sizeof MEM[0]);
    assert_int_equal(msid_meas_init(ms, &mc, MEM[0], sizeof MEM[0]), MSID_OK);
}

static void negative_control(void **st)
{
    (void)st;
    const long a0 = ALLOCS;
    void *volatile p = malloc(16);
    free(p);
    assert_int_equal(ALLOCS - a0, 2);
}

static void can_hot_path_allocates_nothing(void **st)
{
    (void)st;
    msid_twiddle tw;
    msid_meas ms;
    meas_setup(&tw, &ms, 1, 1, 1);
    msid_can_decoder_cfg dc = {0x200, 1, 1, MSID_CAN_ENC_F32, 0, 0.001, P, 16, 7, &ms, 6 * P};
    assert_int_equal(msid_can_decoder_init(&(msid_can_decoder){0}, &dc, MEM[1], sizeof MEM[1]), MSID_OK);
    msid_can_decoder d;
    assert_int_equal(msid_can_decoder_init(&d, &dc, MEM[1], sizeof MEM[1]), MSID_OK);
    msid_frf_cfg fc = {P, 1, 1, 1, 3, 0, NULL};
    msid_frf f;
    assert_int_equal(msid_frf_init(&f, &fc, MEM[2], sizeof MEM[2]), MSID_OK);
    msid_can_frame fr;
    const long a0 = ALLOCS;
    memset(&fr, 0, sizeof fr);
    fr.id = 0x202; fr.len = 8;
    msid_can_encode_state(fr.data, MSID_CAN_STATE_RUNNING, 0, 0, 6 * P);
    assert_int_equal(msid_can_decoder_feed(&d, &fr), MSID_OK);
    for (uint32_t s = 0; s < 6 * P; ++s) {
        const double ph = 6.283185307179586 * (double)s / P;   /* a multisine at the lines 1, 3, 5 */
        const double u = cos(ph) + cos(3 * ph + 1) + cos(5 * ph + 2);
        const double row[2] = {u, 0.5 * u + 0.01 * (double)((s * 7919u) % 13u)};
        for (uint32_t k = 0; k < 2; ++k) {
            memset(&fr, 0, sizeof fr);
            fr.id = 0x200 + msid_can_chunk_id(MSID_CAN_ENC_F32, 0, k);
            fr.len = 8;
            msid_can_encode_sample(fr.data, MSID_CAN_ENC_F32, 0, k, s, 0,
                                   (s % P == 0 ? MSID_CAN_PSTART : 0u) | (s == 0 ? MSID_CAN_SEGSTART : 0u), row, 2, 0.001);
            assert_int_equal(msid_can_decoder_feed(&d, &fr), MSID_OK);
        }
    }
    memset(&fr, 0, sizeof fr);
    fr.id = 0x202; fr.len = 8;
    msid_can_encode_state(fr.data, MSID_CAN_STATE_DONE, 0, 0, 6 * P);
    assert_int_equal(msid_can_decoder_feed(&d, &fr), MSID_OK);
    const msid_pstats *ps[1] = {msid_meas_stats(&ms, 0)};
    assert_int_equal(msid_frf_compute(&f, ps), MSID_OK);
    assert_int_equal(ALLOCS - a0, 0);
    assert_int_equal(d.cnt.samples, 6 * P);
    assert_int_equal(msid_pstats_count(ps[0]), 6);
}

/* An in-memory msid-modbus/1 device with a ring of 6 P samples, all written and DONE. */
typedef struct { uint16_t ir[65536]; uint16_t cmd_seq; } mdev;
static mdev DEV;
static int rd(void *ctx, uint32_t a, uint32_t n, uint16_t *dst)
{
    mdev *d = ctx;
    d->ir[MSID_MB_IR_CMD_DONE] = d->cmd_seq;
    memcpy(dst, d->ir + a, n * sizeof *dst);
    return 0;
}
static int wr(void *ctx, uint32_t a, uint32_t n, const uint16_t *src)
{
    mdev *d = ctx;
    if (a == MSID_MB_HR_CMD_SEQ && n) d->cmd_seq = src[0];
    return 0;
}
static void nop(void *ctx) { (void)ctx; }
static int rc0(void *ctx) { (void)ctx; return 0; }
static uint32_t exc(void *ctx) { (void)ctx; return 0; }
static const char *err(void *ctx) { (void)ctx; return ""; }

static void modbus_hot_path_allocates_nothing(void **st)
{
    (void)st;
    msid_twiddle tw;
    msid_meas ms;
    meas_setup(&tw, &ms, 1, 1, 1);
    const uint32_t W = msid_mb_sample_regs(MSID_MB_ENC_F32, 2);
    msid_mb_header h;
    memset(&h, 0, sizeof h);
    h.magic = MSID_MB_MAGIC; h.version = MSID_MB_PROTO_VERSION; h.state = MSID_MB_STATE_DONE; h.nu = 1; h.ny = 1;
    h.encoding = MSID_MB_ENC_F32; h.sample_regs = W; h.ring_addr = MSID_MB_RING_ADDR; h.ring_samples = 1000;
    h.write_index = 6 * P; h.total = 6 * P; h.period = P; h.periods = 6;
    msid_mb_header_encode(DEV.ir, &h);
    for (uint32_t s = 0; s < 6 * P; ++s) {
        uint16_t *r = DEV.ir + MSID_MB_RING_ADDR + s * W;
        r[0] = (uint16_t)s;
        const double ph = 6.283185307179586 * (double)s / P, u = cos(ph) + cos(3 * ph + 1) + cos(5 * ph + 2);
        msid_mb_encode_value(r + 1, u, MSID_MB_ENC_F32, 0, 1.0);
        msid_mb_encode_value(r + 3, 0.5 * u + 0.01 * (double)((s * 7919u) % 13u), MSID_MB_ENC_F32, 0, 1.0);
    }
    const msid_mb_backend be = {"mem", rd, rd, wr, nop, rc0, exc, err, nop, NULL, NULL, NULL};
    msid_mb_transport tr = {&be, &DEV};
    msid_mb_client cl;
    msid_mb_client_init(&cl, &tr, 1, 1);
    msid_mb_acq_cfg qc;
    memset(&qc, 0, sizeof qc);
    qc.client = &cl; qc.n_inputs = 1; qc.n_outputs = 1; qc.encoding = MSID_MB_ENC_F32; qc.scale = 1.0; qc.meas = &ms;
    qc.period = P;
    msid_mb_acq q;
    assert_int_equal(msid_mb_acq_init(&q, &qc, MEM[1], sizeof MEM[1]), MSID_OK);
    const long a0 = ALLOCS;
    assert_int_equal(msid_mb_acq_start(&q, 0, 6), 0);
    int r = 0, prog;
    for (int i = 0; i < 100 && r == 0; ++i) r = msid_mb_acq_poll(&q, &prog);
    assert_int_equal(r, 1);
    assert_int_equal(ALLOCS - a0, 0);
    assert_int_equal(q.st.cnt.samples, 6 * P);
}

/* (3) the DBC receive path: a frame's message by id, presence, decode and encode of every signal */
static void dbc_receive_path_allocates_nothing(void **st)
{
    (void)st;
    static const char text[] = "BO_ 2147483904 S: 8 A\n SG_ mux M : 0|8@1+ (1,0) [0|255] \"\" B\n"
                               " SG_ v m1 : 15|16@0- (0.1,-5) [-100|100] \"V\" B\n SG_ f : 32|32@1- (1,0) [0|0] \"\" B\n"
                               "SIG_VALTYPE_ 2147483904 f : 1;\n";
    static _Alignas(8) unsigned char mem[4096];
    msid_dbc d;
    assert_true(msid_dbc_mem_size(text, sizeof text - 1) <= sizeof mem);
    assert_int_equal(msid_dbc_init(&d, text, sizeof text - 1, mem, sizeof mem), 0);
    uint8_t data[8] = {1, 0x12, 0x34, 0, 0, 0, 0xC0, 0x3F};
    const long a0 = ALLOCS;
    double sum = 0;
    for (int n = 0; n < 1000; ++n) {
        const msid_dbc_message *m = msid_dbc_message_by_id(&d, 0x100u | MSID_CAN_EFF_FLAG);
        assert_non_null(m);
        for (uint32_t k = 0; k < m->n_signals; ++k) {
            const msid_dbc_signal *s = &d.signals[m->first_signal + k];
            double v;
            if (msid_dbc_present(&d, s, data, 8) == 1 && msid_dbc_decode(s, data, 8, &v) == 0) {
                sum += v;
                (void)msid_dbc_encode(s, v, data, 8);
            }
        }
    }
    assert_int_equal(ALLOCS - a0, 0);
    assert_true(sum != 0);
}

/* (4) the CANopen master over the test node: a drive's records, its statusword following the controlword */
static void co_follow(test_node *t, uint16_t index, uint8_t sub, uint32_t value)
{
    (void)sub;
    if (index != 0x6040) return;
    /* shutdown -> ready, switch on -> switched on, enable -> operation enabled, quick stop / disable -> disabled */
    const uint32_t sw = value == 0x06 ? 0x21 : value == 0x07 ? 0x23 : value == 0x0F ? 0x27 : 0x40;
    tn_find(t, 0x6041, 0)->value = sw;
}

static void canopen_master_allocates_nothing(void **st)
{
    (void)st;
    static test_node t;
    memset(&t, 0, sizeof t);
    t.id = 3;
    tn_add(&t, 0x6040, 0, 2, TN_RW, 1, 0);
    tn_add(&t, 0x6041, 0, 2, TN_RO, 1, 0x40);
    tn_add(&t, 0x6064, 0, 4, TN_RO, 1, 0);
    tn_add_pdo(&t, 1, 1, 0x183, 1);
    t.on_write = co_follow;
    const msid_co_io io = tn_io(&t);
    msid_co_sdo s;
    assert_int_equal(msid_co_sdo_init(&s, &io, 3, 50), 0);
    msid_co_hb hb;
    assert_int_equal(msid_co_hb_init(&hb, 3, 100), 0);
    const long a0 = ALLOCS;
    msid_co_pdo_cfg saved, c = {.tx = 1, .num = 1, .trans_type = 1, .n = 2};
    c.e[0] = (msid_co_pdo_entry){0x6041, 0, 16};
    c.e[1] = (msid_co_pdo_entry){0x6064, 0, 32};
    assert_int_equal(msid_co_pdo_save(&s, 1, 1, &saved), 0);
    assert_int_equal(msid_co_pdo_configure(&s, &c, &saved), 0);
    assert_int_equal(msid_co_pdo_restore(&s, &saved), 0);
    msid_co402_state fin;
    assert_int_equal(msid_co402_goto(&s, 1, 0, 1000, &fin), 0);
    assert_int_equal(msid_co402_goto(&s, 0, 0, 1000, &fin), 0);
    msid_can_frame f = {.id = 0x703, .len = 1, .data = {0x05}};
    for (uint64_t ms = 0; ms < 1000; ms += 10) {
        assert_int_equal(msid_co_hb_frame(&hb, &f, ms), 1);
        assert_int_equal(msid_co_hb_check(&hb, ms + 5), MSID_CO_HB_ALIVE);
    }
    msid_can_frame e = {.id = 0x083, .len = 8, .data = {0x10, 0x23, 0x01}};
    msid_co_emcy em;
    assert_int_equal(msid_co_emcy_decode(&e, 3, &em), 1);
    assert_int_equal(ALLOCS - a0, 0);
    assert_int_equal(em.code, 0x2310);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(negative_control),
        cmocka_unit_test(can_hot_path_allocates_nothing),
        cmocka_unit_test(modbus_hot_path_allocates_nothing),
        cmocka_unit_test(dbc_receive_path_allocates_nothing),
        cmocka_unit_test(canopen_master_allocates_nothing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
