/* Twiddle table from the deterministic whole-turn sin/cos. */
#include "msid/msid_twiddle.h"
#include "msid/msid_dmath.h"
#include "msid_internal.h"

/* The one memory layout (see msid__layout): the table. */
static size_t layout(msid_cplx **w, uint32_t period, void *mem)
{
    msid__layout y = msid__layout_begin(mem);
    *w = (msid_cplx *)msid__lay(&y, period, sizeof(msid_cplx));
    return y.size;
}

size_t msid_twiddle_mem_size(uint32_t period)
{
    if (period < MSID_MIN_PERIOD || period > MSID_MAX_PERIOD) return 0;
    msid_cplx *w;
    return layout(&w, period, 0);
}

msid_status msid_twiddle_init(msid_twiddle *tw, uint32_t period, void *mem, size_t len)
{
    if (!tw) return MSID_E_NULL;
    const size_t need = msid_twiddle_mem_size(period);
    if (need == 0) return MSID_E_PERIOD;
    const msid_status st = msid__mem_check(mem, len, need);
    if (st != MSID_OK) return st;
    msid_cplx *w;
    (void)layout(&w, period, mem);
    for (uint32_t n = 0; 2u * (uint64_t)n <= period; ++n) {
        double c, s;
        /* n/P rounded once (IEEE division); n/P = k/8 is exact, so the
         * symmetric points get exact 0, +-1, +-sqrt(1/2) values. Only
         * n <= P/2 is computed (the rounding error of n/P is half as large
         * there); the rest is w[P-n] = conj(w[n]), exactly. */
        msid_cis_turns((double)n / (double)period, &c, &s);
        w[n].re = c;
        w[n].im = -s;
        if (n != 0u && 2u * (uint64_t)n != period) {
            w[period - n].re = c;
            w[period - n].im = s;
        }
    }
    tw->period = period;
    tw->w = w;
    return MSID_OK;
}
