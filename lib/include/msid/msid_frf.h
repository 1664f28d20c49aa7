/**
 * @file msid_frf.h
 * @brief MIMO least-squares FRF per line with two covariance estimates.
 *
 * From the period statistics of m experiments (::msid_pstats, lines excited
 * first, then detection lines), per excited line:
 *  - Ghat = Ybar Ubar^H (Ubar Ubar^H)^{-1}  (ny x nu), Ybar = [ybar_1..ybar_m],
 *    Ubar = [ubar_1..ubar_m]; for m = nu this is the ETFE Y U^{-1}
 *    (González et al. 2025 eq. 37; Tsiamis et al. 2024 eq. 5).
 *  - cov (nonparametric, errors-in-variables): with W = Ubar^+ (m x nu),
 *    Cov vec(Ghat) = sum_e (w_e^T conj(w_e)) (x) S_e,
 *    S_e = [-Ghat I] C_Z,e [-Ghat I]^H / K_e  (Pintelon 2002 eqs. 31-32, MIMO form).
 *    Valid with noisy inputs and coloured noise.
 *  - cov_known_input: the input is taken as exact and the output noise
 *    covariance pooled over experiments, Sigma_p = sum_e S_yy,e / sum_e (K_e-1):
 *    Cov vec(Ghat) = sum_e (w_e^T conj(w_e)) (x) Sigma_p / K_e, i.e. the
 *    Sigma (x) Z^{-1} structure of González Theorem 2 (eq. 29), block-diagonal per line.
 * vec stacks columns: element (i, j) of G has vec index i + ny*j; covariance
 * matrices are (ny*nu) x (ny*nu), row-major.
 *
 * Degrees of freedom (complex): dof_known_input = sum_e (K_e - 1) exactly.
 * dof (nonparametric) is the Satterthwaite value (sum c_e)^2 / sum c_e^2/(K_e-1)
 * with c_e = |w_e|^2 / K_e (equal noise assumed across experiments); it equals
 * sum_e (K_e - 1) for balanced designs. For a scalar element with variance v
 * and dof n, |Ghat_ij - G_ij|^2 / v ~ F(2, 2n) (exact for known input);
 * for a DC line (real) (Ghat_ij - G_ij)^2 / v ~ F(1, n).
 */
#ifndef MSID_FRF_H
#define MSID_FRF_H

#include "msid_pstats.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Configuration. */
typedef struct msid_frf_cfg {
    uint32_t period;         /**< P (for frequencies and noise scaling) */
    uint32_t n_inputs;       /**< nu */
    uint32_t n_outputs;      /**< ny */
    uint32_t n_experiments;  /**< m >= nu */
    uint32_t n_lines;        /**< excited lines L (first L lines of the statistics) */
    uint32_t n_detect;       /**< detection lines after them (may be 0) */
    const uint8_t *folded;   /**< [L] or NULL: 1 where a CT line folded (G and cov are conjugated) */
} msid_frf_cfg;

/** Per-line solve status. */
#define MSID_LINE_OK 0
#define MSID_LINE_SINGULAR 1   /**< Ubar is numerically singular (cond > 1e12) */
#define MSID_LINE_UNEXCITED 2  /**< the inputs barely reach the line: weakest input direction
                                    below 1e-10 of the strongest line, or below 10 dB over the input noise */

/** Instance (caller-owned). */
typedef struct msid_frf {
    uint32_t period, n_inputs, n_outputs, n_experiments, n_lines, n_detect;
    uint8_t *folded;          /**< [L] */
    msid_cplx *G;             /**< [L * ny*nu] row-major ny x nu */
    msid_cplx *cov;           /**< [L * (ny nu)^2] */
    msid_cplx *cov_ki;        /**< [L * (ny nu)^2] */
    double *dof;              /**< [L] */
    double *dof_ki;           /**< [L] */
    msid_cplx *noise;         /**< [L * ny*ny] pooled per-period output noise covariance */
    double *snr;              /**< [L * ny] SNR of the averaged output spectrum, dB */
    double *cond;             /**< [L] condition number of Ubar */
    double *urel;             /**< [L] smallest singular value of Ubar squared, over the largest |Ubar|_F^2 of all lines */
    double *usnr;             /**< [L] smallest singular value of Ubar squared over the input noise power of the means (inf: exact input) */
    uint8_t *line_status;     /**< [L] MSID_LINE_* */
    msid_cplx *noise_time;    /**< [ny*ny] time-domain noise covariance estimate */
    msid_cplx *dmean;         /**< [n_detect * m * ny] mean output spectrum at detection lines */
    double *dvar;             /**< [n_detect * ny] pooled per-period variance there */
    double *dpval;            /**< [n_detect * ny] p-value of "no periodic content" */
    msid_cplx *work;          /**< scratch */
    int32_t bad_line;         /**< first singular line (-1 if none) */
    int32_t bad_experiment;   /**< experiment with < 2 periods (-1 if none) */
    uint32_t K_total;         /**< sum of K_e */
} msid_frf;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_frf_mem_size(const msid_frf_cfg *cfg);

