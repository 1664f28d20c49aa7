/**
 * @file msid_cissim.h
 * @brief Online invariant-subspace regression of discrete-cISSIM (You, Huang,
 * Zhang 2023, Algorithm 2): a fixed-allocation, per-period recursive update of
 * the ISP coefficient matrix R^i of eq. (25), so firmware can refine its
 * estimate every period and hand it to the host (tools/fit/cissim, Alg. 4-5).
 *
 * Regressor per sample k (k = 0 at the first pushed sample), one row per
 * column of v_k: a DC line (bin 0) gives the row 1/sqrt(2) (eq. 7), any other
 * line b gives the rows sin(2 pi b k / T) and cos(2 pi b k / T). After t whole
 * periods the estimate is
 *   R_t = (t-1)/t R_{t-1} + (1/t) (2/T) sum_{k in period t} w_k z_k^T,
 * equal to the offline Alg. 1 estimate (2/(t T)) F^T Z on the same t periods
 * up to rounding (tests/fit/test_cissim.cpp: relative 1e-12).
 * Row-major s x C, C = channels in the order pushed (msid records: u.., y..).
 */
#ifndef MSID_CISSIM_H
#define MSID_CISSIM_H

#include "msid_types.h"
#include "msid_status.h"
#include "msid_twiddle.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Configuration. */
typedef struct msid_cissim_cfg {
    uint32_t period;              /**< T in [MSID_MIN_PERIOD, MSID_MAX_PERIOD], samples per period */
    uint32_t n_lines;             /**< q >= 1 lines of the interested set F^i */
    const uint32_t *bins;         /**< [q] bins in [0, T/2), no duplicates (copied at init) */
    uint32_t n_channels;          /**< C = nu + ny in [2, MSID_MAX_CHANNELS] */
    const msid_twiddle *twiddle;  /**< table of period T (shared, read-only, must outlive the object) */
} msid_cissim_cfg;

/** Instance (caller-owned). Read it through the accessor functions. */
typedef struct msid_cissim {
    uint32_t period, n_lines, n_channels, n_rows;
    const msid_twiddle *tw;
    uint32_t *bins;     /**< [q] */
    uint32_t *phase;    /**< [q] (k * bin) mod T of the next sample */
    double *acc;        /**< [s * C] sum over the current period of w_k z_k^T */
    double *est;        /**< [s * C] R_t */
    uint32_t in_period; /**< samples of the current period pushed */
    uint64_t periods;   /**< t, whole periods folded into est */
} msid_cissim;

/**
 * @brief Bytes of working memory.
 * @return a multiple of MSID_MEM_ALIGN, or 0 when the configuration is invalid
 *         (see ::msid_cissim_init for the checks).
 */
size_t msid_cissim_mem_size(const msid_cissim_cfg *cfg);

/**
 * @brief Initialise (t = 0, estimate zero).
 * @return MSID_OK, MSID_E_NULL, MSID_E_PERIOD, MSID_E_NO_LINES, MSID_E_LINE_RANGE,
 *         MSID_E_LINE_DUP, MSID_E_DIMS, MSID_E_BACKEND (twiddle of another period),
 *         MSID_E_MEM_ALIGN or MSID_E_MEM_SIZE.
 */
msid_status msid_cissim_init(msid_cissim *cs, const msid_cissim_cfg *cfg, void *mem, size_t len);

/**
 * @brief Push n samples (rows of C values, row-major). Every completed period
 * updates the estimate (Alg. 2 steps 6-10). O(q C) per sample, no allocation.
 * @return MSID_OK, MSID_E_NULL or MSID_E_NOT_FINITE (nothing of that call is used then).
 */
msid_status msid_cissim_push(msid_cissim *cs, const double *rows, size_t n);

/** Rows s of the estimate: 1 per DC line, 2 per other line. */
uint32_t msid_cissim_rows(const msid_cissim *cs);
/** Whole periods t folded into the estimate. */
uint64_t msid_cissim_periods(const msid_cissim *cs);
/** The estimate R_t, s x C row-major (all zero before the first whole period). */
const double *msid_cissim_estimate(const msid_cissim *cs);

#ifdef __cplusplus
}
#endif
#endif
