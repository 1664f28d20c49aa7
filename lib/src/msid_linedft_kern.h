/* The vector kernel of the streaming line DFT (msid_linedft.c), in msid_linedft_vec.c, the one file with
 * intrinsics: SSE2 on x86-64 and Advanced SIMD on AArch64 (both in the base instruction set).
 * Elsewhere (32-bit ARM, whose NEON has no double lanes; Cortex-M; any build with MSID_NO_SIMD) the
 * scalar kernels of msid_linedft.c run. Each accumulator adds its terms v*w with one multiply and one
 * add in sample order, as the scalar kernels do (lib/ is built with -ffp-contract=off): the same bits
 * on every path, which tests/unit (test_linedft, test_linedft_scalar) check. */
#ifndef MSID_LINEDFT_KERN_H
#define MSID_LINEDFT_KERN_H
#include <stdint.h>

#include "msid/msid_types.h"

#if !defined(MSID_NO_SIMD) && defined(__SSE2__)
#define MSID_LINEDFT_SSE2 1
#define MSID_LINEDFT_VEC 1
#elif !defined(MSID_NO_SIMD) && defined(__aarch64__) && defined(__ARM_NEON)
#define MSID_LINEDFT_NEON 1
#define MSID_LINEDFT_VEC 1
#endif

/* Twiddle index i advanced by bin k modulo the period P (i, k < P). */
static inline uint32_t msid__ldft_step(uint32_t i, uint32_t k, uint32_t P)
{
    i += k;
    return i >= P ? i - P : i;
}

#ifdef MSID_LINEDFT_VEC
/**
 * Four lines, the channel pairs: for l < 4 and c < (C & ~1),
 * acc[l*C + c] += sum over s < ns of x[s*C + c] * w[(idx[l] + s*k[l]) mod P], in sample order.
 * w: the twiddle table (P entries, 16-byte aligned); acc: [4][C], 16-byte aligned; x: ns rows of C.
 * @return the channels done, C rounded down to even (the caller adds the odd last one).
 */
uint32_t msid__ldft_pairs4(const msid_cplx *w, uint32_t P, const uint32_t *k, const uint32_t *idx,
                           msid_cplx *acc, uint32_t C, const double *x, uint32_t ns);
#endif
#endif
