/**
 * @file msid_plant.h
 * @brief Discrete-time MIMO state-space system, for simulators and tests.
 *
 * x(n+1) = A x(n) + B u(n),  y(n) = C x(n) + D u(n).
 * Used by the built-in demo plant, the device simulators (firmware_sim/) and
 * the Monte Carlo tests, and as a noise-colouring filter. Fixed memory.
 */
#ifndef MSID_PLANT_H
#define MSID_PLANT_H

#include "msid_types.h"
#include "msid_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest state dimension. */
#define MSID_MAX_STATES 64u

/** Configuration: matrices row-major, copied at init. */
typedef struct msid_plant_cfg {
    uint32_t n_states;   /**< n in [0, MSID_MAX_STATES] (0: static gain D) */
    uint32_t n_inputs;   /**< nu in [1, MSID_MAX_CHANNELS] */
    uint32_t n_outputs;  /**< ny in [1, MSID_MAX_CHANNELS] */
    const double *A;     /**< n x n (may be NULL if n = 0) */
    const double *B;     /**< n x nu */
    const double *C;     /**< ny x n */
    const double *D;     /**< ny x nu, or NULL for zero */
} msid_plant_cfg;

/** Instance (caller-owned). */
typedef struct msid_plant {
    uint32_t n, nu, ny;
    double *A, *B, *C, *D, *x, *xn;
    msid_cplx *work;     /**< n*(n+nu) complex for ::msid_plant_frf */
} msid_plant;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_plant_mem_size(const msid_plant_cfg *cfg);

/** @brief Initialise with zero state. @return MSID_OK, MSID_E_NULL, MSID_E_DIMS, MSID_E_NOT_FINITE, MSID_E_MEM_*. */
msid_status msid_plant_init(msid_plant *p, const msid_plant_cfg *cfg, void *mem, size_t len);

/** @brief One step: y = C x + D u, then x = A x + B u. */
void msid_plant_step(msid_plant *p, const double *u, double *y);

/** @brief Set the state (n values) or zero it (x == NULL). */
void msid_plant_set_state(msid_plant *p, const double *x);

/**
 * @brief Frequency response G(z) = C (zI - A)^{-1} B + D at z = exp(j 2 pi f).
 * @param f frequency in cycles per sample
 * @param G output ny x nu, row-major
 * @return MSID_OK or MSID_E_SINGULAR (z is an eigenvalue of A).
 */
msid_status msid_plant_frf(msid_plant *p, double f, msid_cplx *G);

#ifdef __cplusplus
}
#endif
#endif
