/* Private helpers shared by the core objects. Not installed. */
#ifndef MSID_INTERNAL_H
#define MSID_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include "msid/msid_types.h"
#include "msid/msid_status.h"

/* A static helper that must be inlined into each caller (the per-sample push
 * paths: a call with its argument dispatch costs tens of instructions per
 * sample on a Cortex-M). */
#if defined(__GNUC__)
#define MSID__ALWAYS_INLINE static inline __attribute__((always_inline))
#else
#define MSID__ALWAYS_INLINE static inline
#endif

/* Round a byte count up to the memory alignment. */
static inline size_t msid__round(size_t n)
{
    return (n + (MSID_MEM_ALIGN - 1u)) & ~(size_t)(MSID_MEM_ALIGN - 1u);
}

/* Caller memory handed to an _init: present, aligned, at least `need` bytes. */
static inline msid_status msid__mem_check(const void *mem, size_t len, size_t need)
{
    if (!mem) return MSID_E_NULL;
    if (((uintptr_t)mem & (MSID_MEM_ALIGN - 1u)) != 0u) return MSID_E_MEM_ALIGN;
    if (len < need) return MSID_E_MEM_SIZE;
    return MSID_OK;
}

static inline int msid__finite(double x)
{
    /* x - x is 0 for finite x and NaN otherwise; no libm needed. */
    return (x - x) == 0.0;
}

static inline int msid__is_pow2(uint32_t x) { return x && !(x & (x - 1u)); }

/* Saturating size arithmetic for _mem_size: returns SIZE_MAX on overflow. */
static inline size_t msid__mul(size_t a, size_t b)
{
    if (a && b > SIZE_MAX / a) return SIZE_MAX;
    return a * b;
}
static inline size_t msid__add(size_t a, size_t b)
{
    return (a > SIZE_MAX - b) ? SIZE_MAX : a + b;
}
/* Rounded chunk of n elements of size sz. */
static inline size_t msid__chunk(size_t n, size_t sz)
{
    size_t b = msid__mul(n, sz);
    return b == SIZE_MAX ? SIZE_MAX : msid__round(b);
}

/* Memory layout of an object. Each object has ONE layout routine that walks
 * its chunks in order with msid__lay; _mem_size runs it without memory (base
 * NULL: only the rounded sizes are summed, saturating at SIZE_MAX) and _init
 * runs it on the caller's block (after msid__mem_check against _mem_size) to
 * place the chunks, so the size and the placement cannot drift apart. */
typedef struct msid__layout {
    unsigned char *base;   /* caller memory, or NULL to size only */
    size_t size;           /* bytes laid out so far (each chunk rounded to MSID_MEM_ALIGN) */
} msid__layout;

static inline msid__layout msid__layout_begin(void *base)
{
    msid__layout y;
    y.base = (unsigned char *)base;
    y.size = 0;
    return y;
}

/* Next chunk of n elements of sz bytes: its address (NULL when only sizing).
 * Out of line (msid_layout.c): the saturating size arithmetic is the same for
 * every chunk, and one copy keeps the layout routines small in flash. */
void *msid__lay(msid__layout *y, size_t n, size_t sz);

/* In-place heapsort of n uint32 values (no recursion, no allocation). */
static inline void msid__sift(uint32_t *a, size_t i, size_t n)
{
    for (;;) {
        size_t c = 2u * i + 1u;
        if (c >= n) return;
        if (c + 1u < n && a[c + 1u] > a[c]) ++c;
        if (a[i] >= a[c]) return;
        uint32_t t = a[i]; a[i] = a[c]; a[c] = t;
        i = c;
    }
}
static inline void msid__sort_u32(uint32_t *a, size_t n)
{
    if (n < 2u) return;
    for (size_t i = n / 2u; i-- > 0u;) msid__sift(a, i, n);
    for (size_t e = n - 1u; e > 0u; --e) {
        uint32_t t = a[0]; a[0] = a[e]; a[e] = t;
        msid__sift(a, 0, e);
    }
}

#endif
