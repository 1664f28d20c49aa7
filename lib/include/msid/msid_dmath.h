/**
 * @file msid_dmath.h
 * @brief Deterministic elementary functions built from IEEE-754 +,-,*,/ only.
 *
 * libm's cos/sin/log may differ by an ulp between platforms. Every value that
 * must be bit-reproducible across platforms (twiddle tables, generated
 * excitation samples, random phases, simulated noise) goes through these
 * functions instead. The library is compiled with -ffp-contract=off so the
 * compiler cannot fuse operations differently on different targets.
 * Accuracy: better than 2 ulp in the ranges stated.
 */
#ifndef MSID_DMATH_H
#define MSID_DMATH_H

#include "msid_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * @brief cos and sin of a whole-turn angle: c = cos(2*pi*t), s = sin(2*pi*t).
 * @param t angle in turns (1 turn = 2*pi rad); any finite value with |t| < 2^52.
 *          Multiples of 1/8 turn give exact results (e.g. t = 0.25 gives c = 0, s = 1).
 * @param c output cosine (may be NULL)
 * @param s output sine (may be NULL)
 */
void msid_cis_turns(double t, double *c, double *s);

/**
 * @brief Natural logarithm, deterministic.
 * @param x argument, finite and > 0. Non-positive arguments return -inf (x == 0) or NaN.
 * @return ln(x)
 */
double msid_log(double x);

/**
 * @brief Square root. IEEE-754 sqrt is correctly rounded, hence deterministic.
 */
double msid_sqrt(double x);

#ifdef __cplusplus
}
#endif
#endif
