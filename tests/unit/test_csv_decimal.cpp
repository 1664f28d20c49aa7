// The CSV reader's number parser (tools/records/msid_decimal.hpp, msid_csv_cells.hpp) against
// std::from_chars, bit for bit, on 4 million random and adversarial decimal
// strings (fixed seed): every shape of the fast path (1..15 digits, a dot
// anywhere, exponents in and beyond [-22, 22]), 16..25 digits (from_chars
// path), halfway and near-halfway cases, subnormals, overflow, leading zeros.
// Negative control: the same checker on a parser that is deliberately 1 ulp
// off for one string in 64 must report those strings (a checker that cannot
// fail would prove nothing).
// The cell parser (cells::parse_cell, SSSE3 on x86-64, Advanced SIMD on AArch64 and NEON on 32-bit ARM, the CSV reader's path for cells whose
// extent it knows) on the same strings and on 2 million cells of the shape it
// takes, each after 16 random bytes it must ignore: whenever it accepts a cell
// its value has from_chars' bits and from_chars reads the whole cell, and it
// accepts every cell of its shape (-?D+.D+, at most 15 digits). Negative
// controls: a cell parser 1 ulp off, and one that takes a cell of a wrong shape.
// The structural scan (cells::hit_mask64) against a byte loop on random text.
// Without a vector path these tests are not built, and on a CPU without the
// extension (cells::available() false: an ARMv7 without NEON) they are skipped;
// the reader's scalar path is then the one test_csv_rows checks.
// MSID_EXPECT_CELLS=1 or 0 (tests/unit/CMakeLists.txt) states whether this CPU
// must take the vector path, so a dispatch that never takes it (or takes it on
// a CPU without NEON) fails instead of skipping.
#include "msid_csv_cells.hpp"
#include "msid_decimal.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

extern "C" {
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include "msid/msid_rng.h"
}

