/**
 * @file msid_design.h
 * @brief Multisine excitation design: period, lines, amplitudes, phases and
 *        the MIMO pattern across experiments.
 *
 * A design describes m experiments on nu inputs. In experiment e, input i is
 * @f[ u_i^{(e)}(n) = \sum_l \mathrm{Re}\{ c_{e,i,l}\, e^{j 2\pi b_l n / P} \} @f]
 * with @f$ c_{e,i,l} = A_{i,l}\, e^{j 2\pi \varphi_{i,l}}\, T_{i,e} @f$, where
 * T is the nu x m pattern (rows of the m-point DFT matrix, or of a Sylvester
 * Hadamard matrix). T has orthogonal rows, so every line's nu x m input matrix
 * U_l = diag(A e^{j phi}) T has condition number max_i A_{i,l} / min_i A_{i,l}
 * (1 for equal amplitudes). This is Assumption 1 of González et al. 2025 (eq. 3).
 * A DC line (bin 0) must stay real: it uses Hadamard signs, or with the DFT
 * pattern the real basis 1, cos(2 pi k e/m), sin(2 pi k e/m), ..., whose rows
 * are orthogonal with norms sqrt(m) or sqrt(m/2): condition number <= sqrt(2).
 *
 * Continuous-time designs give line frequencies in rad/s and a sample time h.
 * Each line must complete a whole number of cycles in P*h; it maps to the
 * discrete-time bin it aliases to, folding to P-b (and conjugating) above
 * Nyquist. Sampling slower than Nyquist is supported. Designs that violate
 * Assumption 2 (eq. 5) are refused: two lines on one bin, or a non-zero line
 * on DC or Nyquist. The refused lines are named by ::msid_design_diag.
 */
#ifndef MSID_DESIGN_H
#define MSID_DESIGN_H

#include "msid_types.h"
#include "msid_status.h"
#include "msid_twiddle.h"
#include "msid_fft.h"

