/**
 * @file sim_plant.h
 * @brief msid-devsim's simulated plant definitions: the built-in 2x2 plant, a
 *        small text file format and the exact frequency response. No device
 *        state: the device core (sim_device.c) owns the plant it loaded.
 */
#ifndef MSID_SIM_PLANT_H
#define MSID_SIM_PLANT_H

#include <stddef.h>
#include <stdint.h>
#include "msid/msid.h"

#define SIM_MAX_STATES 16u

/** The simulated plant: discrete-time state space stepped sample by sample,
 *  or a continuous-time system whose exact steady-state response to the
 *  multisine is evaluated at t = n h (valid for any h, also below Nyquist). */
typedef struct sim_plant_def {
    int ct;                          /**< 0: x(n+1) = A x + B u; 1: dx/dt = A x + B u */
    uint32_t n, nu, ny;              /**< states (<= SIM_MAX_STATES), inputs, outputs */
    double A[SIM_MAX_STATES * SIM_MAX_STATES], B[SIM_MAX_STATES * MSID_MAX_INPUTS];
    double C[MSID_MAX_OUTPUTS * SIM_MAX_STATES], D[MSID_MAX_OUTPUTS * MSID_MAX_INPUTS];
    double h;                        /**< CT plant with a DT design: sample time (s) */
} sim_plant_def;

/** @brief Parse a plant file; 0, or -1 with a message naming the problem in err. */
int sim_parse_plant(const char *path, sim_plant_def *p, char *err, size_t errlen);
/** @brief The built-in 4-state 2x2 DT plant (tests/integration/helpers.py dt_plant_2x2). */
void sim_builtin_plant(sim_plant_def *p);
/** @brief A built-in 4-state SISO DT plant: a lightly damped mode at 0.05 and one at 0.15 cycles per sample. */
void sim_builtin_siso_plant(sim_plant_def *p);
/** @brief G at line frequency: DT z = e^{j w}, w in rad/sample; CT s = j w, w in rad/s. G is ny x nu; 0 or -1 (singular). */
int sim_plant_response(const sim_plant_def *p, double w, msid_cplx *G);

#endif
