/* Shared helpers of the libFuzzer harnesses: a byte reader over the fuzz input and aligned memory. */
#ifndef MSID_FUZZ_UTIL_H
#define MSID_FUZZ_UTIL_H
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct { const uint8_t *p; size_t n; } fz;

static inline uint32_t fz_u8(fz *f) { if (!f->n) return 0; f->n--; return *f->p++; }
static inline uint32_t fz_u16(fz *f) { const uint32_t a = fz_u8(f); return a | fz_u8(f) << 8; }
static inline uint32_t fz_u32(fz *f) { const uint32_t a = fz_u16(f); return a | fz_u16(f) << 16; }
static inline double fz_f64(fz *f)
{
    uint64_t v = fz_u32(f);
    v |= (uint64_t)fz_u32(f) << 32;
    double d;
    memcpy(&d, &v, sizeof d);
    return d;
}
static inline void fz_bytes(fz *f, void *dst, size_t n)
{
    const size_t k = n < f->n ? n : f->n;
    memcpy(dst, f->p, k);
    memset((uint8_t *)dst + k, 0, n - k);
    f->p += k; f->n -= k;
}
/* 64-byte aligned memory of n bytes (n may be 0); NULL above the harness's memory cap. */
#define FZ_MEM_CAP ((size_t)64 << 20)
static inline void *fz_alloc(size_t n)
{
    if (n > FZ_MEM_CAP) return NULL;
    return aligned_alloc(64, (n + 63) / 64 * 64 + 64);
}
/* A twiddle table of period P in memory of its own (free() it); aborts if the core refuses it. */
#include "msid/msid_twiddle.h"
static inline void *fz_twiddle(uint32_t P, msid_twiddle *tw)
{
    const size_t n = msid_twiddle_mem_size(P);
    void *m = fz_alloc(n);
    if (!m || msid_twiddle_init(tw, P, m, n) != MSID_OK) abort();
    return m;
}
#endif
