/**
 * @file msid_linedft.h
 * @brief Streaming DFT at selected lines, period by period.
 *
 * Push samples of C channels (interleaved rows: x[n*C + c]) one at a time or
 * in blocks. For every completed period of P samples the object exposes
 * X_c[b] = sum_{n<P} x_c(n) exp(-j 2 pi b n / P) at each configured bin b.
 *
 * Two paths give the same numbers (within 1e-12 relative):
 *  - streaming: O(L*C) per sample, twiddle index (b*n) mod P kept in integers
 *    (no phase drift however long the run), nothing buffered;
 *  - FFT: buffers one period per channel and runs one real FFT per channel
 *    through a ::msid_fft_backend; cheaper when many lines are wanted.
 * ::MSID_DFT_AUTO picks the cheaper one from (P, L, C) only, so the choice is
 * deterministic. Results are bit-identical whatever block sizes are pushed,
 * and with the period end spread over the next period or not (cfg.spread).
 */
#ifndef MSID_LINEDFT_H
#define MSID_LINEDFT_H

#include "msid_types.h"
#include "msid_status.h"
#include "msid_twiddle.h"
#include "msid_fft.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Path selection. */
typedef enum msid_dft_path {
    MSID_DFT_AUTO = 0,   /**< FFT path if a backend is given and it is cheaper */
    MSID_DFT_STREAM = 1, /**< per-sample accumulation at the lines */
    MSID_DFT_FFT = 2,    /**< one real FFT per channel per period (needs a backend) */
    MSID_DFT_STREAM_F32 = 3 /**< streaming in single precision (FPUs without double, e.g. Cortex-M4F):
                                 samples rounded to float, float twiddles and accumulators per period,
                                 spectra handed on as double. Error per period and line at most
                                 (P + 3) * 2^-24 * sum_n |x_c(n)| (docs/target.md); never chosen by AUTO */
} msid_dft_path;

/** Period flags (bit set). */
#define MSID_PERIOD_GAP 1u        /**< the caller marked missing samples in this period */
#define MSID_PERIOD_NONFINITE 2u  /**< a NaN or infinity reached the spectra */

/** Line DFT configuration. */
typedef struct msid_linedft_cfg {
    uint32_t period;              /**< P in [MSID_MIN_PERIOD, MSID_MAX_PERIOD] */
    uint32_t n_channels;          /**< C in [1, MSID_MAX_CHANNELS] */
    uint32_t n_lines;             /**< L >= 1 */
    const uint32_t *bins;         /**< [L] bins in [0, P/2] (copied at init) */
    const msid_twiddle *twiddle;  /**< table of period P (must outlive the object) */
    msid_dft_path path;           /**< path request */
    const msid_fft_backend *fft;  /**< backend for the FFT path, or NULL */
    int spread;                   /**< 1: spread period end (streaming paths only, see ::msid_linedft_settle);
                                       costs a second set of accumulators (L*C complex, or 2*L*C floats) */
} msid_linedft_cfg;

/** Line DFT instance (caller-owned). */
typedef struct msid_linedft {
    uint32_t period, n_channels, n_lines;
    msid_dft_path path;           /**< the path in use (STREAM or FFT) */
    const msid_twiddle *twiddle;
    const msid_fft_backend *fft;
    uint32_t *bins;               /**< [L] */
    uint32_t *idx;                /**< [L] twiddle index of the next sample (stream) */
    msid_cplx *acc;               /**< [L*C] running sums (stream) */
    double *buf;                  /**< [C*P] period buffer (FFT) */
    msid_cplx *fout;              /**< [P/2+1] FFT output (FFT) */
    msid_cplx *out;               /**< [L*C] spectra of the last completed period */
    uint32_t pos;                 /**< samples of the current period pushed so far */
    uint32_t flags;               /**< flags of the current period */
    uint32_t out_flags;           /**< flags of the completed period in `out` */
    int ready;                    /**< 1 when `out` holds a completed, unreleased period */
    uint64_t periods;             /**< completed periods since init/reset */
    msid_status err;              /**< sticky backend error */
    float *accf;                  /**< [2*L*C] running sums re, im (STREAM_F32) */
    float *twf;                   /**< [2*P] twiddles re, im in single precision (STREAM_F32) */
    int spread;                   /**< 1: period end deferred to ::msid_linedft_settle */
    int pending;                  /**< spread: a completed period waits in acc2/accf2 to be settled */
    uint32_t pend_line;           /**< spread: lines of the pending period settled into `out` so far */
    uint32_t pend_flags;          /**< spread: flags of the pending period */
    msid_cplx *acc2;              /**< [L*C] spread (STREAM): sums of the pending period, zero when free */
    float *accf2;                 /**< [2*L*C] spread (STREAM_F32): sums of the pending period, zero when free */
} msid_linedft;

