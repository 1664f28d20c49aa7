/* The streaming line DFT's four-line vector kernel (contract: msid_linedft_kern.h), the only file of
 * lib/ with intrinsics. One 128-bit register holds one accumulator's (re, im), so a channel pair's eight
 * accumulators stay in registers and each twiddle load serves two channels. The same kernel for
 * two instruction sets through a few operations:
 *   SSE2 (x86-64 baseline)              _mm_load_pd / _mm_set1_pd / _mm_mul_pd / _mm_add_pd
 *   Advanced SIMD (AArch64 baseline)    vld1q_f64 / vld1q_dup_f64 / vmulq_f64 / vaddq_f64
 * Multiply, then add, never a fused multiply-add: the product is rounded before the sum, as in the
 * scalar kernels (lib/ is built with -ffp-contract=off, so the compiler fuses nothing either).
 * Compiled to nothing where neither applies (32-bit ARM's NEON has no double lanes) or with MSID_NO_SIMD. */
#include "msid_linedft_kern.h"

#if defined(MSID_LINEDFT_SSE2)
#include <emmintrin.h>
typedef __m128d msid__v2;
#define V_LOAD(p) _mm_load_pd(p)            /* 16-byte aligned (msid__layout, the twiddle table) */
#define V_STORE(p, v) _mm_store_pd((p), (v))
#define V_DUP(p) _mm_set1_pd(*(p))
#define V_MULADD(a, x, t) _mm_add_pd((a), _mm_mul_pd((x), (t)))
#elif defined(MSID_LINEDFT_NEON)
#include <arm_neon.h>
typedef float64x2_t msid__v2;
#define V_LOAD(p) vld1q_f64(p)
#define V_STORE(p, v) vst1q_f64((p), (v))
#define V_DUP(p) vld1q_dup_f64(p)
#define V_MULADD(a, x, t) vaddq_f64((a), vmulq_f64((x), (t)))
#endif

#ifdef MSID_LINEDFT_VEC
uint32_t msid__ldft_pairs4(const msid_cplx *w, uint32_t P, const uint32_t *k, const uint32_t *idx,
                           msid_cplx *acc, uint32_t C, const double *x, uint32_t ns)
{
    const uint32_t k0 = k[0], k1 = k[1], k2 = k[2], k3 = k[3];
    uint32_t c = 0;
    for (; c + 2u <= C; c += 2u) {
        uint32_t i0 = idx[0], i1 = idx[1], i2 = idx[2], i3 = idx[3];
        double *A = &acc[0].re;
        msid__v2 a00 = V_LOAD(A + 2 * (0 * C + c)), a01 = V_LOAD(A + 2 * (0 * C + c + 1));
        msid__v2 a10 = V_LOAD(A + 2 * (1 * C + c)), a11 = V_LOAD(A + 2 * (1 * C + c + 1));
        msid__v2 a20 = V_LOAD(A + 2 * (2 * C + c)), a21 = V_LOAD(A + 2 * (2 * C + c + 1));
        msid__v2 a30 = V_LOAD(A + 2 * (3 * C + c)), a31 = V_LOAD(A + 2 * (3 * C + c + 1));
        const double *row = x + c;
        for (uint32_t s = 0; s < ns; ++s, row += C) {
            const msid__v2 x0 = V_DUP(row), x1 = V_DUP(row + 1);
            const msid__v2 t0 = V_LOAD(&w[i0].re), t1 = V_LOAD(&w[i1].re);
            const msid__v2 t2 = V_LOAD(&w[i2].re), t3 = V_LOAD(&w[i3].re);
            a00 = V_MULADD(a00, x0, t0); a01 = V_MULADD(a01, x1, t0);
            a10 = V_MULADD(a10, x0, t1); a11 = V_MULADD(a11, x1, t1);
            a20 = V_MULADD(a20, x0, t2); a21 = V_MULADD(a21, x1, t2);
            a30 = V_MULADD(a30, x0, t3); a31 = V_MULADD(a31, x1, t3);
            i0 = msid__ldft_step(i0, k0, P); i1 = msid__ldft_step(i1, k1, P);
            i2 = msid__ldft_step(i2, k2, P); i3 = msid__ldft_step(i3, k3, P);
        }
        V_STORE(A + 2 * (0 * C + c), a00); V_STORE(A + 2 * (0 * C + c + 1), a01);
        V_STORE(A + 2 * (1 * C + c), a10); V_STORE(A + 2 * (1 * C + c + 1), a11);
        V_STORE(A + 2 * (2 * C + c), a20); V_STORE(A + 2 * (2 * C + c + 1), a21);
        V_STORE(A + 2 * (3 * C + c), a30); V_STORE(A + 2 * (3 * C + c + 1), a31);
    }
    return c;
}
#else
typedef int msid__linedft_vec_unused;   /* ISO C: a translation unit declares something */
#endif
