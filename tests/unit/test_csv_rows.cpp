// The CSV reader's two row paths against each other (tools/msid/csv_io.cpp):
// parse_lines_cells (every delimiter found first, cells of the common shape by
// decimal::parse_cell, any other line by the general path) and parse_lines
// (every line by the general path). On 1,500 random files of every shape the
// reader accepts or refuses (delimiters , ; tab; LF and CRLF; time and ignored
// columns; trailing delimiters; numbers in every notation, '+', spaces,
// exponents, 16+ digits; blank, ragged and bad lines; a line longer than the
// cell path's 32 KiB scan; files over 1 MiB, split between two threads), both
// must give the same rows bit for bit or the same one error message.
// Coverage: on the common shape the cell path must take every row (a reader
// that always fell back would pass the comparison): Record::general_lines.
#include "msid_records.hpp"
#include "msid_csv_cells.hpp"
#include "msid_decimal.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <unistd.h>
#include <vector>

extern "C" {
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
#include "msid/msid_rng.h"
}

namespace {

std::string tmp_file()
{
    static std::string p;
    if (p.empty()) p = "/tmp/msid-test-csv-rows." + std::to_string(getpid()) + ".csv";
    return p;
}

void write_file(const std::string &path, const std::string &text)
{
    FILE *f = std::fopen(path.c_str(), "wb");
    assert_non_null(f);
    assert_int_equal(std::fwrite(text.data(), 1, text.size(), f), text.size());
    std::fclose(f);
}

uint64_t u(msid_rng &r, uint64_t n) { return msid_rng_u64(&r) % n; }

// One number in a random notation (mostly the shape the cell path takes).
std::string number(msid_rng &r)
{
    char b[64];
    const double x = (msid_rng_u64(&r) % 2 ? -1.0 : 1.0) * std::ldexp((double)(msid_rng_u64(&r) >> 11), -53) *
                     std::pow(10.0, (double)u(r, 7) - 3.0);
    switch (u(r, 16)) {
    case 0: std::snprintf(b, sizeof b, "%.17g", x); break;
    case 1: std::snprintf(b, sizeof b, "%.3e", x); break;
    case 2: std::snprintf(b, sizeof b, "%lld", (long long)(x * 1000)); break;
    case 3: std::snprintf(b, sizeof b, "+%.6f", std::fabs(x)); break;
    case 4: std::snprintf(b, sizeof b, " %.9f ", x); break;
    case 5: std::snprintf(b, sizeof b, "%.15f", x); break;
    case 6: std::snprintf(b, sizeof b, "%.1f", x); break;
    default: std::snprintf(b, sizeof b, "%.9g", x); break;
    }
    return b;
}

// A random CSV text: header, rows, and (sometimes) one defect.
std::string random_csv(msid_rng &r, bool big)
{
    const char delims[] = {',', ';', '\t'};
    const char d = delims[u(r, 8) < 6 ? 0 : 1 + u(r, 2)];
    const bool crlf = u(r, 4) == 0, time_col = u(r, 3) == 0, trailing = u(r, 5) == 0;
    const size_t nu = 1 + u(r, 2), ny = 1 + u(r, 3);
    std::vector<std::string> names;
    if (time_col) names.push_back("t");
    for (size_t k = 1; k <= nu; ++k) names.push_back("u" + std::to_string(k));
    for (size_t k = 1; k <= ny; ++k) names.push_back("y" + std::to_string(k));
    const size_t ncol = names.size();
    const char *eol = crlf ? "\r\n" : "\n";
    std::string s;
    for (size_t c = 0; c < ncol; ++c) s += (c ? std::string(1, d) : "") + names[c];
    if (trailing) s += std::string(1 + u(r, 2), d);
    s += eol;
    const size_t rows = big ? 60000 + u(r, 20000) : 1 + u(r, 300);
    const size_t defect_row = u(r, rows + rows / 4);   // beyond rows: none
    const unsigned defect = (unsigned)u(r, 14);
    for (size_t i = 0; i < rows; ++i) {
        std::string line;
        for (size_t c = 0; c < ncol; ++c) {
            if (c) line += d;
            line += time_col && c == 0 ? std::to_string(i) : number(r);
        }
        if (trailing && u(r, 2)) line += std::string(1 + u(r, 3), d);
        if (i == defect_row) {
            switch (defect) {
            case 0: s += eol; break;                                     // a blank line inside
            case 1: line = line.substr(0, line.rfind(d)); break;         // ragged: a cell short
            case 2: line += d; line += "1.5"; break;                     // ragged: a cell more
            case 3: line[line.size() / 2] = 'x'; break;                  // a bad character
            case 4: line.insert(line.size() / 2, "\r"); break;           // a stray carriage return
            case 5: line = "nan" + line.substr(line.find(d)); break;                 // NaN
            case 6: line = "  " + line; break;                           // leading spaces
            case 7: line.insert(line.find(d) + 1, 40000, '1'); break;     // a line over 32 KiB
            case 8: line.insert(line.find(d), "e-3"); break;             // an exponent
            case 9: line.insert(line.find(d) + 1, 1, d); break;          // an empty cell
            case 10: line += eol; line += eol; break;                    // a blank line, then rows
            case 11: line.insert(0, "0.123456789012345678"); break;      // many digits
            case 12: line.insert(line.find(d) + 1, "1e999"); break;      // out of range
            default: line.insert(line.find(d) + 1, "\"q\""); break;      // a quote
            }
        }
        s += line;
        s += i + 1 == rows && u(r, 4) == 0 ? "" : eol;                   // a last line without newline
    }
    if (defect_row == rows && u(r, 2)) s += eol;                         // a blank line at the end
    return s;
}

struct Outcome {
    bool ok = false;
    std::string err;
    msidrec::Record rec;
};

Outcome read(const std::string &path, bool split, bool cells)
{
    Outcome o;
    try {
        o.rec = msidrec::read_record_csv(path, {}, split, cells);
        o.ok = true;
    } catch (const std::exception &e) {
        o.err = e.what();
    }
    return o;
}

bool same(const Outcome &a, const Outcome &b)
{
    if (a.ok != b.ok) return false;
    if (!a.ok) return a.err == b.err;
    return a.rec.n_rows == b.rec.n_rows && a.rec.nu == b.rec.nu && a.rec.ny == b.rec.ny &&
           a.rec.rows.size() == b.rec.rows.size() &&
           std::memcmp(a.rec.rows.data(), b.rec.rows.data(), a.rec.rows.size() * sizeof(double)) == 0;
}

void test_cell_path_equals_general_path(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 20261124);
    const std::string path = tmp_file();
    size_t ok = 0, bad = 0, mismatches = 0;
    for (int n = 0; n < 1500; ++n) {
        const bool big = n % 150 == 0;   // 10 files of 3-6 MB: split in two, many 32 KiB scans
        const std::string text = random_csv(r, big);
        write_file(path, text);
        const bool split = n % 2 == 0;
        const Outcome g = read(path, split, false), c = read(path, split, true);
        if (!same(g, c)) {
            if (!mismatches)
                std::fprintf(stderr, "file %d: general %s / cells %s\n", n, g.ok ? "ok" : g.err.c_str(),
                             c.ok ? "ok" : c.err.c_str());
            ++mismatches;
        }
        (g.ok ? ok : bad)++;
    }
    std::remove(path.c_str());
    std::fprintf(stderr, "%zu files read, %zu refused, %zu mismatches\n", ok, bad, mismatches);
    assert_int_equal(mismatches, 0);
    assert_true(ok > 500 && bad > 300);   // both outcomes exercised
}