namespace {

using Parser = const char *(*)(const char *, const char *, double &, bool &);

// The string s (followed by a ',' delimiter and padding, as inside a CSV row).
struct Probe {
    std::string buf;
    explicit Probe(const std::string &s) : buf(s + ",\n" + std::string(16, '\n')) {}
};

// One random decimal string of a random shape.
std::string random_number(msid_rng &r)
{
    std::string s;
    const uint64_t shape = msid_rng_u64(&r) % 8;
    if (msid_rng_u64(&r) % 2) s += '-';
    const unsigned nd = shape < 5 ? 1 + (unsigned)(msid_rng_u64(&r) % 15)      // fast-path digit counts
                                  : 1 + (unsigned)(msid_rng_u64(&r) % 25);     // up to 25 digits
    std::string digits;
    for (unsigned k = 0; k < nd; ++k) digits += (char)('0' + msid_rng_u64(&r) % 10);
    if (shape == 1) digits[0] = '0';                                         // leading zeros
    if (shape == 2) for (unsigned k = nd / 2; k < nd; ++k) digits[k] = '9';  // runs of 9s (carries)
    const unsigned dot = (unsigned)(msid_rng_u64(&r) % (nd + 2));            // nd + 1: no dot
    if (dot <= nd) digits.insert(digits.begin() + dot, '.');
    if (digits == ".") digits = "0.";
    s += digits;
    if (shape >= 3 && msid_rng_u64(&r) % 2) {
        const int e = shape == 7 ? (int)(msid_rng_u64(&r) % 700) - 350   // subnormal .. overflow
                                 : (int)(msid_rng_u64(&r) % 61) - 30;    // around the [-22, 22] border
        s += (msid_rng_u64(&r) % 2) ? 'e' : 'E';
        s += std::to_string(e);
    }
    return s;
}

// Strings made to be hard: halfway between two doubles, the fast-path borders, extremes.
std::vector<std::string> adversarial()
{
    std::vector<std::string> v = {
        "0", "-0", "0.0", "5.", ".5", "-.5", "1", "9007199254740992", "9007199254740993", "9007199254740995",
        "999999999999999", "9999999999999999", "0.1", "0.2", "0.3", "1e22", "1e23", "1e-22", "1e-23",
        "123456789012345e22", "123456789012345e-22", "2.2250738585072011e-308", "2.2250738585072014e-308",
        "4.9406564584124654e-324", "2.4703282292062327e-324", "2.4703282292062328e-324", "1.7976931348623157e308",
        "1.7976931348623158e308", "1.7976931348623159e308", "1e400", "1e-400", "0.000000000000000000000001",
        "100000000000000000000000", "1.00000000000000011102230246251565404236316680908203125",
        "1.00000000000000011102230246251565404236316680908203124", "1.00000000000000011102230246251565404236316680908203126",
        "8.98846567431158e307", "3.0517578125e-05", "0.720449303", "-0.595336847", "1.20735233",
        "000000000000001", "0000000000000001.5", "7.2057594037927933e16", "72057594037927933",
    };
    // every double's shortest form and its 17-digit form, and the decimal halfway to the next double
    msid_rng r;
    msid_rng_seed(&r, 77);
    char b[64];
    for (int k = 0; k < 20000; ++k) {
        uint64_t bits = msid_rng_u64(&r) & 0x7FEFFFFFFFFFFFFFull;
        double x;
        std::memcpy(&x, &bits, 8);
        auto res = std::to_chars(b, b + sizeof b, x);
        v.emplace_back(b, res.ptr);
        std::snprintf(b, sizeof b, "%.17g", x);
        v.emplace_back(b);
        const double y = std::nextafter(x, INFINITY);
        if (std::isfinite(y)) {   // the midpoint x + (y - x) / 2, to 40 significant digits
            std::snprintf(b, sizeof b, "%.40Lg", (long double)x + ((long double)y - (long double)x) / 2);
            v.emplace_back(b);
        }
    }
    return v;
}

// Mismatches of `p` against std::from_chars (value bits, end position, accepted or not).
size_t check(Parser p, const std::vector<std::string> &strs, std::string *first)
{
    size_t bad = 0;
    for (const auto &s : strs) {
        const Probe pr(s);
        const char *b = pr.buf.data(), *e = b + pr.buf.size();
        double ref = 0, got = 0;
        auto res = std::from_chars(b, e, ref);
        bool slow = false;
        const char *q = p(b, e, got, slow);
        const bool ok_ref = res.ec == std::errc(), ok = q != nullptr;
        bool same = ok == ok_ref;
        // from_chars reports out of range (1e400, 1e-400) without a value; parse_slow passes that on
        if (same && ok) same = q == res.ptr && std::memcmp(&ref, &got, 8) == 0 && (slow || std::isfinite(got));
        if (!same) {
            if (!bad && first) *first = s;
            ++bad;
        }
    }
    return bad;
}

const char *parse_ok(const char *p, const char *end, double &v, bool &slow)
{
    return msidrec::decimal::parse(p, end, v, slow);
}

// The negative control: 1 ulp off when the string's length is a multiple of 64... of its bytes' sum.
const char *parse_off_by_one_ulp(const char *p, const char *end, double &v, bool &slow)
{
    const char *q = msidrec::decimal::parse(p, end, v, slow);
    unsigned sum = 0;
    for (const char *c = p; q && c < q; ++c) sum += (unsigned char)*c;
    if (q && sum % 64 == 0 && std::isfinite(v)) v = std::nextafter(v, INFINITY);
    return q;
}

std::vector<std::string> corpus()
{
    std::vector<std::string> v = adversarial();
    msid_rng r;
    msid_rng_seed(&r, 2026);
    const size_t n = 4000000;
    v.reserve(v.size() + n);
    for (size_t k = 0; k < n; ++k) v.push_back(random_number(r));
    return v;
}

void test_decimal_equals_from_chars(void **)
{
    const std::vector<std::string> strs = corpus();
    std::string first;
    const size_t bad = check(parse_ok, strs, &first);
    if (bad) std::fprintf(stderr, "%zu mismatches, first '%s'\n", bad, first.c_str());
    assert_int_equal(bad, 0);
}

void test_decimal_negative_control(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 2026);
    std::vector<std::string> strs;
    for (int k = 0; k < 200000; ++k) strs.push_back(random_number(r));
    const size_t bad = check(parse_off_by_one_ulp, strs, nullptr);
    // about one string in 64 is made wrong: the checker must see (nearly) all of them
    assert_true(bad > strs.size() / 128);
}

#ifdef MSID_CSV_CELLS
using CellParser = bool (*)(const char *, size_t, double &);

bool cell_ok(const char *s, size_t len, double &v) { return msidrec::cells::parse_cell(s, len, v); }