/** @brief Path AUTO would choose for these dimensions (STREAM without a backend). */
msid_dft_path msid_linedft_choose(uint32_t period, uint32_t n_lines, uint32_t n_channels, int have_fft);

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_linedft_mem_size(const msid_linedft_cfg *cfg);

/**
 * @brief Initialise at the start of a period.
 * @return MSID_OK, MSID_E_NULL, MSID_E_PERIOD, MSID_E_DIMS, MSID_E_NO_LINES, MSID_E_ARG (spread with the FFT path),
 *         MSID_E_LINE_RANGE, MSID_E_BACKEND (FFT requested without a matching backend),
 *         MSID_E_MEM_ALIGN or MSID_E_MEM_SIZE.
 */
msid_status msid_linedft_init(msid_linedft *d, const msid_linedft_cfg *cfg, void *mem, size_t len);

/**
 * @brief Push up to n samples (rows of C doubles); stops at the end of the current period.
 * @param x rows x[k*C + c], k < n
 * @return samples consumed (0 if a completed period is waiting for ::msid_linedft_release).
 */
size_t msid_linedft_push(msid_linedft *d, const double *x, size_t n);

/**
 * @brief Push up to n samples given as float (rows of C floats), for firmware
 *        whose ADC data are float or integer: with ::MSID_DFT_STREAM_F32 no
 *        conversion happens per sample (on a Cortex-M4F the double-to-float
 *        conversion is a library call). The result is the same bits as
 *        ::msid_linedft_push of the same values as double, on every path
 *        (float to double is exact, and the float path rounds each double
 *        sample to float, which gives the float back).
 * @return samples consumed, as ::msid_linedft_push.
 */
size_t msid_linedft_push_f32(msid_linedft *d, const float *x, size_t n);

/**
 * @brief Advance over n missing samples (data lost upstream); every period they
 *        touch is flagged ::MSID_PERIOD_GAP. Stops at the end of the current period.
 * @return samples skipped (0 if a completed period is waiting).
 */
size_t msid_linedft_push_gap(msid_linedft *d, size_t n);

/** @brief Flag the current (incomplete) period ::MSID_PERIOD_GAP. */
void msid_linedft_mark_gap(msid_linedft *d);

/** @brief 1 if a completed period is available. */
int msid_linedft_ready(const msid_linedft *d);

/** @brief Spectra of the completed period, [L*C] indexed l*C + c; NULL if none is ready. */
const msid_cplx *msid_linedft_spectra(const msid_linedft *d);

/** @brief Flags of the completed period (::MSID_PERIOD_GAP, ::MSID_PERIOD_NONFINITE). */
uint32_t msid_linedft_flags(const msid_linedft *d);

/** @brief Release the completed period so pushing can continue. */
void msid_linedft_release(msid_linedft *d);

/** @brief Drop any partial period and restart at sample 0 of a period. */
void msid_linedft_reset(msid_linedft *d);

/**
 * @brief Spread period end (cfg.spread = 1): settle up to n_lines lines of the pending period.
 *
 * Without spreading, the sample that completes a period also copies the
 * spectra of all L lines and checks them, O(L*C) at once. With spreading, that
 * sample only swaps two sets of accumulators, O(1); the completed period is
 * *pending* and each call here converts, checks and clears n_lines of its
 * lines into `out`; after the last line the period is ready
 * (::msid_linedft_ready) exactly as without spreading, bit for bit. A firmware
 * with a per-sample budget calls it with 1 line per sample during the next
 * period (::msid_meas does this itself with msid_meas_cfg.spread). The next
 * period cannot complete while one is pending or ready: ::msid_linedft_push
 * then settles the pending lines itself if `out` is free, else it stops one
 * sample short of the period end.
 * @return lines settled by this call (0 if none is pending).
 */
size_t msid_linedft_settle(msid_linedft *d, size_t n_lines);

/** @brief 1 while a completed period waits to be settled (spread mode). */
int msid_linedft_pending(const msid_linedft *d);

/** @brief Sticky error from the FFT backend (MSID_OK if none). */
msid_status msid_linedft_error(const msid_linedft *d);

#ifdef __cplusplus
}
#endif
#endif
