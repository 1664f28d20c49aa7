/**
 * @file msid_can_est.h
 * @brief msid-can/1 extension "estimate/1": estimation on the device over CAN.
 *        Shared by the device (firmware_sim/sim_can.c) and hosts; pure C11.
 *
 * Two identifiers beside the base protocol (docs/can-protocol.md), classic
 * 8-byte frames, little-endian like the rest of msid-can/1:
 *  - EST_CTRL (base + 0x03, host -> device): ALPHA words, SETUP (after
 *    COMMIT, before START: mode, transient test, skip periods), SOLVE, QUERY;
 *  - EST (base + 0x04, device -> host), multiplexed by byte 0: STATE, NEED,
 *    HAVE, SIZE, PERIODS, and the result block as VALUE_LO / VALUE_HI pairs
 *    (a double's low and high 32 bits with its 24-bit index), bit for bit.
 * The result block is the Modbus extension's (msid_mb_est.h: per experiment
 * counts, the noise covariance, per line G, cov, dof, cov_known_input,
 * dof_known_input, noise_cov, snr, cond, input_snr, status), as doubles.
 * A device without the extension ignores both identifiers: a host that gets
 * no EST STATE after SETUP knows it has none. Protocol version stays 1.
 */
#ifndef MSID_CAN_EST_H
#define MSID_CAN_EST_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MSID_CAN_ID_EST_CTRL 0x03u   /**< host -> device */
#define MSID_CAN_ID_EST 0x04u        /**< device -> host */

/** EST_CTRL byte 0. */
enum {
    MSID_CAN_EST_CMD_SETUP = 1,   /**< byte 1 mode (1 estimate only: no sample frames; 2 estimate and stream),
                                       byte 2 transient (0 off, 1 flag, 2 drop), bytes 4-5 skip periods (u16) */
    MSID_CAN_EST_CMD_ALPHA = 2,   /**< byte 1 word (0 low, 1 high) of the transient test level (double), bytes 4-7;
                                       sent before SETUP (default 0.01) */
    MSID_CAN_EST_CMD_SOLVE = 3,   /**< solve; the device answers STATE, then SIZE and the block, then STATE again */
    MSID_CAN_EST_CMD_QUERY = 4    /**< the device answers STATE, NEED, HAVE, PERIODS */
};

/** EST byte 0 (mux). */
enum {
    MSID_CAN_EST_MUX_STATE = 0,   /**< byte 1 state, byte 2 mode, byte 3 extension version, bytes 4-5 msid_status,
                                       bytes 6-7 bad line/experiment + 1 */
    MSID_CAN_EST_MUX_NEED = 1,    /**< bytes 4-7: bytes of working memory the estimator needs */
    MSID_CAN_EST_MUX_HAVE = 2,    /**< bytes 4-7: bytes the device has for it */
    MSID_CAN_EST_MUX_SIZE = 3,    /**< bytes 4-7: doubles in the result block */
    MSID_CAN_EST_MUX_PERIODS = 4, /**< bytes 4-7: periods in the statistics (all experiments) */
    MSID_CAN_EST_MUX_LO = 16,     /**< bytes 1-3 index, bytes 4-7 low 32 bits of double `index` */
    MSID_CAN_EST_MUX_HI = 17      /**< bytes 1-3 index, bytes 4-7 high 32 bits */
};

/** Estimator states (as the Modbus extension's EST_STATE). */
enum {
    MSID_CAN_EST_STATE_OFF = 0, MSID_CAN_EST_STATE_ACCUMULATING = 1, MSID_CAN_EST_STATE_READY = 2,
    MSID_CAN_EST_STATE_ERROR = 3
};

/** Version of the CAN estimate extension (EST STATE byte 3). */
#define MSID_CAN_EST_VERSION 1u

/** @brief EST STATE frame. */
void msid_can_est_encode_state(uint8_t d[8], uint32_t state, uint32_t mode, uint32_t status, uint32_t bad1);
/** @brief EST NEED / HAVE / SIZE / PERIODS frame. */
void msid_can_est_encode_u32(uint8_t d[8], uint32_t mux, uint32_t v);
/** @brief The two EST frames of double `index` (lo, hi). */
void msid_can_est_encode_value(uint8_t lo[8], uint8_t hi[8], uint32_t index, double v);
/**
 * @brief Host side: collect a VALUE_LO/HI frame into vals[n] (have[n]: bit 0 low, bit 1 high word seen).
 * @return 1 if the frame was a value inside [0, n), 0 otherwise.
 */
int msid_can_est_collect(const uint8_t d[8], double *vals, uint8_t *have, uint32_t n);

/** Host side: what the device last said in its EST frames (STATE, NEED, HAVE, SIZE, PERIODS). */
typedef struct msid_can_est_view {
    uint32_t states;              /**< EST STATE frames seen (a counter: a caller compares before and after a request) */
    uint32_t answers;             /**< EST PERIODS frames seen (the last frame of the answer to SETUP and QUERY) */
    uint32_t state;               /**< MSID_CAN_EST_STATE_* of the last STATE */
    uint32_t mode;                /**< 0 off, 1 estimate only, 2 estimate and stream */
    uint32_t version;             /**< extension version (MSID_CAN_EST_VERSION) */
    uint32_t status;              /**< msid_status of a failure (0: none) */
    uint32_t bad1;                /**< bad line (singular, range) or experiment (few periods) + 1; 0: none */
    uint32_t need, have;          /**< working memory: bytes the estimator needs / the device has for it */
    uint32_t size;                /**< doubles in the result block (SIZE) */
    uint32_t periods;             /**< periods in the statistics, all experiments */
} msid_can_est_view;

/**
 * @brief Host side: apply an EST frame's payload to *v (STATE, NEED, HAVE, SIZE, PERIODS; values are
 *        left to ::msid_can_est_collect).
 * @return the multiplexer (MSID_CAN_EST_MUX_*) or -1 for one it does not know (v unchanged).
 */
int msid_can_est_update(msid_can_est_view *v, const uint8_t d[8]);

#ifdef __cplusplus
}
#endif
#endif