/** @brief Initialise. @return MSID_OK, MSID_E_NULL, MSID_E_DIMS, MSID_E_EXPERIMENTS, MSID_E_NO_LINES, MSID_E_PERIOD, MSID_E_MEM_*. */
msid_status msid_frf_init(msid_frf *f, const msid_frf_cfg *cfg, void *mem, size_t len);

/**
 * @brief Solve every line from the statistics of the m experiments.
 * @param stats [m] statistics with n_lines + n_detect lines and nu + ny channels ([u; y])
 * @return MSID_OK; MSID_E_FEW_PERIODS (see bad_experiment) if an experiment has < 2 periods;
 *         MSID_E_SINGULAR (see bad_line and ::msid_frf_line_status) if Ubar is singular
 *         (cond > 1e12) or the inputs do not excite a line (MSID_LINE_UNEXCITED) - the
 *         other lines are still solved; MSID_E_DIMS if the statistics do not match;
 *         MSID_E_RANGE (see bad_line) if |U|^2 at a line over- or underflows (nothing is
 *         solved then), or a solved line's G, covariances, noise or dof are not finite
 *         (data scaled near 1e+-150): results are never silently NaN or infinite.
 */
msid_status msid_frf_compute(msid_frf *f, const msid_pstats *const *stats);

/** @brief Ghat at line l: ny x nu row-major. */
const msid_cplx *msid_frf_G(const msid_frf *f, uint32_t l);
/** @brief Nonparametric covariance of vec(Ghat) at line l, (ny nu)^2 row-major. */
const msid_cplx *msid_frf_cov(const msid_frf *f, uint32_t l);
/** @brief Known-input (pooled) covariance of vec(Ghat) at line l. */
const msid_cplx *msid_frf_cov_known_input(const msid_frf *f, uint32_t l);
/** @brief Complex degrees of freedom of ::msid_frf_cov at line l. */
double msid_frf_dof(const msid_frf *f, uint32_t l);
/** @brief Complex degrees of freedom of ::msid_frf_cov_known_input at line l. */
double msid_frf_dof_known_input(const msid_frf *f, uint32_t l);
/** @brief Pooled output noise covariance of one period's DFT at line l (ny x ny). */
const msid_cplx *msid_frf_noise_cov(const msid_frf *f, uint32_t l);
/** @brief Per-output SNR (dB) of the period-averaged output spectrum at line l (+inf if noiseless). */
const double *msid_frf_snr_db(const msid_frf *f, uint32_t l);
/** @brief Condition number of Ubar at line l. */
double msid_frf_cond(const msid_frf *f, uint32_t l);
/** @brief MSID_LINE_OK, MSID_LINE_SINGULAR or MSID_LINE_UNEXCITED. */
int msid_frf_line_status(const msid_frf *f, uint32_t l);
/** @brief Input SNR at line l in dB: weakest input direction (smallest singular value of
 *  Ubar, squared) over the noise power of the input means; +inf for exact inputs. */
double msid_frf_input_snr_db(const msid_frf *f, uint32_t l);
/** @brief Input level at line l in dB relative to the strongest line (weakest input direction). */
double msid_frf_input_rel_db(const msid_frf *f, uint32_t l);
/** @brief Time-domain output noise covariance estimate (ny x ny): mean over lines of noise_cov / P. */
const msid_cplx *msid_frf_noise_cov_time(const msid_frf *f);
/** @brief Mean output spectrum at detection line d: [m * ny], index e*ny + i. */
const msid_cplx *msid_frf_detect_mean(const msid_frf *f, uint32_t d);
/** @brief Pooled per-period output variance at detection line d: [ny]. */
const double *msid_frf_detect_var(const msid_frf *f, uint32_t d);
/** @brief p-value (per output) of "no periodic content" at detection line d: F(2m, 2 sum(K_e-1)) test. */
const double *msid_frf_detect_pvalue(const msid_frf *f, uint32_t d);

#ifdef __cplusplus
}
#endif
#endif
