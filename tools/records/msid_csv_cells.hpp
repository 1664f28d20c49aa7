// The CSV reader's vector path: the two primitives that read 16 or 64 bytes at once, for x86-64
// (SSE2/SSSE3), AArch64 (Advanced SIMD) and 32-bit ARM with NEON, and nothing else. Every vector
// intrinsic of the CSV reader is in this file, behind MSID_CSV_CELLS; without it (another CPU), or
// when available() says the CPU lacks the extension, the reader takes its scalar path, which gives the
// same values and errors bit for bit (tests/unit/test_csv_rows.cpp, test_csv_decimal.cpp run both on
// every architecture).
//
// armhf: Debian's baseline (ARMv7-A, VFPv3-D16) has no NEON, but nearly every board that runs it does
// (a Raspberry Pi 2-5 on a 32-bit OS, BeagleBone, i.MX 6). The functions here are compiled for NEON
// by attribute and taken only when the kernel reports it (AT_HWCAP), so one armhf binary serves both.
// ARMv7's NEON has 64-bit table look-ups and pairwise adds only: the two places that differ from
// AArch64 take each 16-byte register as two halves.
//
// parse_cell: Clinger's fast path (msid_decimal.hpp) for a cell whose extent is already known (the
// reader finds every delimiter first, with hit_mask64), for the one shape a data file repeats
// (-?D+.D+, 2..15 digits): the 16 bytes that end at the cell are taken in one register, checked (one
// '.', the rest digits), the dot squeezed out by a byte shuffle and the digits summed by
// multiply-adds into the exact integer m < 10^15. The value is then the one IEEE division m / 10^f of
// the scalar path, so the bits are the same on every CPU. No branch depends on the digits, so cells
// are parsed independently of each other.
#pragma once
#include "msid_decimal.hpp"

#include <cstddef>
#include <cstdint>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <tmmintrin.h>
#define MSID_CSV_CELLS 1
/// Functions that inline parse_cell or hit_mask64 carry this attribute (SSSE3 is checked at run time).
#define MSID_CELLS_TARGET __attribute__((target("ssse3")))
#elif defined(__aarch64__) && defined(__ARM_NEON) && (defined(__GNUC__) || defined(__clang__))
#include <arm_neon.h>
#define MSID_CSV_CELLS 1
#define MSID_CELLS_TARGET   // Advanced SIMD is part of every AArch64 CPU
#elif defined(__arm__) && defined(__linux__) && defined(__GNUC__) && !defined(__clang__) && defined(__ARM_FP)
#include <arm_neon.h>
#include <sys/auxv.h>
#define MSID_CSV_CELLS 1
#define MSID_CSV_CELLS_ARM32 1
/// NEON is checked at run time (AT_HWCAP): the armhf baseline does not have it.
#define MSID_CELLS_TARGET __attribute__((target("fpu=neon")))
#endif

