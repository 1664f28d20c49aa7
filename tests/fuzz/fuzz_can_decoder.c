/* libFuzzer: the msid-can/1 frame decoder (classic, FD, error, status and foreign frames) feeding a real
 * msid_meas, then the FRF. The first bytes choose the configuration (encoding, FD, window, channels,
 * the design's K P bound); the rest is a stream of frames: id (4), len (1), flags (1), data (len). */
#include "fuzz_util.h"
#include "msid/msid.h"
#include "msid_daq/msid_can_decoder.h"

static const uint32_t BINS[3] = {1, 2, 3};   /* below P/2 for every P here */

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz in = {data, size};
    const uint32_t P = 8u << (fz_u8(&in) % 3);   /* 8, 16, 32 */
    const uint32_t nu = 1 + fz_u8(&in) % 2, ny = 1 + fz_u8(&in) % 3, m = nu + fz_u8(&in) % 2;
    const uint32_t enc = fz_u8(&in) & 1, fd = fz_u8(&in) & 1, window = 1 + fz_u8(&in) % 32;
    const uint32_t bounded = fz_u8(&in) & 1, K = 2 + fz_u8(&in) % 6;
    msid_twiddle tw;
    void *tw_mem = fz_twiddle(P, &tw);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = nu; mc.n_outputs = ny; mc.n_experiments = m; mc.n_lines = 3; mc.bins = BINS;
    mc.twiddle = &tw; mc.path = MSID_DFT_STREAM; mc.transient = MSID_TRANSIENT_FLAG; mc.max_periods = 4 * K + 8;
    const size_t nm = msid_meas_mem_size(&mc);
    void *mm = fz_alloc(nm);
    msid_meas ms;
    if (!mm || msid_meas_init(&ms, &mc, mm, nm) != MSID_OK) abort();
    msid_can_decoder_cfg dc = {0x200, nu, ny, enc, fd, 0.001, P, window, 7, &ms, bounded ? (uint64_t)K * P : 0};
    const size_t nd = msid_can_decoder_mem_size(&dc);
    void *md = fz_alloc(nd);
    msid_can_decoder d;
    if (!md || msid_can_decoder_init(&d, &dc, md, nd) != MSID_OK) abort();
    while (in.n >= 6) {
        msid_can_frame f;
        memset(&f, 0, sizeof f);
        f.id = fz_u32(&in);
        /* mostly the device's identifiers, so the fuzzer reaches the decoder's depth */
        if (!(f.id & 0x80000000u) && (f.id & 0x40000000u)) f.id = 0x200u | (f.id & 0x7Fu);
        f.len = (uint8_t)(fz_u8(&in) % 65);
        f.flags = (uint8_t)fz_u8(&in);
        fz_bytes(&in, f.data, f.len);
        f.t_ns = 1000u * (uint64_t)in.n;
        const msid_status st = msid_can_decoder_feed(&d, &f);
        if (st != MSID_OK && st != MSID_E_CAPACITY && st != MSID_E_STATE) abort();
        if (st != MSID_OK) break;
    }
    msid_can_decoder_abort(&d);
    /* the decoder's counts are bounded by what the design allows */
    if (bounded && d.cnt.samples + d.cnt.samples_lost > (uint64_t)K * P * (d.st.cnt.segments + 1)) abort();
    msid_frf_cfg fc = {P, nu, ny, m, 3, 0, NULL};
    const size_t nf = msid_frf_mem_size(&fc);
    void *mf = fz_alloc(nf);
    msid_frf frf;
    const msid_pstats *ps[MSID_MAX_EXPERIMENTS];
    for (uint32_t e = 0; e < m; ++e) ps[e] = msid_meas_stats(&ms, e);
    if (mf && msid_frf_init(&frf, &fc, mf, nf) == MSID_OK) (void)msid_frf_compute(&frf, ps);
    free(mf);
    free(md);
    free(mm);
    free(tw_mem);
    return 0;
}
