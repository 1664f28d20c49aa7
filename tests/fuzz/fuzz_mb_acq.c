/* libFuzzer: the Modbus ring poller against a hostile device in process. Every register the host reads
 * (header and ring) comes from the fuzz input; the device's answers to commands are honoured so the
 * poller runs. It must end with a result or one error in bounded work, never read out of bounds, and
 * never push more than the design's K P samples per segment. */
#include "fuzz_util.h"
#include "msid/msid.h"
#include "msid_daq/msid_mb_acq.h"

typedef struct { fz in; uint32_t cmd_seq; int wrote_cmd; uint32_t reads; } dev;

static int rd(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst)
{
    dev *d = ctx;
    if (!d->in.n || ++d->reads > 4096) return -MSID_DAQ_E_IO;
    for (uint32_t k = 0; k < n; ++k) dst[k] = (uint16_t)fz_u16(&d->in);
    if (addr == 0 && n >= MSID_MB_IR_HEADER) {
        dst[MSID_MB_IR_MAGIC] = MSID_MB_MAGIC;   /* past the magic check, to the counts */
        if (d->wrote_cmd) dst[MSID_MB_IR_CMD_DONE] = (uint16_t)d->cmd_seq;
    }
    return 0;
}
static int rh(void *ctx, uint32_t a, uint32_t n, uint16_t *dst) { return rd(ctx, a, n, dst); }
static int wr(void *ctx, uint32_t addr, uint32_t n, const uint16_t *src)
{
    dev *d = ctx;
    if (addr == MSID_MB_HR_CMD_SEQ && n) { d->cmd_seq = src[0]; d->wrote_cmd = 1; }
    return 0;
}
static void nop(void *ctx) { (void)ctx; }
static int rc0(void *ctx) { (void)ctx; return 0; }
static uint32_t exc(void *ctx) { (void)ctx; return 4; }
static const char *err(void *ctx) { (void)ctx; return "fuzz"; }

static const uint32_t BINS[2] = {1, 3};

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    dev d = {{data, size}, 0, 0, 0};
    const uint32_t enc = fz_u8(&d.in) % 3, wo = fz_u8(&d.in) % 4, K = 2 + fz_u8(&d.in) % 4, P = 16;
    const msid_mb_backend be = {"fuzz", rd, rh, wr, nop, rc0, exc, err, nop, NULL, NULL, NULL};
    msid_mb_transport tr = {&be, &d};
    msid_mb_client cl;
    msid_mb_client_init(&cl, &tr, 1, 1);
    cl.retries = 0;       /* no retries and no backoff sleeps: one bad reply is one error */
    cl.backoff_ms = 0;
    msid_twiddle tw;
    void *tw_mem = fz_twiddle(P, &tw);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = 1; mc.n_lines = 2; mc.bins = BINS;
    mc.twiddle = &tw; mc.path = MSID_DFT_STREAM;
    const size_t nm = msid_meas_mem_size(&mc);
    void *mm = fz_alloc(nm);
    msid_meas ms;
    if (!mm || msid_meas_init(&ms, &mc, mm, nm) != MSID_OK) abort();
    msid_mb_acq_cfg qc;
    memset(&qc, 0, sizeof qc);
    qc.client = &cl; qc.batch = 4; qc.n_inputs = 1; qc.n_outputs = 1; qc.encoding = enc; qc.word_order = wo;
    qc.scale = 0.001; qc.meas = &ms; qc.period = P;
    const size_t nq = msid_mb_acq_mem_size(&qc);
    void *mq = fz_alloc(nq);
    msid_mb_acq q;
    if (!mq || msid_mb_acq_init(&q, &qc, mq, nq) != MSID_OK) abort();
    if (msid_mb_acq_start(&q, 0, K) == 0) {
        for (int i = 0; i < 256; ++i) {
            int prog = 0;
            const int r = msid_mb_acq_poll(&q, &prog);
            if (r != 0) break;
        }
        /* Per segment at most K P samples pushed, and per restart at most 2 K P samples declared lost before the
           new segment's start (a segment may begin up to K P per restart after the last one seen, at most two
           restarts between polls: msid_mb_acq.c MAX_RESTARTS_PER_POLL). */
        if (q.st.cnt.samples + q.st.cnt.samples_lost > (uint64_t)K * P * (3 * q.st.cnt.segments + 1)) abort();
    }
    free(mq);
    free(mm);
    free(tw_mem);
    return 0;
}
