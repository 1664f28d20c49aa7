/**
 * @file msid_mb_est.h
 * @brief msid-modbus/1 extension "estimate/1": estimation on the device.
 *        Shared by the device (firmware_sim/, which fills the result block
 *        from its own msid_meas + msid_frf) and the host (daq/, tools/, which
 *        reads it back). Pure C11: no OS calls, no heap, no stdio.
 *
 * The extension keeps register map version 1: a device that has it sets bit 0
 * of input register MSID_MB_IR_EXT (40, after the 40 header registers a
 * version-1 host reads); a device without it leaves 40.. at 0. The host
 * writes the estimator settings into holding registers 140..146 before the
 * design upload (the device latches them at COMMIT and clears MODE, so a
 * later host that knows nothing of the extension gets a plain device), runs
 * the experiments, sends SOLVE, waits for EST_STATE READY and reads the
 * result block: every value an IEEE-754 double in 4 registers, most
 * significant word first (bit for bit, no scaling). docs/modbus-registers.md.
 */
#ifndef MSID_MB_EST_H
#define MSID_MB_EST_H

#include <stddef.h>
#include <stdint.h>

#include "msid/msid.h"
#include "msid_mb_proto.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Extension bits in MSID_MB_IR_EXT. */
#define MSID_MB_EXT_ESTIMATE 0x0001u
/** Version of the estimate extension (MSID_MB_IR_EST_VERSION). */
#define MSID_MB_EST_VERSION 1u

/** Holding registers of the extension (written before the upload, latched at COMMIT). */
enum {
    MSID_MB_HR_EST_MODE = 140,       /**< MSID_MB_EST_OFF / _ONLY / _STREAM; cleared by the device at COMMIT */
    MSID_MB_HR_EST_SKIP = 141,       /**< leading periods of each experiment not used */
    MSID_MB_HR_EST_TRANSIENT = 142,  /**< msid_transient_mode: 0 off, 1 flag, 2 drop */
    MSID_MB_HR_EST_ALPHA = 143,      /**< 143-146: level of the transient test, float64 */
    MSID_MB_HR_EXT_COUNT = 147       /**< holding registers of a device with the extension */
};

/** Estimation modes. */
enum {
    MSID_MB_EST_OFF = 0,     /**< a plain msid-modbus/1 device: the ring carries the samples */
    MSID_MB_EST_ONLY = 1,    /**< the device estimates; no ring (the plant rate is not bounded by the link) */
    MSID_MB_EST_STREAM = 2   /**< the device estimates and also fills the ring (a host can check it bit for bit) */
};

/** Input registers of the extension: 40..55 (the ring starts at 64). */
enum {
    MSID_MB_IR_EXT = 40,             /**< extension bits (0: none) */
    MSID_MB_IR_EST_VERSION = 41,     /**< MSID_MB_EST_VERSION */
    MSID_MB_IR_EST_MODE = 42,        /**< mode latched at COMMIT */
    MSID_MB_IR_EST_STATE = 43,       /**< MSID_MB_EST_STATE_* */
    MSID_MB_IR_EST_STATUS = 44,      /**< msid_status of the device's estimator (0: none) */
    MSID_MB_IR_EST_BAD = 45,         /**< bad line (singular, range) or experiment (few periods) + 1; 0: none */
    MSID_MB_IR_EST_NEED = 46,        /**< 46-47: bytes of working memory the estimator needs */
    MSID_MB_IR_EST_HAVE = 48,        /**< 48-49: bytes the device has for it */
    MSID_MB_IR_EST_ADDR = 50,        /**< input register of the result block */
    MSID_MB_IR_EST_REGS = 51,        /**< 51-52: registers of the result block */
    MSID_MB_IR_EST_PERIODS = 53,     /**< 53-54: periods in the statistics so far (all experiments; per period) */
    MSID_MB_IR_EST_SOLVED = 55,      /**< SOLVE commands completed (mod 65536) */
    MSID_MB_IR_EXT_END = 56          /**< first register after the extension header */
};

/** Command of the extension (holding register CMD). */
#define MSID_MB_CMD_SOLVE 4u

