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
// The cell parser of the CSV reader's vector path (a cell of known extent,
// SSSE3 or Advanced SIMD) is msid_csv_cells.hpp.
#pragma once
#include <charconv>
#include <cstdint>
#include <cstring>
#include <system_error>

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

}  // namespace decimal
}  // namespace msidrec
