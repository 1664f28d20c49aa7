/**
 * @file msid_meas.h
 * @brief Measurement pipeline: sample rows -> ::msid_linedft -> per-experiment ::msid_pstats.
 *
 * One object per multi-experiment measurement. Rows are
 * [u_1..u_nu, y_1..y_ny] (nu + ny doubles), one per sample, periods back to
 * back from the start of each experiment. Acquisition adapters feed it; the
 * FRF is then solved with ::msid_frf_compute on ::msid_meas_stats.
 * Missing samples are declared with ::msid_meas_push_gap (keeps alignment)
 * or ::msid_meas_mark_gap; every period they touch is discarded and counted.
 *
 * Per-sample time. Without spreading, the sample that completes a period also
 * copies its spectra and updates the period statistics, O(L*C + L*C^2), many
 * times the cost of an ordinary sample. With cfg.spread = 1 that sample only
 * swaps two sets of accumulators, and the 2 (L + D) units of deferred work
 * (settle one line of the spectra, update one line's statistics) are done by
 * the samples of the next period, ceil(2 (L + D) / P) units per sample pushed
 * (1 whenever L + D <= P/2), so the per-sample maximum is an ordinary sample
 * plus one line.
 * The statistics are the same bits whatever the block sizes; they are
 * complete after ::msid_meas_end (or ::msid_meas_flush), not in between.
 */
#ifndef MSID_MEAS_H
#define MSID_MEAS_H

#include "msid_linedft.h"
#include "msid_pstats.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Configuration. Arrays are copied at init. */
typedef struct msid_meas_cfg {
    uint32_t period;               /**< P */
    uint32_t n_inputs;             /**< nu in [1, MSID_MAX_INPUTS] */
    uint32_t n_outputs;            /**< ny in [1, MSID_MAX_OUTPUTS] */
    uint32_t n_experiments;        /**< m in [nu, MSID_MAX_EXPERIMENTS] */
    uint32_t n_lines;              /**< excited lines L >= 1 */
    const uint32_t *bins;          /**< [L] excited bins in [0, P/2) */
    uint32_t n_detect;             /**< extra non-excited lines for noise/distortion (may be 0) */
    const uint32_t *detect_bins;   /**< [n_detect] bins in [1, P/2), not excited */
    const msid_twiddle *twiddle;   /**< table of period P (stream path) */
    msid_dft_path path;            /**< DFT path request */
    const msid_fft_backend *fft;   /**< FFT backend or NULL */
    uint32_t skip_periods;         /**< leading periods of each experiment (segment) to ignore */
    uint32_t max_periods;          /**< per-experiment history for the transient test (0: none) */
    uint32_t beyond_history;       /**< ::msid_pstats_cfg beyond_history: periods after a full history
                                        are used untested instead of refused */
    msid_transient_mode transient; /**< transient test mode */
    double alpha;                  /**< transient test level per experiment (0: 0.01) */
    int spread;                    /**< 1: bounded per-sample time. The period-end work (spectra
                                        copy, O(L*C), and period statistics, O(L*C^2)) is spread
                                        over the first samples of the next period, one line per
                                        sample; results are bit-identical. Streaming paths only
                                        (not FFT); memory: one more set of accumulators */
} msid_meas_cfg;

/** Instance (caller-owned). */
typedef struct msid_meas {
    uint32_t period, n_inputs, n_outputs, n_experiments, n_lines, n_detect;
    int current;                   /**< experiment being measured, or -1 */
    msid_linedft dft;
    msid_pstats *ps;               /**< [m] */
    uint64_t *leftover;            /**< [m] samples of incomplete periods discarded at end */
    uint64_t *samples;             /**< [m] samples pushed (including gaps) */
    msid_status err;               /**< first error (sticky) */
    int spread;                    /**< cfg.spread */
    uint32_t spread_rate;          /**< spread: units of deferred work per sample, ceil(2 (L + D) / P) */
    int pend;                      /**< spread: a completed period is being processed */
    uint32_t pend_unit;            /**< spread: units done; unit u < L+D settles line u of the spectra,
                                        unit L+D+l updates the statistics of line l */
    int pend_use;                  /**< spread: the statistics use the pending period */
} msid_meas;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_meas_mem_size(const msid_meas_cfg *cfg);

/**
 * @brief Initialise. @return MSID_OK or an error of the sub-objects (MSID_E_ARG: spread with the FFT path), MSID_E_EXPERIMENTS,
 *        MSID_E_LINE_RANGE (excited bin >= P/2), MSID_E_LINE_DUP (a bin excited twice or also a detection bin).
 */
msid_status msid_meas_init(msid_meas *ms, const msid_meas_cfg *cfg, void *mem, size_t len);

/**
 * @brief Start (or continue, as a new segment) experiment e at sample 0 of a period.
 * @return MSID_OK, MSID_E_ARG (e >= m) or MSID_E_STATE (another experiment is open).
 */
msid_status msid_meas_begin(msid_meas *ms, uint32_t e);

/**
 * @brief Push n sample rows of nu+ny doubles.
 * @return MSID_OK, MSID_E_STATE (no experiment open), MSID_E_CAPACITY (history full) or MSID_E_BACKEND.
 */
msid_status msid_meas_push(msid_meas *ms, const double *rows, size_t n);

/**
 * @brief Push n sample rows of nu+ny floats (see ::msid_linedft_push_f32): with
 *        path ::MSID_DFT_STREAM_F32 no per-sample conversion; the same bits as
 *        ::msid_meas_push of the same values as double.
 * @return as ::msid_meas_push.
 */
msid_status msid_meas_push_f32(msid_meas *ms, const float *rows, size_t n);

/** @brief Declare n missing samples: alignment is kept and the periods they touch are discarded. */
msid_status msid_meas_push_gap(msid_meas *ms, size_t n);

/**
 * @brief Spread mode: finish the deferred work of the last completed period now
 *        (no-op otherwise); ::msid_meas_end does it itself.
 * @return MSID_OK or the error the statistics gave (MSID_E_CAPACITY, MSID_E_BACKEND).
 */
msid_status msid_meas_flush(msid_meas *ms);

/** @brief Discard the current period (for example after a bus error). */
msid_status msid_meas_mark_gap(msid_meas *ms);

/**
 * @brief Close the open experiment: samples of an incomplete last period are
 *        discarded and counted; the transient test runs.
 * @param leftover samples discarded now (may be NULL)
 */
msid_status msid_meas_end(msid_meas *ms, uint64_t *leftover);

/** @brief Statistics of experiment e (NULL if e is out of range). */
const msid_pstats *msid_meas_stats(const msid_meas *ms, uint32_t e);

/** @brief Samples of incomplete periods discarded in experiment e. */
uint64_t msid_meas_leftover(const msid_meas *ms, uint32_t e);

#ifdef __cplusplus
}
#endif
#endif
