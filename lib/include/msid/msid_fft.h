/**
 * @file msid_fft.h
 * @brief Backend table for the dense-line path of ::msid_linedft.
 *
 * The core never plans or allocates an FFT. A host supplies a backend (for
 * example ::msid_fft_fftw in libmsid_fftw, which wraps FFTW3) as a table of
 * function pointers, the way libmodbus plugs transports in.
 */
#ifndef MSID_FFT_H
#define MSID_FFT_H

#include "msid_types.h"
#include "msid_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** A real-to-complex DFT of one fixed length. */
typedef struct msid_fft_backend {
    const char *name;   /**< e.g. "fftw3" */
    uint32_t period;    /**< P: the only length `r2c` accepts */
    void *ctx;          /**< backend state, passed back to r2c */
    /**
     * Forward DFT out[k] = sum_{n<P} in[n] exp(-j 2 pi k n / P), k = 0..P/2.
     * `in` holds P doubles, `out` P/2+1 values; both MSID_MEM_ALIGN-aligned.
     * Must not modify `in`. Returns MSID_OK or MSID_E_BACKEND.
     */
    msid_status (*r2c)(void *ctx, const double *in, msid_cplx *out);
    /**
     * Optional (NULL: the core calls `r2c` and picks the bins). The same DFT at
     * `n` bins only: out[i * stride] = X[bins[i]], i < n, bins[i] in [0, P/2]
     * (a backend may compute them more cheaply than the whole spectrum).
     * `in` as for r2c (P doubles, aligned, not modified); `stride` >= 1.
     * Returns MSID_OK or MSID_E_BACKEND.
     */
    msid_status (*r2c_bins)(void *ctx, const double *in, const uint32_t *bins, uint32_t n, msid_cplx *out,
                            uint32_t stride);
} msid_fft_backend;

#ifdef __cplusplus
}
#endif
#endif
