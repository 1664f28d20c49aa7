/**
 * @file msid_rng.h
 * @brief Seeded pseudo-random numbers, bit-identical on every platform.
 *
 * xoshiro256** (Blackman & Vigna) seeded by splitmix64. Integer arithmetic
 * only for ::msid_rng_u64 and ::msid_rng_uniform; ::msid_rng_normal uses the
 * Marsaglia polar method with the deterministic ::msid_log and IEEE sqrt.
 * The state is a plain value struct: it needs no working memory.
 */
#ifndef MSID_RNG_H
#define MSID_RNG_H

#include "msid_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Generator state. Copy it to fork a stream. */
typedef struct msid_rng {
    uint64_t s[4];     /**< xoshiro256** state */
    double spare;      /**< cached second normal deviate */
    int has_spare;     /**< 1 if `spare` is valid */
} msid_rng;

/**
 * @brief Seed the generator. Every seed, including 0, gives a valid state.
 * @param r state to initialise
 * @param seed any 64-bit value
 */
void msid_rng_seed(msid_rng *r, uint64_t seed);

/** @brief Next 64 uniformly distributed bits. */
uint64_t msid_rng_u64(msid_rng *r);

/** @brief Uniform double in [0, 1) with 53 random bits. */
double msid_rng_uniform(msid_rng *r);

/** @brief Standard normal deviate N(0, 1). */
double msid_rng_normal(msid_rng *r);

#ifdef __cplusplus
}
#endif
#endif
