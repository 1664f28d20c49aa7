/**
 * @file msid_types.h
 * @brief Basic types, limits and memory alignment shared by every msid object.
 *
 * msid objects follow one pattern (CMSIS-DSP / kissfft style):
 *  - the caller owns the instance struct (`msid_<obj>`), usually on the stack
 *    or in static storage;
 *  - `msid_<obj>_mem_size(&cfg)` returns the bytes of working memory needed;
 *  - `msid_<obj>_init(&obj, &cfg, mem, len)` places all state in `mem`, which
 *    must be aligned to ::MSID_MEM_ALIGN bytes and at least that long.
 * Nothing in the core library allocates, prints or touches errno.
 */
#ifndef MSID_TYPES_H
#define MSID_TYPES_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Complex double, stored as (re, im). Arrays of it are interleaved doubles. */
typedef struct msid_cplx {
    double re; /**< real part */
    double im; /**< imaginary part */
} msid_cplx;

/** Required alignment of every `mem` block passed to an `_init`, in bytes. */
#define MSID_MEM_ALIGN 64u

/** Largest number of inputs (nu). */
#define MSID_MAX_INPUTS 16u
/** Largest number of outputs (ny). */
#define MSID_MAX_OUTPUTS 16u
/** Largest number of channels in one sample row (nu + ny). */
#define MSID_MAX_CHANNELS (MSID_MAX_INPUTS + MSID_MAX_OUTPUTS)
/** Largest number of experiments (m). */
#define MSID_MAX_EXPERIMENTS 64u
/** Largest period, in samples. */
#define MSID_MAX_PERIOD (1u << 24)
/** Smallest period, in samples. */
#define MSID_MIN_PERIOD 2u
/** Amplitudes of a design's lines lie in [MSID_MIN_AMPLITUDE, MSID_MAX_AMPLITUDE] (in the input's units).
 *  The design squares them (input matrices, condition numbers, crest factors): A^2 stays within double
 *  precision's normal range for A in [1e-150, 1e150]. Beyond it the design's own arithmetic overflows and an
 *  amplitude of 1e308 was reported as a singular input matrix. (A record's magnitudes are checked again where
 *  the FRF squares its spectra: MSID_E_RANGE.) */
#define MSID_MAX_AMPLITUDE 1e150
#define MSID_MIN_AMPLITUDE 1e-150

#ifdef __cplusplus
}
#endif
#endif
