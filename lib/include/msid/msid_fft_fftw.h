/**
 * @file msid_fft_fftw.h
 * @brief FFTW3 backend for the dense-line path (host only, in libmsid_fftw).
 *
 * FFTW allocates inside its planner, so this backend lives outside the
 * heap-free core archive. Create it once per period, pass `&f.be` as
 * ::msid_linedft_cfg::fft, destroy it after the line DFT is done.
 */
#ifndef MSID_FFT_FFTW_H
#define MSID_FFT_FFTW_H

#include "msid_fft.h"

#ifdef __cplusplus
extern "C" {
#endif

/** FFTW planning effort. */
typedef enum msid_fftw_effort {
    MSID_FFTW_ESTIMATE = 0, /**< FFTW_ESTIMATE: instant planning */
    MSID_FFTW_MEASURE = 1   /**< FFTW_MEASURE: slower planning, faster transforms */
} msid_fftw_effort;

/** Backend instance. */
typedef struct msid_fft_fftw {
    msid_fft_backend be;   /**< the table to hand to msid_linedft */
    void *plan;            /**< fftw_plan */
    double *in;            /**< planning/fallback input buffer (P doubles) */
    void *out;             /**< planning/fallback output buffer (P/2+1 complex) */
} msid_fft_fftw;

/**
 * @brief Plan a real-to-complex transform of length `period`.
 * @return MSID_OK, MSID_E_NULL, MSID_E_PERIOD or MSID_E_BACKEND (planning failed).
 */
msid_status msid_fft_fftw_create(msid_fft_fftw *f, uint32_t period, msid_fftw_effort effort);

/** @brief Release the plan and buffers (safe on a zeroed or destroyed instance). */
void msid_fft_fftw_destroy(msid_fft_fftw *f);

#ifdef __cplusplus
}
#endif
#endif
