/* After init, the daq hot path allocates nothing (issue 15): malloc, calloc, realloc, aligned_alloc,
 * posix_memalign and free are interposed here and counted around (1) CAN frames -> decoder -> msid_meas
 * -> FRF, and (2) the Modbus ring poller reading an in-memory device -> msid_meas. A negative control
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
#include "msid_daq/msid_mb_acq.h"

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
    const msid_mb_backend be = {"mem", rd, rd, wr, nop, rc0, exc, err, nop, NULL};
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

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(negative_control),
        cmocka_unit_test(can_hot_path_allocates_nothing),
        cmocka_unit_test(modbus_hot_path_allocates_nothing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
