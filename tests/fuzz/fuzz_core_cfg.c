/* libFuzzer: the core's configuration validation with any cfg struct from bytes. Every field of the
 * design, measurement (linedft + pstats) and FRF configurations comes from the input; pointers point at
 * buffers the size the fields claim. mem_size must answer 0 or a size init accepts, init must refuse
 * or succeed without touching memory beyond mem_size, and a successful set must run rows through. */
#include "fuzz_util.h"
#include "msid/msid.h"

#define MAXL 64

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fz in = {data, size};
    uint32_t bins[MAXL], det[MAXL];
    double omega[MAXL], amp[MSID_MAX_INPUTS * MAXL], ph[MSID_MAX_INPUTS * MAXL];
    /* ---- design ---- */
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = fz_u32(&in) % (1u << 14);   /* P beyond 2^14 only costs time: validation is the same code */
    dc.n_lines = fz_u8(&in) % (MAXL + 2);   /* may exceed the arrays' MAXL: mem_size must refuse or we cap */
    const uint32_t Lb = dc.n_lines < MAXL ? dc.n_lines : MAXL;
    for (uint32_t l = 0; l < MAXL; ++l) { bins[l] = fz_u16(&in); omega[l] = fz_f64(&in); }
    const int ct = fz_u8(&in) & 1;
    dc.bins = ct ? NULL : bins;
    dc.omega = ct ? omega : NULL;
    dc.sample_time = fz_f64(&in);
    dc.ct_tol = (fz_u8(&in) & 1) ? fz_f64(&in) : 0.0;
    for (uint32_t k = 0; k < MSID_MAX_INPUTS * MAXL; ++k) { amp[k] = 1.0 + (k % 7); ph[k] = 0.1 * (k % 13); }
    if (fz_u8(&in) & 1) { amp[fz_u8(&in) % (MSID_MAX_INPUTS * MAXL)] = fz_f64(&in); }
    dc.amplitudes = (fz_u8(&in) & 1) ? amp : NULL;
    dc.amp_per_input = (int)(fz_u8(&in) & 1);
    dc.phase_mode = (msid_phase_mode)(fz_u8(&in) % 4);
    dc.phases = (fz_u8(&in) & 1) ? ph : NULL;
    dc.seed = fz_u32(&in);
    dc.n_inputs = fz_u8(&in) % (MSID_MAX_INPUTS + 2);
    dc.n_experiments = fz_u8(&in) % (MSID_MAX_EXPERIMENTS + 2);
    dc.pattern = (msid_pattern)(fz_u8(&in) % 3);
    dc.crest = (msid_crest_mode)(fz_u8(&in) % 4);
    if (dc.crest == MSID_CREST_FFT) dc.crest = MSID_CREST_NONE;   /* no FFT backend in the core */
    if (dc.n_lines > MAXL || dc.n_inputs * dc.n_lines > MSID_MAX_INPUTS * MAXL) dc.n_lines = Lb;
    if ((uint64_t)dc.period * dc.n_lines * dc.n_inputs * dc.n_experiments > (1u << 16)) dc.crest = MSID_CREST_NONE;
    msid_twiddle tw;
    void *mt = NULL;
    if (dc.period >= MSID_MIN_PERIOD) {
        const size_t nt = msid_twiddle_mem_size(dc.period);
        mt = fz_alloc(nt);
        if (!mt || msid_twiddle_init(&tw, dc.period, mt, nt) != MSID_OK) abort();
        dc.twiddle = &tw;
    }
    const size_t nd = msid_design_mem_size(&dc);
    msid_design d;
    void *md = nd ? fz_alloc(nd) : NULL;
    if (md) (void)msid_design_init(&d, &dc, md, nd);
    free(md);
    /* ---- measurement and FRF ---- */
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = fz_u16(&in) % 8192u;   /* larger P: the same checks, only slower */
    mc.n_inputs = fz_u8(&in) % (MSID_MAX_INPUTS + 2);
    mc.n_outputs = fz_u8(&in) % (MSID_MAX_OUTPUTS + 2);
    mc.n_experiments = fz_u8(&in) % (MSID_MAX_EXPERIMENTS + 2);
    mc.n_lines = fz_u8(&in) % (MAXL + 1);
    mc.n_detect = fz_u8(&in) % 4;
    for (uint32_t l = 0; l < MAXL; ++l) { bins[l] = fz_u16(&in); det[l] = fz_u16(&in); }
    mc.bins = bins;
    mc.detect_bins = det;
    mc.path = (msid_dft_path)(fz_u8(&in) % 2 ? MSID_DFT_STREAM : fz_u8(&in) % 4);
    if (mc.path == MSID_DFT_FFT) mc.path = MSID_DFT_STREAM;   /* no FFT backend in the core */
    mc.skip_periods = fz_u32(&in);
    mc.max_periods = fz_u8(&in) % 40;
    mc.transient = (msid_transient_mode)(fz_u8(&in) % 4);
    mc.alpha = fz_f64(&in);
    msid_twiddle tw2;
    void *mt2 = NULL;
    if (mc.period >= MSID_MIN_PERIOD && mc.period <= MSID_MAX_PERIOD) {
        const size_t nt = msid_twiddle_mem_size(mc.period);
        mt2 = fz_alloc(nt);
        if (!mt2 || msid_twiddle_init(&tw2, mc.period, mt2, nt) != MSID_OK) abort();
        mc.twiddle = &tw2;
    }
    const size_t nm = msid_meas_mem_size(&mc);
    void *mm = nm && nm <= ((size_t)8 << 20) ? fz_alloc(nm) : NULL;   /* bigger sizes: validated above */
    msid_meas ms;
    if (mm && mc.twiddle && msid_meas_init(&ms, &mc, mm, nm) == MSID_OK) {
        const uint32_t C = mc.n_inputs + mc.n_outputs;
        double row[MSID_MAX_CHANNELS];
        for (uint32_t e = 0; e < mc.n_experiments && e < 4; ++e) {
            if (msid_meas_begin(&ms, e) != MSID_OK) abort();
            const uint64_t n = (uint64_t)mc.period * (2 + fz_u8(&in) % 3);
            for (uint64_t s = 0; s < n && s < 512; ++s) {
                for (uint32_t c = 0; c < C; ++c) row[c] = (double)(int8_t)fz_u8(&in);
                if (msid_meas_push(&ms, row, 1) != MSID_OK) break;
            }
            if (fz_u8(&in) & 1) (void)msid_meas_push_gap(&ms, fz_u32(&in));
            (void)msid_meas_end(&ms, NULL);
        }
        msid_frf_cfg fc = {mc.period, mc.n_inputs, mc.n_outputs, mc.n_experiments, mc.n_lines, mc.n_detect, NULL};
        const size_t nf = msid_frf_mem_size(&fc);
        void *mf = nf ? fz_alloc(nf) : NULL;
        msid_frf f;
        const msid_pstats *ps[MSID_MAX_EXPERIMENTS];
        for (uint32_t e = 0; e < mc.n_experiments; ++e) ps[e] = msid_meas_stats(&ms, e);
        if (mf && msid_frf_init(&f, &fc, mf, nf) == MSID_OK && msid_frf_compute(&f, ps) == MSID_OK)
            for (uint32_t l = 0; l < mc.n_lines; ++l)
                if (!(msid_frf_dof(&f, l) >= 1.0)) abort();   /* a solved line has a finite dof >= 1 */
        free(mf);
    }
    free(mm);
    free(mt2);
    free(mt);
    return 0;
}
