/* Fixed, stable test plants shared by the FRF / determinism tests. */
#ifndef MSID_UNIT_PLANTS_H
#define MSID_UNIT_PLANTS_H

#include "msid/msid.h"

/* SISO, poles 0.6 +- 0.37j (|p| = 0.707), a zero, direct feed-through. */
static const double UP_SISO_A[4] = {1.2, -0.5, 1.0, 0.0};
static const double UP_SISO_B[2] = {1.0, 0.0};
static const double UP_SISO_C[2] = {0.3, 0.2};
static const double UP_SISO_D[1] = {0.1};
static inline msid_plant_cfg up_siso(void)
{
    msid_plant_cfg c = {2, 1, 1, UP_SISO_A, UP_SISO_B, UP_SISO_C, UP_SISO_D};
    return c;
}

/* 2x2 with 4 states (|poles| <= 0.71), cross-coupled through B, C and D. */
static const double UP_MIMO_A[16] = {1.2, -0.5, 0.0, 0.0,
                                     1.0, 0.0, 0.0, 0.0,
                                     0.0, 0.0, 0.5, 0.3,
                                     0.0, 0.0, -0.3, 0.5};
static const double UP_MIMO_B[8] = {1.0, 0.0, 0.0, 0.0, 0.5, 1.0, 0.0, 0.2};
static const double UP_MIMO_C[8] = {0.3, 0.2, 1.0, 0.0, 0.0, 1.0, 0.4, -0.5};
static const double UP_MIMO_D[4] = {0.1, 0.0, 0.05, -0.2};
static inline msid_plant_cfg up_mimo(void)
{
    msid_plant_cfg c = {4, 2, 2, UP_MIMO_A, UP_MIMO_B, UP_MIMO_C, UP_MIMO_D};
    return c;
}

#endif
