// msid_decimal_parse: decimal text to double, correctly rounded (bit-identical
// to std::from_chars, which is the reference of tests/unit/test_csv_decimal.cpp).
//
// Two paths, both exact:
//  1. The fast path of Clinger (1990, "How to read floating point numbers
//     accurately", section 3): at most 15 significant digits (m < 10^15 <
//     2^53) with a decimal exponent e in [-22, 22]; m and 10^|e| are exact
//     doubles, so the one IEEE multiply or divide m * 10^e, m / 10^-e is the
//     correctly rounded value. Eight fraction digits at a time by SWAR.
//  2. Anything else: std::from_chars (correctly rounded; libstdc++ >= 12).
//
// parse_cell: the same fast path for a cell whose extent is already known (the
// CSV reader finds every delimiter first), for the one shape a data file
// repeats (-?D+.D+, 2..15 digits): the 16 bytes that end at the cell are taken
// in one SSSE3 register, checked (one '.', the rest digits), the dot squeezed
// out by a byte shuffle and the digits summed by multiply-adds. No branch
// depends on the digits, so cells are parsed independently of each other; the
// general parse above follows each cell's bytes one after the other.
#pragma once
#include <charconv>
#include <cstdint>
#include <cstring>
#include <system_error>
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <tmmintrin.h>
#endif