// Negative controls: 1 ulp off for one cell in 64 (by its bytes' sum); a cell with an exponent read
// as its mantissa (the parse of a wrong shape).
bool cell_off_by_one_ulp(const char *s, size_t len, double &v)
{
    if (!msidrec::cells::parse_cell(s, len, v)) return false;
    unsigned sum = 0;
    for (size_t k = 0; k < len; ++k) sum += (unsigned char)s[k];
    if (sum % 64 == 0) v = std::nextafter(v, INFINITY);
    return true;
}
bool cell_ignores_exponent(const char *s, size_t len, double &v)
{
    size_t n = 0;
    while (n < len && (s[n] | 0x20) != 'e') ++n;
    return msidrec::cells::parse_cell(s, n, v) || msidrec::cells::parse_cell(s, len, v);
}

// Is s of the cell parser's shape: -?D+.D+ with 2..15 digits?
bool cell_shape(const std::string &s)
{
    size_t k = s[0] == '-', digits = 0, dots = 0;
    if (k == s.size()) return false;
    const size_t first = k;
    for (; k < s.size(); ++k) {
        if (s[k] == '.') {
            if (dots++ || k == first || k + 1 == s.size()) return false;
        } else if (msidrec::decimal::digit(s[k])) {
            ++digits;
        } else {
            return false;
        }
    }
    return dots == 1 && digits <= 15;
}

// Mismatches of the cell parser `p` against std::from_chars; `missed`: cells of its shape it refused.
size_t check_cells(CellParser p, const std::vector<std::string> &strs, size_t &taken, size_t &missed,
                   std::string *first)
{
    static const char junk[] = "0123456789.-+eE,;\t \n\r\"x";
    msid_rng r;
    msid_rng_seed(&r, 31);
    size_t bad = 0;
    taken = missed = 0;
    std::string buf;
    for (const auto &s : strs) {
        buf.clear();
        for (int k = 0; k < 16; ++k) buf += junk[msid_rng_u64(&r) % (sizeof junk - 1)];
        buf += s;
        buf += ',';
        double got = 0, ref = 0;
        const char *c = buf.data() + 16;
        const bool ok = p(c, s.size(), got);
        if (ok) {
            ++taken;
            auto res = std::from_chars(c, c + s.size(), ref);
            if (res.ec != std::errc() || res.ptr != c + s.size() || std::memcmp(&ref, &got, 8) != 0) {
                if (!bad && first) *first = s;
                ++bad;
            }
        } else if (cell_shape(s)) {
            if (!bad && first) *first = s + " (refused)";
            ++missed;
        }
    }
    return bad;
}

// Cells of the parser's shape: a sign or not, 2..17 digits (16, 17: refused), the dot anywhere inside.
std::vector<std::string> cells()
{
    msid_rng r;
    msid_rng_seed(&r, 4242);
    std::vector<std::string> v;
    v.reserve(2000000);
    for (int n = 0; n < 2000000; ++n) {
        const unsigned nd = 2 + (unsigned)(msid_rng_u64(&r) % 16);
        std::string s = msid_rng_u64(&r) % 2 ? "-" : "";
        std::string d;
        for (unsigned k = 0; k < nd; ++k) d += (char)('0' + msid_rng_u64(&r) % 10);
        if (msid_rng_u64(&r) % 4 == 0) d[0] = '0';
        d.insert(d.begin() + 1 + (long)(msid_rng_u64(&r) % (nd - 1)), '.');
        v.push_back(s + d);
    }
    return v;
}

void test_cell_equals_from_chars(void **)
{
    if (!msidrec::cells::available()) skip();
    std::vector<std::string> strs = corpus();
    const std::vector<std::string> c = cells();
    strs.insert(strs.end(), c.begin(), c.end());
    for (const char *x : {"", "-", ".", "-.", "1.", ".5", "1.5e3", "+1.5", "1..5", "-0.0", "0.0", "1 .5", "1.5 "})
        strs.emplace_back(x);
    std::string first;
    size_t taken = 0, missed = 0;
    const size_t bad = check_cells(cell_ok, strs, taken, missed, &first);
    if (bad || missed) std::fprintf(stderr, "%zu mismatches, %zu refused, first '%s'\n", bad, missed, first.c_str());
    assert_int_equal(bad, 0);
    assert_int_equal(missed, 0);
    assert_true(taken > 1800000);   // the cells of its shape (about 7/8 of 2 million) and the corpus's
}

