/**
 * @file sim_twomass.h
 * @brief The simulated drive's mechanics: a motor and a load coupled by an elastic shaft (one lightly damped
 *        mode), discretized exactly for a zero-order-hold torque over one SYNC period.
 *
 * Continuous model (SI units), state x = [theta_m, omega_m, theta_l, omega_l] (rad, rad/s), input the motor
 * torque tau (N m):
 *
 *     J_m domega_m/dt = tau - k (theta_m - theta_l) - d (omega_m - omega_l) - b_m omega_m
 *     J_l domega_l/dt =       k (theta_m - theta_l) + d (omega_m - omega_l) - b_l omega_l
 *
 * Its discrete step over T (the SYNC period, s) is x[k+1] = A x[k] + B tau[k] with A = e^(F T),
 * B = int_0^T e^(F s) ds G (F, G the continuous matrices), computed once at init; sim_twomass_step is that
 * linear map and nothing else, so the exact FRF from tau to any state at z = e^(j w T) is
 * e_i' (z I - A)^-1 B (a test reads A and B from the struct). The antiresonance is at sqrt(k / J_l) rad/s,
 * the resonance at sqrt(k (J_m + J_l) / (J_m J_l)).
 */
#ifndef MSID_SIM_TWOMASS_H
#define MSID_SIM_TWOMASS_H

/** Mechanical parameters (SI). */
typedef struct sim_twomass_par {
    double jm;   /**< motor inertia, kg m^2, > 0 */
    double jl;   /**< load inertia, kg m^2, > 0 */
    double k;    /**< shaft stiffness, N m / rad, >= 0 */
    double d;    /**< shaft damping, N m s / rad, >= 0 */
    double bm;   /**< motor viscous friction, N m s / rad, >= 0 */
    double bl;   /**< load viscous friction, N m s / rad, >= 0 */
} sim_twomass_par;

/** The discrete plant (caller-owned). */
typedef struct sim_twomass {
    sim_twomass_par p;
    double ts;         /**< step, s */
    double a[4][4];    /**< A = e^(F ts) */
    double b[4];       /**< B */
    double x[4];       /**< theta_m, omega_m, theta_l, omega_l */
} sim_twomass;

/** @brief msid-devsim's default mechanics: Jm 1e-4, Jl 2e-4 kg m^2, k 50 N m/rad, d 2e-3 N m s/rad, bm 1e-4,
 *         bl 1e-4 N m s/rad (resonance 138 Hz, damping ratio about 0.017; antiresonance 80 Hz). */
sim_twomass_par sim_twomass_default(void);

/** @brief Discretize for step ts (s, > 0) and zero the state. @return 0, or -1 for parameters out of range. */
int sim_twomass_init(sim_twomass *m, const sim_twomass_par *p, double ts);

/** @brief One step: x <- A x + B tau (tau in N m, held over the step). */
void sim_twomass_step(sim_twomass *m, double tau);

#endif
