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
    MSID_FFTW_MEASURE = 1,  /**< FFTW_MEASURE: slower planning, faster transforms */
    /**
     * For msid_linedft's lines (msid frf): with P even, one complex DFT of P/2
     * points of the samples taken as (x[2n], x[2n+1]) pairs, split into the
     * real DFT at the wanted bins only (be.r2c_bins; twiddles from
     * ::msid_cis_turns). Planning it is a small fraction of planning FFTW's
     * real transform of the same P, and a transform costs about the same. be.r2c
     * (the whole spectrum) then splits every bin: slower than ESTIMATE's plan,
     * so take ESTIMATE for whole spectra. Odd P: ESTIMATE's real plan.
     */
    MSID_FFTW_LINES = 2
} msid_fftw_effort;

/** Backend instance. */
typedef struct msid_fft_fftw {
    msid_fft_backend be;   /**< the table to hand to msid_linedft */
    void *plan;            /**< fftw_plan: real DFT of P, or (half) complex DFT of P/2 */
    double *in;            /**< planning/fallback input buffer (P doubles) */
    void *out;             /**< planning/fallback output buffer (P/2+1 complex) */
    int half;              /**< MSID_FFTW_LINES with P even: `plan` is the complex DFT of P/2 */
    /** Twiddles exp(-j 2 pi k / P) of the last bins asked for: [0] by r2c_bins, [1] by r2c (all) */
    struct {
        uint32_t n;        /**< bins cached */
        uint32_t *bins;    /**< their bins (n) */
        msid_cplx *w;      /**< their twiddles (n) */
    } tw[2];
} msid_fft_fftw;

/**
 * @brief Plan a real-to-complex transform of length `period` (MSID_FFTW_LINES: the complex DFT
 *        of period/2 points and the split at the lines, be.r2c_bins; see ::msid_fftw_effort).
 * @return MSID_OK, MSID_E_NULL, MSID_E_PERIOD, MSID_E_ARG (unknown effort) or MSID_E_BACKEND
 *         (planning failed).
 */
msid_status msid_fft_fftw_create(msid_fft_fftw *f, uint32_t period, msid_fftw_effort effort);

/** @brief Release the plan and buffers (safe on a zeroed or destroyed instance). */
void msid_fft_fftw_destroy(msid_fft_fftw *f);

#ifdef __cplusplus
}
#endif
#endif
