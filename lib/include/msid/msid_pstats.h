/**
 * @file msid_pstats.h
 * @brief Period statistics of one experiment: per line, the running mean and
 *        sample covariance (complex Hermitian, Welford) of the stacked
 *        spectrum vector z = [U_1..U_nu, Y_1..Y_ny] across periods.
 *
 * Periods are offered with their flags from ::msid_linedft. The first
 * `skip_periods` are ignored (plant transient); gap or non-finite periods are
 * discarded and counted, never used. With a period history, a leave-one-out
 * test flags periods whose spectra depart from the others by more than the
 * sample variance explains (see ::msid_pstats_detect), and can drop them.
 *
 * Mean and covariance follow Pintelon 2002 eq. (25) and (32), vector form:
 *   zbar = (1/K) sum_p z_p,   C_Z = 1/(K-1) sum_p (z_p - zbar)(z_p - zbar)^H.
 */
#ifndef MSID_PSTATS_H
#define MSID_PSTATS_H

#include "msid_types.h"
#include "msid_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Transient-period handling. */
typedef enum msid_transient_mode {
    MSID_TRANSIENT_OFF = 0,  /**< no test */
    MSID_TRANSIENT_FLAG = 1, /**< test and report; keep the periods */
    MSID_TRANSIENT_DROP = 2  /**< test, drop flagged periods, recompute */
} msid_transient_mode;

/** Configuration. */
typedef struct msid_pstats_cfg {
    uint32_t n_lines;       /**< L >= 1 */
    uint32_t n_channels;    /**< q in [1, MSID_MAX_CHANNELS] */
    uint32_t skip_periods;  /**< leading valid periods ignored */
    uint32_t max_periods;   /**< history capacity in periods (>= 3 when transient != OFF); 0 = none */
    msid_transient_mode transient; /**< transient test mode */
    double alpha;           /**< family-wise false-alarm probability of the test per experiment, (0,1); 0 selects 0.01 */
    uint32_t beyond_history; /**< 1: with the history full, later periods are used without an entry
                                  (counted in `untested`; the transient and drift tests cover the first
                                  max_periods periods); 0: they are refused (MSID_E_CAPACITY) */
} msid_pstats_cfg;

/** Period counters of one experiment. */
typedef struct msid_pstats_counts {
    uint32_t offered;        /**< completed periods offered */
    uint32_t skipped;        /**< leading periods ignored (skip_periods) */
    uint32_t gap;            /**< discarded: caller marked missing samples */
    uint32_t nonfinite;      /**< discarded: NaN/Inf in the spectra */
    uint32_t transient_flagged; /**< flagged by the transient test */
    uint32_t transient_dropped; /**< of those, dropped (DROP mode) */
    uint32_t used;           /**< periods in the statistics (K) */
    int tested;              /**< 1 if the transient test ran (needs >= 3 periods) */
    int drift_tested;        /**< 1 if the drift test ran (needs >= 6 stored periods) */
    int drift;               /**< 1 if the drift test fired (then nothing is dropped) */
    uint32_t untested;       /**< used beyond a full history (beyond_history): in the statistics, not tested */
} msid_pstats_counts;

/** Instance (caller-owned). */
typedef struct msid_pstats {
    uint32_t n_lines, n_channels, skip_periods, max_periods;
    msid_transient_mode transient;
    double alpha;
    uint32_t K;             /**< periods in mean/m2 */
    msid_cplx *mean;        /**< [L*q] */
    msid_cplx *m2;          /**< [L*q*q] scatter sum_p (z-mean)(z-mean)^H, row-major per line */
    msid_cplx *hist;        /**< [max_periods*L*q] accepted periods, in order */
    uint8_t *hflag;         /**< [max_periods] 1 = flagged by the test */
    uint8_t *hdrop;         /**< [max_periods] 1 = dropped */
    double *hpval;          /**< [max_periods] test p-value per accepted period (NaN if untested) */
    uint32_t *hidx;         /**< [max_periods] 0-based number of each accepted period among all offered */
    double *scr;            /**< [5*L*q] scratch of msid_pstats_detect (with a history only) */
    msid_cplx *tmean;       /**< [L*q] mean of the periods beyond the history (beyond_history only) */
    msid_cplx *tm2;         /**< [L*q*q] their scatter (DROP rebuilds from the kept history plus these) */
    uint32_t tK;            /**< periods beyond the history */
    int beyond;             /**< 1: the period begun last has no history entry */
    double drift_pval;      /**< p-value of the drift test (NaN if untested) */
    uint32_t nhist;         /**< accepted periods stored */
    uint32_t seg_skipped;   /**< periods skipped in the current segment */
    msid_pstats_counts cnt;
} msid_pstats;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_pstats_mem_size(const msid_pstats_cfg *cfg);

/**
 * @brief Initialise empty statistics.
 * @return MSID_OK, MSID_E_NULL, MSID_E_DIMS, MSID_E_NO_LINES, MSID_E_ARG (transient test
 *         without history of at least 3 periods, or alpha outside (0,1)), MSID_E_MEM_ALIGN, MSID_E_MEM_SIZE.
 */
msid_status msid_pstats_init(msid_pstats *ps, const msid_pstats_cfg *cfg, void *mem, size_t len);

/** @brief Forget all periods and counters. */
void msid_pstats_reset(msid_pstats *ps);

/**
 * @brief Start a new segment of the same experiment (for example after a
 *        device restart): the next `skip_periods` valid periods are skipped
 *        again; statistics and counters are kept.
 */
void msid_pstats_new_segment(msid_pstats *ps);