#ifdef __cplusplus
extern "C" {
#endif

/** How the line phases are chosen. */
typedef enum msid_phase_mode {
    MSID_PHASE_RANDOM = 0,    /**< uniform in [0,1) turns from msid_rng seeded by `seed` */
    MSID_PHASE_SCHROEDER = 1, /**< Schroeder phases, low crest factor (per input) */
    MSID_PHASE_USER = 2       /**< given in `phases` */
} msid_phase_mode;

/** Phase/sign pattern across experiments. */
typedef enum msid_pattern {
    MSID_PATTERN_DFT = 0,      /**< T[i][e] = exp(-j 2 pi i e / m), any m >= nu */
    MSID_PATTERN_HADAMARD = 1  /**< T = rows of the Sylvester Hadamard matrix, m a power of 2 */
} msid_pattern;

/**
 * How ::msid_design_init computes the crest factors max|u|/rms(u) (direct synthesis is O(m nu P L):
 * too slow for a host design of large P with many lines, fine for a small firmware design).
 */
typedef enum msid_crest_mode {
    MSID_CREST_DIRECT = 0, /**< direct synthesis of every sample, O(m nu P L), no extra memory (small designs) */
    MSID_CREST_FFT = 1,    /**< two real DFTs per input and experiment through cfg->fft, O(m nu P log P);
                                2.5 P doubles more working memory. Same samples up to rounding (~1e-15 relative) */
    MSID_CREST_NONE = 2    /**< not computed (NaN), O(1): devices and readers that never report them */
} msid_crest_mode;

/** Design configuration. All pointers are read during init only. */
typedef struct msid_design_cfg {
    uint32_t period;          /**< P, samples per period, [MSID_MIN_PERIOD, MSID_MAX_PERIOD] */
    uint32_t n_lines;         /**< L >= 1 */
    const uint32_t *bins;     /**< discrete-time design: L bins, each in [0, P/2), no duplicates; bin 0 is a DC line */
    const double *omega;      /**< continuous-time design (used when bins == NULL): L frequencies in rad/s, >= 0 */
    double sample_time;       /**< continuous-time design: h in seconds, > 0 */
    double ct_tol;            /**< CT: tolerance in cycles on omega*P*h/(2 pi) being an integer; 0 selects 1e-6 */
    const double *amplitudes; /**< NULL for all 1; else L values, or nu*L values [i*L + l] if amp_per_input,
                                   each in [MSID_MIN_AMPLITUDE, MSID_MAX_AMPLITUDE] */
    int amp_per_input;        /**< 0: amplitudes shared by all inputs; 1: one row per input */
    msid_phase_mode phase_mode; /**< phase choice */
    const double *phases;     /**< MSID_PHASE_USER: nu*L phases in turns [i*L + l] (1 turn = 2 pi rad) */
    uint64_t seed;            /**< MSID_PHASE_RANDOM seed */
    uint32_t n_inputs;        /**< nu in [1, MSID_MAX_INPUTS] */
    uint32_t n_experiments;   /**< m in [nu, MSID_MAX_EXPERIMENTS] */
    msid_pattern pattern;     /**< pattern across experiments */
    const msid_twiddle *twiddle; /**< table of the same period; used to compute the crest factors */
    msid_crest_mode crest;    /**< how the crest factors are computed (0: MSID_CREST_DIRECT) */
    const msid_fft_backend *fft; /**< MSID_CREST_FFT: a real DFT of length `period` */
} msid_design_cfg;

/** Which lines made a design fail (see ::msid_design_diag). -1 when not applicable. */
typedef struct msid_design_diag_t {
    int32_t line_a;   /**< first offending line index (0-based), or -1 */
    int32_t line_b;   /**< second offending line index, or -1 */
    int64_t bin;      /**< the bin involved, or -1 */
} msid_design_diag_t;

/** Design instance (caller-owned). Read it through the accessor functions. */
typedef struct msid_design {
    uint32_t period, n_lines, n_inputs, n_experiments;
    int is_ct;                /**< 1 for a continuous-time design */
    double sample_time;       /**< h (CT), else 0 */
    msid_phase_mode phase_mode;
    msid_pattern pattern;
    uint64_t seed;
    uint32_t *bins;           /**< [L] discrete-time bin of each line */
    uint8_t *folded;          /**< [L] 1 if the CT line folds to P - b (its DT coefficient is conjugated) */
    double *omega;            /**< [L] CT frequency in rad/s (CT designs), else 2 pi b / P rad/sample */
    double *amp;              /**< [nu*L] amplitude A_{i,l} (peak) */
    double *phase;            /**< [nu*L] base phase in turns */
    msid_cplx *coef;          /**< [m*nu*L] DT coefficient c_{e,i,l} (index (e*nu + i)*L + l) */
    double *cond;             /**< [L] condition number of the nu x m input matrix of each line */
    double cond_max;          /**< max over lines of cond */
    double *crest;            /**< [m*nu] crest factor max|u|/rms(u) of each input in each experiment */
    msid_design_diag_t diag;  /**< offending lines when init failed */
} msid_design;

/**
 * @brief Bytes of working memory for a design.
 * @return the size, or 0 if the dimensions in cfg are out of range.
 */
size_t msid_design_mem_size(const msid_design_cfg *cfg);

/**
 * @brief Validate and build a design. On failure, ::msid_design_diag names the offending lines.
 * @return MSID_OK or one of MSID_E_NULL, MSID_E_MEM_SIZE, MSID_E_MEM_ALIGN, MSID_E_PERIOD,
 *         MSID_E_NO_LINES, MSID_E_LINE_RANGE, MSID_E_LINE_DUP, MSID_E_DIMS, MSID_E_EXPERIMENTS,
 *         MSID_E_AMPLITUDE, MSID_E_PHASE, MSID_E_PATTERN, MSID_E_SAMPLE_TIME,
 *         MSID_E_CT_NOT_PERIODIC, MSID_E_ALIAS_COLLISION, MSID_E_ALIAS_EDGE, MSID_E_SINGULAR,
 *         MSID_E_ARG (unknown phase mode).
 */
msid_status msid_design_init(msid_design *d, const msid_design_cfg *cfg, void *mem, size_t len);

/** @brief Offending lines of the last failed ::msid_design_init (valid even when init failed). */
msid_design_diag_t msid_design_diag(const msid_design *d);

/**
 * @brief Complex coefficient c_{e,i,l} (the sample-domain phasor of line l).
 * @param e experiment in [0, m); @param i input in [0, nu); @param l line in [0, L)
 */
msid_cplx msid_design_coef(const msid_design *d, uint32_t e, uint32_t i, uint32_t l);

/**
 * @brief Expected one-period DFT of input i in experiment e at line l:
 *        P/2 * c for 0 < b < P/2, P * Re(c) for the DC line.
 *        (DFT convention X[b] = sum_n x[n] exp(-j 2 pi b n / P).)
 */
msid_cplx msid_design_input_dft(const msid_design *d, uint32_t e, uint32_t i, uint32_t l);

/**
 * @brief Crest factor max|u| / rms(u) of input i in experiment e over one period
 *        (computed at init from the exact samples ::msid_gen produces).
 * @return the crest factor (>= 1), or NaN if an index is out of range.
 */
double msid_design_crest_factor(const msid_design *d, uint32_t e, uint32_t i);

/** @brief Condition number of line l's nu x m input matrix (NaN if l is out of range). */
double msid_design_cond(const msid_design *d, uint32_t l);

/**
 * @brief Sample of input i in experiment e at period index n, computed the way
 *        ::msid_gen does (bit-identical). O(L). For tests and one-off use.
 */
double msid_design_sample(const msid_design *d, const msid_twiddle *tw, uint32_t e, uint32_t i, uint32_t n);

#ifdef __cplusplus
}
#endif
#endif