// The comparison itself must see a wrong value: a file changed in one digit of one cell reads
// differently (so equal outcomes above are not equal by construction).
void test_comparison_sees_a_changed_cell(void **)
{
    const std::string path = tmp_file();
    std::string text = "u1,y1\n";
    for (int i = 0; i < 5000; ++i) text += "0.123456789,-1.5\n";
    write_file(path, text);
    const Outcome a = read(path, true, true);
    text[6 + 17 * 4000 + 10] = '8';
    write_file(path, text);
    const Outcome b = read(path, true, true), g = read(path, true, false);
    std::remove(path.c_str());
    assert_true(a.ok && b.ok);
    assert_false(same(a, b));
    assert_true(same(b, g));
    assert_true(b.rec.rows[2 * 4000] == 0.123456788);
}

// The cell path takes every row of the common shape (LF and CRLF, ',' ';' and tab, a time column,
// trailing delimiters, files split between threads), and a row of another shape goes to the
// general path alone.
void test_cell_path_takes_the_common_rows(void **)
{
    if (!msidrec::cells::available()) skip();
    const std::string path = tmp_file();
    msid_rng r;
    msid_rng_seed(&r, 7);
    for (int variant = 0; variant < 6; ++variant) {
        const char d = variant == 3 ? ';' : (variant == 4 ? '\t' : ',');
        const char *eol = variant == 1 ? "\r\n" : "\n";
        std::string text = variant == 2 ? std::string("t") + d + "u1" + d + "y1" : std::string("u1") + d + "y1";
        text += variant == 5 ? std::string(2, d) + eol : eol;
        const size_t rows = variant == 0 ? 100000 : 3000;   // variant 0: 4 MB, two threads, blocks
        char b[64];
        for (size_t i = 0; i < rows; ++i) {
            if (variant == 2) text += std::to_string(i) + d;
            for (int c = 0; c < 2; ++c) {
                std::snprintf(b, sizeof b, "%.9g", (msid_rng_u64(&r) % 2 ? -1.0 : 1.0) *
                                                       std::ldexp((double)(msid_rng_u64(&r) >> 11), -52));
                text += b;
                text += c ? (variant == 5 ? std::string(2, d) : std::string()) + eol : std::string(1, d);
            }
        }
        write_file(path, text);
        const Outcome c = read(path, true, true), g = read(path, true, false);
        assert_true(c.ok && g.ok && same(c, g));
        assert_int_equal(c.rec.n_rows, rows);
        // %.9g writes an exponent for |x| < 1e-4 (about 1 cell in 10^4): those rows go the general way
        if (c.rec.general_lines > rows / 1000 + 1) std::fprintf(stderr, "variant %d: %zu general lines of %zu\n", variant, c.rec.general_lines, rows);
        assert_true(c.rec.general_lines <= rows / 1000 + 1);
        assert_int_equal(g.rec.general_lines, rows);
        // one row with a '+' goes to the general path, and only that one
        size_t at = text.find(eol, text.size() / 3) + std::strlen(eol);   // not a block or half start
        if (variant == 2) at = text.find(d, at) + 1;   // a number, not the (ignored) time column
        text.insert(at, "+");
        write_file(path, text);
        const Outcome c2 = read(path, true, true), g2 = read(path, true, false);
        assert_true(c2.ok && g2.ok && same(c2, g2));
        if (c2.rec.general_lines != c.rec.general_lines + 1) std::fprintf(stderr, "variant %d: %zu then %zu general lines; at %zu: %.40s\n", variant, c.rec.general_lines, c2.rec.general_lines, at, text.c_str() + at - 20);
        assert_int_equal(c2.rec.general_lines, c.rec.general_lines + 1);
    }
    std::remove(path.c_str());
}

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cell_path_equals_general_path),
        cmocka_unit_test(test_comparison_sees_a_changed_cell),
        cmocka_unit_test(test_cell_path_takes_the_common_rows),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