/**
 * @brief Offer one completed period.
 * @param z spectra [L*q], index l*q + c (the layout of ::msid_linedft_spectra)
 * @param flags ::MSID_PERIOD_GAP / ::MSID_PERIOD_NONFINITE; a flagged period is counted and discarded
 * @return MSID_OK, or MSID_E_CAPACITY if the history is full and beyond_history is 0 (the period is
 *         not used).
 */
msid_status msid_pstats_add(msid_pstats *ps, const msid_cplx *z, uint32_t flags);

/**
 * @brief Spread form of ::msid_pstats_add, first part, O(1): counts the period
 *        and decides whether it is used (*use = 1: then K already counts it and
 *        its lines must follow through ::msid_pstats_add_lines before anything
 *        reads the statistics). Same return values as ::msid_pstats_add.
 */
msid_status msid_pstats_add_begin(msid_pstats *ps, uint32_t flags, int *use);

/**
 * @brief Spread form of ::msid_pstats_add, second part: history copy and Welford
 *        update of lines [l0, l1) of the period begun last, O((l1 - l0) q^2).
 *        Lines are independent: any split into ranges gives the bits of ::msid_pstats_add.
 */
void msid_pstats_add_lines(msid_pstats *ps, const msid_cplx *z, uint32_t l0, uint32_t l1);

/**
 * @brief Run the transient test on the stored periods (no-op when mode is OFF).
 *
 * For period p among K kept, line l and channel c, with leave-one-out mean and
 * variance s2 (K-2 complex dof): t = |z_p - mean_{-p}|^2 / (s2 (1 + 1/(K-1))),
 * which is F(2, 2(K-2)) under stationary circular Gaussian noise; its p-value
 * is (1 + t/(K-2))^{-(K-2)}. On a real line (DC or Nyquist: imaginary parts
 * exactly zero) it is F(1, K-2), the two-sided Student-t tail. Channels combine by Bonferroni within a line;
 * lines by a Fisher sum (conservative Gamma(L,1) tail) and a Bonferroni minimum,
 * each at half the level. Period k (0-based, in acceptance order) of K is
 * flagged when its p-value < alpha * (2^-(k+2) + 1/(2K)): a weighted
 * Bonferroni split that gives early periods (where transients sit) more of
 * alpha; the family-wise false-alarm probability stays below alpha.
 * The test is sequential in both modes: the most significant period (relative
 * to its level) is flagged and leaves the reference, and the rest are tested
 * again while K >= 3, so one large disturbance cannot hide a start-up
 * transient by inflating the others' scatter. A flagged period keeps the
 * p-value it was flagged with. DROP mode drops the flagged periods; FLAG mode
 * keeps them in the statistics. Every call (after each segment, say) tests
 * all kept periods afresh: a flag without a drop from an earlier call is
 * cleared first (and uncounted); dropped periods stay dropped.
 *
 * Drift (a trend through the whole record) is told apart from a start-up
 * transient first: with K >= 6 stored periods, a straight line in the period
 * number is fitted to every line and channel over the LATE half of the periods
 * (k >= K/2, where a start-up transient has died out), z_k = a + b k + e_k.
 * t = |b|^2 Sxx (n) / RSS with n = K_late - 2 is F(2, 2n) for a constant
 * spectrum in circular Gaussian noise (F(1, n) on a real line); channels,
 * lines combine as in the transient test. Drift is declared at p < alpha
 * (its own false-alarm probability alpha per experiment), with 5 or more late
 * periods only when the trend is also significant (at 5 alpha) without the
 * late period that departs most from its fitted line (largest studentised squared
 * residuals: one disturbed period at an end of the late half fits a line as
 * well as a drift does); the drift p-value is then max(p, p1 / 5). Then the
 * periods the transient test flags in one pass against all periods are kept
 * (never dropped: dropping early periods of a drifting record only moves the
 * estimate towards the late state).
 *
 * With beyond_history, the periods used after the history filled are in the
 * statistics but neither tested nor dropped: the tests see the first
 * max_periods kept periods. A DROP rebuild is then the Welford statistics of
 * the kept history merged with those of the later periods (Chan et al.'s
 * pairwise update); without drops the statistics are the streaming ones.
 * @return MSID_OK.
 */
msid_status msid_pstats_detect(msid_pstats *ps);

/** @brief Number of periods in the statistics (K). */
uint32_t msid_pstats_count(const msid_pstats *ps);

/** @brief Mean spectrum vector of line l: q values. */
const msid_cplx *msid_pstats_mean(const msid_pstats *ps, uint32_t l);

/** @brief Scatter matrix of line l (q x q, row-major): sum (z-mean)(z-mean)^H. Covariance = scatter/(K-1). */
const msid_cplx *msid_pstats_scatter(const msid_pstats *ps, uint32_t l);

/** @brief Counters. */
msid_pstats_counts msid_pstats_get_counts(const msid_pstats *ps);

/** @brief Stored accepted periods (history length). */
uint32_t msid_pstats_history(const msid_pstats *ps);

/**
 * @brief Test result of stored period k (in acceptance order, k < history length).
 * @param pval p-value of the transient test (NaN if untested); may be NULL
 * @return 0 kept, 1 flagged and kept, 2 flagged and dropped; -1 if k is out of range.
 */
int msid_pstats_period_state(const msid_pstats *ps, uint32_t k, double *pval);

/**
 * @brief Number of stored period k among all periods offered to this
 *        experiment (0-based: skipped, gap and non-finite periods count), so
 *        that reports name the period as it sits in the record; UINT32_MAX if
 *        k is out of range.
 */
uint32_t msid_pstats_period_number(const msid_pstats *ps, uint32_t k);

/** @brief p-value of the drift test (NaN if it did not run); see ::msid_pstats_detect. */
double msid_pstats_drift_pvalue(const msid_pstats *ps);

#ifdef __cplusplus
}
#endif
#endif
