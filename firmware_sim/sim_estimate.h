/**
 * @file sim_estimate.h
 * @brief On-device estimation: the device runs lib/'s msid_meas on
 *        every sample it produces, as encoded for the link (the ADC's codes:
 *        int16/int32 scaled or float32, decoded back to doubles), and solves
 *        msid_frf on request. Fixed memory from the device's arena, bounded by
 *        a budget (--est-mem) so a small target's refusal can be tested.
 *        Protocol-neutral: the Modbus front end publishes the result
 *        (msid-modbus/1 extension estimate/1, daq/include/msid_daq/msid_mb_est.h).
 */
#ifndef MSID_SIM_ESTIMATE_H
#define MSID_SIM_ESTIMATE_H

#include "sim_device.h"

/** Default bytes the device gives its estimator (a Cortex-M7 class part's spare RAM). */
#define SIM_EST_DEFAULT_MEM (1u << 20)

/** The estimator's settings (from the host, latched at COMMIT). */
typedef struct sim_est_cfg {
    uint32_t skip_periods;
    msid_transient_mode transient;
    double alpha;
    uint32_t periods;                /**< K per experiment (sizes the transient test as the host does) */
} sim_est_cfg;

/** The on-device estimator (part of the front end that publishes it). */
typedef struct sim_est {
    int on;                          /**< set up and accumulating */
    msid_status status;              /**< first error (0: none) */
    int32_t bad;                     /**< bad line or experiment (-1: none) */
    size_t need, have;               /**< bytes needed / the budget */
    uint64_t periods;                /**< periods in the statistics (all experiments) */
    int solved;
    msid_meas ms;
    msid_frf f;
} sim_est;

/**
 * @brief Set up after a COMMIT: msid_meas (stream path, the host's transient
 *        settings: test only with >= skip + 3 periods, history 4 K + 8) and
 *        msid_frf for the committed design. @return MSID_OK, MSID_E_MEM_SIZE
 *        (need > budget: e->need, e->have), or the core's refusal.
 */
msid_status sim_est_setup(sim_est *e, sim_device *d, const sim_est_cfg *c);
/** @brief Open experiment x (a new segment after a device restart). */
void sim_est_begin(sim_est *e, uint32_t x);
/** @brief One sample row (nu + ny doubles, as the host would decode it). */
void sim_est_push(sim_est *e, const double *row);
/** @brief Close the open experiment (the design's samples are all produced). */
void sim_est_end(sim_est *e);
/** @brief Solve the FRF from all experiments; MSID_OK or the msid_frf status (bad: line or experiment). */
msid_status sim_est_solve(sim_est *e);

#endif