// Decimal commas (csv_io.cpp: ';' or tab files): "1,25" with point ',' gives the bits of "1.25" with
// '.', and neither parser takes the other separator.
void test_cell_decimal_comma(void **)
{
    if (!msidrec::cells::available()) skip();
    const std::vector<std::string> c = cells();
    size_t taken = 0, bad = 0;
    std::string buf;
    for (size_t k = 0; k < 200000; ++k) {
        std::string s = c[k];
        std::string t = s;
        std::replace(t.begin(), t.end(), '.', ',');
        buf = std::string(16, ';') + t + ";" + std::string(16, ';') + s + ";";
        const char *tc = buf.data() + 16, *sc = tc + t.size() + 1 + 16;
        double a = 0, b = 0;
        const bool ok = msidrec::cells::parse_cell(sc, s.size(), a);
        if (ok != msidrec::cells::parse_cell(tc, t.size(), b, ',')) ++bad;
        else if (ok && std::memcmp(&a, &b, 8) != 0) ++bad;
        taken += ok;
        if (msidrec::cells::parse_cell(sc, s.size(), a, ',') || msidrec::cells::parse_cell(tc, t.size(), b)) ++bad;
    }
    assert_int_equal(bad, 0);
    assert_true(taken > 170000);
}

void test_cell_negative_controls(void **)
{
    if (!msidrec::cells::available()) skip();
    const std::vector<std::string> c = cells();
    const std::vector<std::string> strs(c.begin(), c.begin() + 200000);
    size_t taken = 0, missed = 0;
    assert_true(check_cells(cell_off_by_one_ulp, strs, taken, missed, nullptr) > strs.size() / 128);
    std::vector<std::string> e;
    for (size_t k = 0; k < 2000; ++k) e.push_back(strs[k] + "e3");
    assert_true(check_cells(cell_ignores_exponent, e, taken, missed, nullptr) > 1000);
    // a parser refusing everything fails the coverage count
    assert_int_equal(check_cells([](const char *, size_t, double &) { return false; }, strs, taken, missed,
                                 nullptr), 0);
    assert_true(missed > 150000);
}

// hit_mask64 against the byte loop it replaces, on 64-byte windows of random text drawn mostly from
// the characters it looks for (every bit position, every delimiter the reader takes, bytes >= 0x80).
void test_hit_mask_equals_bytes(void **)
{
    if (!msidrec::cells::available()) skip();
    msid_rng r;
    msid_rng_seed(&r, 64);
    const char pick[] = {',', ';', '\t', '\n', '\r', '0', '.', '-', (char)0x8A, (char)0xAC, ' '};
    char buf[64];
    size_t bad = 0, hits = 0;
    for (int k = 0; k < 20000; ++k) {
        const char d = ",;\t"[k % 3];
        for (char &c : buf)
            c = msid_rng_u64(&r) % 4 ? pick[msid_rng_u64(&r) % sizeof pick] : (char)(msid_rng_u64(&r) & 0xFF);
        uint64_t want = 0;
        for (int i = 0; i < 64; ++i)
            if (buf[i] == d || buf[i] == '\n' || buf[i] == '\r') want |= 1ull << i;
        bad += msidrec::cells::hit_mask64(buf, d) != want;
        hits += (size_t)__builtin_popcountll(want);
    }
    assert_int_equal(bad, 0);
    assert_true(hits > 20000 * 64 / 8);   // about a fifth of the bytes are hits
}
#endif

}  // namespace

// Does this CPU take the vector path as the test's environment says it must (MSID_EXPECT_CELLS)?
void test_vector_path_as_expected(void **)
{
    const char *want = std::getenv("MSID_EXPECT_CELLS");
    if (!want) skip();
#ifdef MSID_CSV_CELLS
    const bool have = msidrec::cells::available();
#else
    const bool have = false;
#endif
    if (have != (std::strcmp(want, "1") == 0))
        fail_msg("the CSV vector path is %s on this CPU, MSID_EXPECT_CELLS=%s", have ? "taken" : "not taken", want);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_decimal_equals_from_chars),
        cmocka_unit_test(test_decimal_negative_control),
        cmocka_unit_test(test_vector_path_as_expected),
#ifdef MSID_CSV_CELLS
        cmocka_unit_test(test_cell_equals_from_chars),
        cmocka_unit_test(test_cell_decimal_comma),
        cmocka_unit_test(test_cell_negative_controls),
        cmocka_unit_test(test_hit_mask_equals_bytes),
#endif
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