/** Estimator states. */
enum {
    MSID_MB_EST_STATE_OFF = 0,       /**< not requested at COMMIT */
    MSID_MB_EST_STATE_ACCUMULATING = 1, /**< set up: experiments feed the statistics */
    MSID_MB_EST_STATE_READY = 2,     /**< SOLVE done: the result block holds the FRF */
    MSID_MB_EST_STATE_ERROR = 3      /**< refused or failed: EST_STATUS (msid_status), EST_BAD, EST_NEED/HAVE */
};

/** Doubles per experiment in the result block: the period counts, drift p-value, samples, leftover. */
enum {
    MSID_MB_EST_X_OFFERED = 0, MSID_MB_EST_X_SKIPPED, MSID_MB_EST_X_GAP, MSID_MB_EST_X_NONFINITE,
    MSID_MB_EST_X_FLAGGED, MSID_MB_EST_X_DROPPED, MSID_MB_EST_X_USED, MSID_MB_EST_X_TESTED,
    MSID_MB_EST_X_DRIFT_TESTED, MSID_MB_EST_X_DRIFT, MSID_MB_EST_X_DRIFT_P, MSID_MB_EST_X_SAMPLES,
    MSID_MB_EST_X_LEFTOVER,
    MSID_MB_EST_X_PERIODS,           /**< MSID_MB_EST_FLAG_MAX entries: 4 (period number from 1) + state
                                          (1 flagged, 2 dropped by the transient test); 0: none; the first ones */
    MSID_MB_EST_X_COUNT = MSID_MB_EST_X_PERIODS + 16
};
/** Flagged periods listed per experiment (the counts are complete; the list holds the first ones). */
#define MSID_MB_EST_FLAG_MAX 16u

/**
 * Layout of the result block, in doubles (4 registers each):
 *   [m * MSID_MB_EST_X_COUNT]  per experiment (index e * X_COUNT + MSID_MB_EST_X_*): period counts,
 *                               drift p-value, samples, leftover, flagged periods
 *   [2 ny^2]                    time-domain noise covariance (re, im pairs, row-major)
 *   [L * line]                  per excited line: G (2 ny nu), cov (2 g^2), dof, cov_known_input (2 g^2),
 *                               dof_known_input, noise_cov (2 ny^2), snr (ny, dB), cond, input_snr (dB),
 *                               line status (MSID_LINE_*), with g = ny nu; complex values as (re, im).
 */
typedef struct msid_mb_est_layout {
    uint32_t nu, ny, m, L;
    uint32_t noise;       /**< offset of the noise covariance */
    uint32_t lines;       /**< offset of line 0 */
    uint32_t line;        /**< doubles per line */
    uint32_t G, cov, dof, cov_ki, dof_ki, lnoise, snr, cond, usnr, status;  /**< offsets within a line */
    uint32_t doubles;     /**< total doubles */
} msid_mb_est_layout;

/** @brief The layout for these dimensions; 0, or -1 if they are out of range. */
int msid_mb_est_layout_init(msid_mb_est_layout *lo, uint32_t nu, uint32_t ny, uint32_t m, uint32_t L);

/** @brief Registers of the result block (4 per double). */
uint32_t msid_mb_est_regs(const msid_mb_est_layout *lo);

/** @brief Store a double in 4 registers, most significant word first (bit for bit). */
void msid_mb_put_f64(uint16_t *regs, double v);
/** @brief Read a double from 4 registers, most significant word first. */
double msid_mb_get_f64(const uint16_t *regs);

/**
 * @brief Device side: fill the result block (msid_mb_est_regs registers) from
 *        the measurement and the solved FRF (lines not solved carry NaN).
 */
void msid_mb_est_encode(uint16_t *regs, const msid_mb_est_layout *lo, const msid_meas *ms, const msid_frf *f);

/** @brief Host side: double number k of the block. */
double msid_mb_est_value(const uint16_t *regs, uint32_t k);

/** @brief Name of an estimator state ("off", "accumulating", "ready", "error"; "?" if unknown). */
const char *msid_mb_est_state_name(uint32_t s);

#ifdef __cplusplus
}
#endif
#endif
