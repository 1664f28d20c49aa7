/* FFTW3 real-to-complex backend. Host only: FFTW allocates in its planner. */
#include "msid/msid_fft_fftw.h"
#include <fftw3.h>
#include <string.h>

static msid_status r2c(void *ctx, const double *in, msid_cplx *out)
{
    msid_fft_fftw *f = (msid_fft_fftw *)ctx;
    const uint32_t P = f->be.period;
    fftw_plan plan = (fftw_plan)f->plan;
    /* New-array execute needs the alignment the plan was made with. */
    const int same_in = fftw_alignment_of((double *)in) == fftw_alignment_of(f->in);
    const int same_out = fftw_alignment_of((double *)out) == fftw_alignment_of((double *)f->out);
    if (same_in && same_out) {
        fftw_execute_dft_r2c(plan, (double *)in, (fftw_complex *)out);
    } else {
        memcpy(f->in, in, (size_t)P * sizeof(double));
        fftw_execute_dft_r2c(plan, f->in, (fftw_complex *)f->out);
        memcpy(out, f->out, ((size_t)P / 2u + 1u) * sizeof(msid_cplx));
    }
    return MSID_OK;
}

msid_status msid_fft_fftw_create(msid_fft_fftw *f, uint32_t period, msid_fftw_effort effort)
{
    if (!f) return MSID_E_NULL;
    memset(f, 0, sizeof(*f));
    if (period < MSID_MIN_PERIOD || period > MSID_MAX_PERIOD) return MSID_E_PERIOD;
    f->in = fftw_alloc_real(period);
    f->out = fftw_alloc_complex(period / 2u + 1u);
    if (!f->in || !f->out) { msid_fft_fftw_destroy(f); return MSID_E_BACKEND; }
    const unsigned flags = (effort == MSID_FFTW_MEASURE ? FFTW_MEASURE : FFTW_ESTIMATE);
    f->plan = fftw_plan_dft_r2c_1d((int)period, f->in, (fftw_complex *)f->out, flags);
    if (!f->plan) { msid_fft_fftw_destroy(f); return MSID_E_BACKEND; }
    f->be.name = "fftw3";
    f->be.period = period;
    f->be.ctx = f;
    f->be.r2c = r2c;
    return MSID_OK;
}

void msid_fft_fftw_destroy(msid_fft_fftw *f)
{
    if (!f) return;
    if (f->plan) fftw_destroy_plan((fftw_plan)f->plan);
    if (f->in) fftw_free(f->in);
    if (f->out) fftw_free(f->out);
    memset(f, 0, sizeof(*f));
}