namespace msidrec {
namespace decimal {

/// Exact powers of ten 10^0 .. 10^22 (all exactly representable as doubles).
inline constexpr double POW10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                     1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/// Are the eight bytes of w (little-endian) all ASCII digits?
inline bool eight_digits(uint64_t w)
{
    return ((w & 0xF0F0F0F0F0F0F0F0ull) | (((w + 0x0606060606060606ull) & 0xF0F0F0F0F0F0F0F0ull) >> 4)) ==
           0x3333333333333333ull;
}

/// Value of eight digit values 0..9 (not ASCII) in w, the first (most significant) in the low byte.
inline uint64_t eight_value_bin(uint64_t w)
{
    w = (w * 10) + (w >> 8);
    w = (((w & 0x000000FF000000FFull) * 0x000F424000000064ull) +
         (((w >> 16) & 0x000000FF000000FFull) * 0x0000271000000001ull)) >> 32;
    return (uint32_t)w;
}

/// Value of eight ASCII digits in w, the first in the low byte.
inline uint64_t eight_value(uint64_t w) { return eight_value_bin(w - 0x3030303030303030ull); }

inline bool digit(char c) { return (unsigned)(c - '0') < 10u; }

/// The general path: std::from_chars (correctly rounded; inf/nan parse, the caller rejects them).
/// Out of line so the fast paths stay in registers.
__attribute__((noinline)) inline const char *parse_slow(const char *s, const char *end, double &v, bool &slow_path)
{
    slow_path = true;
    auto res = std::from_chars(s, end, v);
    return res.ec == std::errc() ? res.ptr : nullptr;
}

/// Path 2 (and 3): the scalar Clinger fast path, else std::from_chars. `p` at the sign or first digit.
inline const char *parse_scalar(const char *p, const char *end, double &v, bool &slow_path)
{
    const char *s = p;
    const bool neg = *p == '-';
    p += neg;
    uint64_t m = 0;
    const char *d0 = p;
    while (digit(*p)) m = m * 10 + (uint64_t)(*p++ - '0');
    size_t nd = (size_t)(p - d0);
    int e10 = 0;
    if (*p == '.') {
        const char *f0 = ++p;
        uint64_t w;
        if (p + 8 <= end && (std::memcpy(&w, p, 8), eight_digits(w)) && nd <= 7) {
            m = m * 100000000ull + eight_value(w);
            p += 8;
        }
        while (digit(*p)) m = m * 10 + (uint64_t)(*p++ - '0');
        e10 = -(int)(p - f0);
        nd += (size_t)(p - f0);
    }
    // at most 15 digits (leading zeros included): m < 10^15 < 2^53, exact
    if (nd == 0 || nd > 15) return parse_slow(s, end, v, slow_path);
    if ((*p | 0x20) == 'e') {
        const char *q = p + 1;
        const bool en = *q == '-';
        q += (*q == '-' || *q == '+');
        if (!digit(*q)) return parse_slow(s, end, v, slow_path);
        int x = 0;
        while (digit(*q) && x < 10000) x = x * 10 + (*q++ - '0');
        if (digit(*q)) return parse_slow(s, end, v, slow_path);
        e10 += en ? -x : x;
        p = q;
    }
    if (e10 < -22 || e10 > 22) return parse_slow(s, end, v, slow_path);
    const double d = (double)m;
    const double r = e10 < 0 ? d / POW10[-e10] : d * POW10[e10];
    v = neg ? -r : r;
    return p;
}

/**
 * @brief Parse one decimal number at p (an optional '-', digits, optional
 *        '.' and digits, optional exponent), correctly rounded.
 * @param p          first byte of the number (its sign or first digit); the
 *                   bytes up to `end` are readable and the text ends before
 *                   `end` in a byte that is no part of a number (a delimiter)
 * @param end        end of the readable bytes
 * @param v          the value (written on success)
 * @param slow_path  set when std::from_chars was needed (only then can v be
 *                   non-finite: "inf", "nan", 1e400)
 * @return the byte after the number, or nullptr if there is none at p
 */
inline const char *parse(const char *p, const char *end, double &v, bool &slow_path)
{
    return parse_scalar(p, end, v, slow_path);
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define MSID_DECIMAL_CELL 1

/// Can parse_cell run on this CPU (SSSE3; every x86-64 CPU since about 2008)? Checked once.
inline bool cell_available()
{
    static const bool ok = __builtin_cpu_supports("ssse3");
    return ok;
}

/// parse_cell's tables: shuf[j] moves bytes 0..j-1 up one byte over a '.' at byte j (byte 0
/// zeroed); keep[n] keeps the last n bytes of 16.
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
 *        path: m / 10^f, m < 10^15, correctly rounded, the bits of parse()).
 *        Call only when cell_available(); inline into a function compiled
 *        with __attribute__((target("ssse3"))).
 * @param s    first byte of the cell
 * @param len  its length in bytes (the delimiter excluded)
 * @param v    the value (written on success only)
 * @param point the decimal separator: '.' or ',' (a decimal comma, "0,25")
 * @return false when the cell has another shape (an exponent, '+', spaces,
 *         more digits, no dot, empty, ...): parse it with parse()
 * @note Reads the 16 bytes that end at s + len (from s + len - 16): the caller
 *       ensures they are readable.
 */
__attribute__((target("ssse3"))) inline bool parse_cell(const char *s, size_t len, double &v, char point = '.')
{
    const bool neg = len && *s == '-';
    len -= neg;   // s + len: the end of the cell either way
    if (len - 3 > 13) return false;   // 3..16 bytes: D.D to 15 digits and the dot
    const char *e = s + neg + len;
    const __m128i raw = _mm_loadu_si128((const __m128i *)(const void *)(e - 16));
    // digit values, the bytes before the number zeroed (they read as leading zeros)
    const __m128i d = _mm_and_si128(_mm_sub_epi8(raw, _mm_set1_epi8('0')),
                                    _mm_load_si128((const __m128i *)(const void *)CELL_TABLES.keep[len]));
    const unsigned nd =
        ~(unsigned)_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_min_epu8(d, _mm_set1_epi8(9)), d)) & 0xFFFFu;
    const unsigned dp = (unsigned)__builtin_ctz(nd | 0x10000u);   // the one non-digit: the dot
    if ((nd & (nd - 1)) != 0 || dp >= 15 || dp <= 16 - len || e[(int)dp - 16] != point) return false;
    const __m128i x = _mm_shuffle_epi8(d, _mm_load_si128((const __m128i *)(const void *)CELL_TABLES.shuf[dp]));
    // 16 digits -> 8 of 2 -> 4 of 4 -> 2 of 8 (the first 8 in the low lane)
    const __m128i p2 = _mm_maddubs_epi16(x, _mm_setr_epi8(10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1, 10, 1));
    const __m128i p4 = _mm_madd_epi16(p2, _mm_setr_epi16(100, 1, 100, 1, 100, 1, 100, 1));
    const __m128i p8 = _mm_madd_epi16(_mm_packs_epi32(p4, p4), _mm_setr_epi16(10000, 1, 10000, 1, 10000, 1, 10000, 1));
    const uint64_t q = (uint64_t)_mm_cvtsi128_si64(p8);
    const uint64_t m = (q & 0xFFFFFFFFu) * 100000000ull + (q >> 32);
    const double r = (double)m / POW10[15 - dp];   // f = 15 - dp fraction digits
    v = neg ? -r : r;
    return true;
}
#else
inline bool cell_available() { return false; }
#endif

}  // namespace decimal
}  // namespace msidrec
