/**
 * @file msid_params.h
 * @brief The parameter set a host uploads to a device (design parameters and stream
 *        format), shared by msid-can/1 and msid-modbus/1: both carry it as the same
 *        8-byte CFG records (msid_can_proto.h), BEGIN first, COMMIT (CRC-32) last.
 *        Pure C11: no OS calls, no heap, no stdio.
 */
#ifndef MSID_PARAMS_H
#define MSID_PARAMS_H

#include <stddef.h>
#include <stdint.h>
#include "msid/msid_design.h"
#include "msid_can_proto.h" /* same directory: the CFG record layout */

#ifdef __cplusplus
extern "C" {
#endif

/** Largest number of lines a device accepts. */
#define MSID_PARAMS_MAX_LINES 1024u
/** Largest number of periods per experiment a parameter set may ask for (the host's --periods limit). */
#define MSID_PARAMS_MAX_PERIODS 100000u

/** The uploaded configuration (design parameters and stream format). */
typedef struct msid_params {
    uint32_t period, n_lines, n_inputs, n_experiments;
    uint32_t pattern, phase_mode;
    uint64_t seed;
    uint32_t bins[MSID_PARAMS_MAX_LINES];
    double amp[MSID_MAX_INPUTS * MSID_PARAMS_MAX_LINES];     /**< [i L + l] */
    double phase[MSID_MAX_INPUTS * MSID_PARAMS_MAX_LINES];   /**< [i L + l], turns */
    double omega[MSID_PARAMS_MAX_LINES];
    double sample_time;
    int have_amp, have_phase, is_ct;
    uint32_t encoding, fd, rate_hz, periods;
    float scale;
    /* receive-side bookkeeping */
    uint32_t crc;       /**< CRC of the committed configuration */
    uint32_t n_frames;  /**< CFG frames since BEGIN */
    uint32_t got[16];   /**< words received per parameter class */
    uint32_t run_crc;
    int open;           /**< 1 between BEGIN and COMMIT */
} msid_params;

/** @brief Empty configuration (no BEGIN seen). */
void msid_params_reset(msid_params *c);

/**
 * @brief CFG frames (8 bytes each) that upload `c`, BEGIN first and COMMIT last.
 * @param out room for `cap` frames, or NULL to count
 * @return the number of frames (0 if c is out of range)
 */
size_t msid_params_frames(const msid_params *c, uint8_t (*out)[8], size_t cap);

/**
 * @brief Apply one CFG frame (device side, and the host replaying a log).
 * @return 0 accepted (more to come), 1 committed (c is complete and consistent),
 *         or -MSID_CAN_ERR_VERSION / -MSID_CAN_ERR_CRC / -MSID_CAN_ERR_CFG.
 */
int msid_params_feed(msid_params *c, const uint8_t *data, uint32_t len, uint32_t host_version);

/** @brief Fill a design configuration that points into `c` (valid while c lives). */
void msid_params_design_cfg(const msid_params *c, msid_design_cfg *dc, const msid_twiddle *tw);

#ifdef __cplusplus
}
#endif
#endif
