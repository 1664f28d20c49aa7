/**
 * @file sim_co402.h
 * @brief The simulated drive's CiA 402 side: the power state machine driven by the controlword (0x6040),
 *        its statusword (0x6041), and the demand torque of the cyclic synchronous modes (CST 10, CSV 9 with
 *        a PI velocity loop, CSP 8 with a P position loop around it; the torque offset 0x60B2 is added to the
 *        demand in each of them). Targets act only in "operation
 *        enabled"; in every other state the demand is 0 (quick stop active: the velocity loop brings the
 *        motor to rest).
 *
 * Units on the bus: torque in per mille of the rated torque 0x6076 (itself in mN m); velocity in mrad/s;
 * position in urad (wrapping as INTEGER32).
 */
#ifndef MSID_SIM_CO402_H
#define MSID_SIM_CO402_H

#include <stdint.h>

#include "msid_daq/msid_co_402.h"

/** Bus unit of velocity, rad/s. */
#define SIM_CO402_VEL_UNIT 1e-3
/** Bus unit of position, rad. */
#define SIM_CO402_POS_UNIT 1e-6

/** @brief A motor angle (rad) as 0x6064 shows it: urad, rounded, wrapping modulo 2^32 as INTEGER32. */
int32_t sim_co402_pos_to_bus(double theta);

/** @brief A motor velocity (rad/s) as 0x606C shows it: mrad/s, rounded, saturated to INTEGER32. */
int32_t sim_co402_vel_to_bus(double omega);

/** Loop gains and limits. */
typedef struct sim_co402_gains {
    double kp;          /**< velocity loop proportional gain, N m s / rad, >= 0 */
    double ki;          /**< velocity loop integral gain, N m / rad, >= 0 */
    double kpp;         /**< position loop gain, 1/s, >= 0 */
    double max_pm;      /**< torque limit, per mille of rated, > 0 */
} sim_co402_gains;

/** The drive (caller-owned). */
typedef struct sim_co402 {
    msid_co402_state state;
    uint16_t controlword;   /**< the last controlword taken (its bit 7 edge resets a fault) */
    sim_co402_gains g;
    double integ;           /**< velocity loop integrator, N m */
} sim_co402;

/** @brief Gains for the default mechanics (sim_twomass_default) at a SYNC period of ts s (> 0): a 20 Hz
 *         velocity loop where 2 pi 20 Hz ts <= 0.2, else its crossover at 0.2 / ts rad/s (stable and well
 *         damped down to a 20 Hz SYNC, see the poles in sim_co402.c); the integral corner and the position
 *         loop at a quarter of the crossover; limit 3000 per mille. */
sim_co402_gains sim_co402_gains_for(double ts);

/** @brief sim_co402_gains_for(1e-3): a 20 Hz velocity loop, a 5 Hz position loop (a 1 kHz SYNC). */
sim_co402_gains sim_co402_default_gains(void);

/** @brief Power on: "switch on disabled" (the "not ready" state passes at once). */
void sim_co402_init(sim_co402 *d, const sim_co402_gains *g);

/** @brief Take a controlword (CiA 402 transitions 2..16; a fault reset on the rising edge of bit 7). */
void sim_co402_controlword(sim_co402 *d, uint16_t cw);

/** @brief A fault: to "fault" (through "fault reaction active", which passes at once). */
void sim_co402_fault(sim_co402 *d);

/** @brief The statusword of the state (bit 4 voltage enabled and bit 9 remote always set). */
uint16_t sim_co402_statusword(const sim_co402 *d);

/** Targets and feedback of one SYNC, in bus units. */
typedef struct sim_co402_io {
    int8_t mode;            /**< 0x6061 */
    int16_t target_torque;  /**< 0x6071, per mille */
    int32_t target_vel;     /**< 0x60FF, mrad/s */
    int32_t target_pos;     /**< 0x607A, urad */
    int16_t torque_offset;  /**< 0x60B2, per mille: added to the demand in CST, CSV and CSP (CiA 402's torque
                                 offset; in CSV it is where a torque-loop measurement injects its excitation) */
    uint32_t rated_mnm;     /**< 0x6076, mN m (0 taken as 1) */
    double omega;           /**< motor velocity, rad/s */
    double theta;           /**< motor position, rad */
    double ts;              /**< SYNC period, s */
} sim_co402_io;

/**
 * @brief The demand of this SYNC: tau in N m, *demand_pm (0x6074) the same in per mille of rated, rounded;
 *        tau is *demand_pm's value, so what the bus shows is what drives the plant.
 */
double sim_co402_demand(sim_co402 *d, const sim_co402_io *io, int16_t *demand_pm);

#endif