#ifdef MSID_CSV_CELLS
namespace msidrec {
namespace cells {

/// Can the vector path run on this CPU? x86-64: SSSE3 (every CPU since about 2008), checked once;
/// 32-bit ARM: NEON, as the kernel reports it; AArch64: always.
inline bool available()
{
#if defined(__x86_64__)
    static const bool ok = __builtin_cpu_supports("ssse3");
    return ok;
#elif defined(MSID_CSV_CELLS_ARM32)
    static const bool ok = (getauxval(AT_HWCAP) & HWCAP_ARM_NEON) != 0;
    return ok;
#else
    return true;
#endif
}

/// parse_cell's tables: shuf[j] moves bytes 0..j-1 up one byte over a '.' at byte j (byte 0
/// zeroed: index 0x80 reads as 0 in both pshufb and tbl); keep[n] keeps the last n bytes of 16.
struct CellTables {
    alignas(16) uint8_t shuf[16][16];
    alignas(16) uint8_t keep[17][16];
    constexpr CellTables() : shuf(), keep()
    {
        for (int j = 0; j < 16; ++j)
            for (int b = 0; b < 16; ++b) shuf[j][b] = (uint8_t)(b > j ? b : (b == 0 ? 0x80 : b - 1));
        for (int n = 0; n <= 16; ++n)
            for (int b = 0; b < 16; ++b) keep[n][b] = b >= 16 - n ? 0xFF : 0;
    }
};
inline constexpr CellTables CELL_TABLES{};

/**
 * @brief The cell [s, s + len) as a number when it is exactly an optional '-',
 *        k >= 1 digits, '.', f >= 1 digits with k + f <= 15 (Clinger's fast
 *        path: m / 10^f, m < 10^15, correctly rounded, the bits of
 *        decimal::parse()). Call only when available(), from a function
 *        marked MSID_CELLS_TARGET.
 * @param s    first byte of the cell
 * @param len  its length in bytes (the delimiter excluded)
 * @param v    the value (written on success only)
 * @param point the decimal separator: '.' or ',' (a decimal comma, "0,25")
 * @return false when the cell has another shape (an exponent, '+', spaces,
 *         more digits, no dot, empty, ...): parse it with decimal::parse()
 * @note Reads the 16 bytes that end at s + len (from s + len - 16): the caller
 *       ensures they are readable.
 */
MSID_CELLS_TARGET inline bool parse_cell(const char *s, size_t len, double &v, char point = '.')
{
    const bool neg = len && *s == '-';
    len -= neg;   // s + len: the end of the cell either way
    if (len - 3 > 13) return false;   // 3..16 bytes: D.D to 15 digits and the dot
    const char *e = s + neg + len;
    uint64_t hi8, lo8;   // the first and the last 8 of the 16 digits (the bytes before the number read as 0)
    unsigned dp;         // the byte of the one non-digit (the dot), 16 if none
#if defined(__x86_64__)
    const __m128i raw = _mm_loadu_si128((const __m128i *)(const void *)(e - 16));
    const __m128i d = _mm_and_si128(_mm_sub_epi8(raw, _mm_set1_epi8('0')),
                                    _mm_load_si128((const __m128i *)(const void *)CELL_TABLES.keep[len]));
    const unsigned nd =
        ~(unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_min_epu8(d, _mm_set1_epi8(9)), d)) & 0xFFFFu;
    dp = (unsigned)__builtin_ctz(nd | 0x10000u);
    if ((nd & (nd - 1)) != 0 || dp >= 15 || dp <= 16 - len || e[(int)dp - 16] != point) return false;
    const __m128i x = _mm_shuffle_epi8(d, _mm_load_si128((const __m128i *)(const void *)CELL_TABLES.shuf[dp]));
    // 16 digits -> 8 of 2 -> 4 of 4 -> 2 of 8 (the first 8 in the low lane)
    const __m128i p2 = _mm_maddubs_epi16(x, _mm_setr_epi8(10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1));
    const __m128i p4 = _mm_madd_epi16(p2, _mm_setr_epi16(100, 1, 100, 1, 100, 1, 100, 1));
    const __m128i p8 = _mm_madd_epi16(_mm_packs_epi32(p4, p4), _mm_setr_epi16(10000, 1, 10000, 1, 10000, 1, 10000, 1));
    const uint64_t q = (uint64_t)_mm_cvtsi128_si64(p8);
    hi8 = q & 0xFFFFFFFFu;
    lo8 = q >> 32;
#else
    const uint8x16_t raw = vld1q_u8((const uint8_t *)(const void *)(e - 16));
    const uint8x16_t d = vandq_u8(vsubq_u8(raw, vdupq_n_u8('0')), vld1q_u8(CELL_TABLES.keep[len]));
    // bit 4i set for a byte i that is no digit (the narrowing shift keeps a nibble of each byte)
    const uint8x16_t bad = vcgtq_u8(d, vdupq_n_u8(9));
    const uint64_t nd =
        vget_lane_u64(vreinterpret_u64_u8(vshrn_n_u16(vreinterpretq_u16_u8(bad), 4)), 0) & 0x1111111111111111ull;
    dp = nd ? (unsigned)__builtin_ctzll(nd) / 4u : 16u;
    if ((nd & (nd - 1)) != 0 || dp >= 15 || dp <= 16 - len || e[(int)dp - 16] != point) return false;
#if defined(MSID_CSV_CELLS_ARM32)
    const uint8x8x2_t dd = {{vget_low_u8(d), vget_high_u8(d)}};
    const uint8x16_t ix = vld1q_u8(CELL_TABLES.shuf[dp]);
    const uint8x16_t x = vcombine_u8(vtbl2_u8(dd, vget_low_u8(ix)), vtbl2_u8(dd, vget_high_u8(ix)));
#else
    const uint8x16_t x = vqtbl1q_u8(d, vld1q_u8(CELL_TABLES.shuf[dp]));
#endif
    // 16 digits -> 8 of 2 -> 4 of 4 -> 2 of 8, each lane (high part) + 10^k (low part): little-endian
    // lanes hold the earlier, more significant digits in their low part
    const uint16x8_t w2 = vreinterpretq_u16_u8(x);
    const uint16x8_t p2 = vmlaq_n_u16(vshrq_n_u16(w2, 8), vandq_u16(w2, vdupq_n_u16(0xFF)), 10);
    const uint32x4_t w4 = vreinterpretq_u32_u16(p2);
    const uint32x4_t p4 = vmlaq_n_u32(vshrq_n_u32(w4, 16), vandq_u32(w4, vdupq_n_u32(0xFFFF)), 100);
    const uint64x2_t w8 = vreinterpretq_u64_u32(p4);
    const uint64_t a = vgetq_lane_u64(w8, 0), b = vgetq_lane_u64(w8, 1);
    hi8 = (a & 0xFFFFFFFFu) * 10000u + (a >> 32);
    lo8 = (b & 0xFFFFFFFFu) * 10000u + (b >> 32);
#endif
    const uint64_t m = hi8 * 100000000ull + lo8;
    const double r = (double)m / decimal::POW10[15 - dp];   // f = 15 - dp fraction digits
    v = neg ? -r : r;
    return true;
}

/// Bit i set when byte p[i] (i < 64) is `d`, '\n' or '\r': the structural characters of 64 bytes.
MSID_CELLS_TARGET inline uint64_t hit_mask64(const char *p, char d)
{
#if defined(__x86_64__)
    const __m128i vd = _mm_set1_epi8(d), vn = _mm_set1_epi8('\n'), vr = _mm_set1_epi8('\r');
    uint64_t m = 0;
    for (int k = 0; k < 4; ++k) {
        const __m128i v = _mm_loadu_si128((const __m128i *)(const void *)(p + 16 * k));
        const __m128i h =
            _mm_or_si128(_mm_or_si128(_mm_cmpeq_epi8(v, vd), _mm_cmpeq_epi8(v, vn)), _mm_cmpeq_epi8(v, vr));
        m |= (uint64_t)(uint16_t)_mm_movemask_epi8(h) << (16 * k);
    }
    return m;
#else
    // each hit byte keeps the weight 2^(i mod 8) of its place; three pairwise additions sum the
    // weights of eight bytes into one, byte j of the result for bytes 8j .. 8j+7
    static const uint8_t W[16] = {1, 2, 4, 8, 16, 32, 64, 128, 1, 2, 4, 8, 16, 32, 64, 128};
    const uint8x16_t vd = vdupq_n_u8((uint8_t)d), vn = vdupq_n_u8('\n'), vr = vdupq_n_u8('\r'), w = vld1q_u8(W);
    uint8x16_t h[4];
    for (int k = 0; k < 4; ++k) {
        const uint8x16_t v = vld1q_u8((const uint8_t *)(const void *)(p + 16 * k));
        h[k] = vandq_u8(vorrq_u8(vorrq_u8(vceqq_u8(v, vd), vceqq_u8(v, vn)), vceqq_u8(v, vr)), w);
    }
#if defined(MSID_CSV_CELLS_ARM32)
    uint8x8_t a[4];
    for (int k = 0; k < 4; ++k) a[k] = vpadd_u8(vget_low_u8(h[k]), vget_high_u8(h[k]));
    const uint8x8_t s = vpadd_u8(vpadd_u8(a[0], a[1]), vpadd_u8(a[2], a[3]));
    return vget_lane_u64(vreinterpret_u64_u8(s), 0);
#else
    uint8x16_t s = vpaddq_u8(vpaddq_u8(h[0], h[1]), vpaddq_u8(h[2], h[3]));
    s = vpaddq_u8(s, s);
    return vgetq_lane_u64(vreinterpretq_u64_u8(s), 0);
#endif
#endif
}

}  // namespace cells
}  // namespace msidrec
#endif
