// msid's MATLAB v5 reader on variables whose data are small elements (at most 4 bytes, stored in the
// tag itself: a 1x2 int16), many of them: each Array points into the reader's copy of its 4 bytes,
// and later variables must not move those copies. fuzz_files found the reader reading freed memory
// (a vector of short strings reallocated under an earlier Array), which returned stale bytes as
// samples; here the values read must be the ones written, for every variable.
#include "msid_records.hpp"

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <unistd.h>

extern "C" {
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>
}

namespace {

void put32(std::string &s, uint32_t v) { s.append((const char *)&v, 4); }   // little-endian hosts

// a small element: the byte count in the upper half of the type word, the data in the next 4 bytes
std::string small(uint32_t type, const void *data, uint32_t n)
{
    std::string s;
    put32(s, n << 16 | type);
    char b[4] = {0, 0, 0, 0};
    std::memcpy(b, data, n);
    s.append(b, 4);
    return s;
}

// a 1x2 double variable stored as int16 (MATLAB narrows a double class whose values fit)
std::string variable(const std::string &name, int16_t a, int16_t b)
{
    std::string body;
    put32(body, 6);   // array flags: class double
    put32(body, 8);
    put32(body, 6);
    put32(body, 0);
    put32(body, 5);   // dimensions 1 x 2
    put32(body, 8);
    put32(body, 1);
    put32(body, 2);
    body += small(1, name.data(), (uint32_t)name.size());   // name (<= 4 characters)
    const int16_t v[2] = {a, b};
    body += small(3, v, 4);                                // miINT16, 4 bytes: a small element
    std::string m;
    put32(m, 14);
    put32(m, (uint32_t)body.size());
    return m + body;
}

void test_many_small_parts_keep_their_values(void **)
{
    std::string f = std::string("MATLAB 5.0 MAT-file, small parts for msid's tests");
    f.resize(116, ' ');
    f.append(8, '\0');
    f += std::string("\x00\x01IM", 4);
    // u1, y1 first, then 40 more: the reader's copies of the first two must survive the later ones
    f += variable("u1", 11, -12);
    f += variable("y1", 21, -22);
    for (int k = 0; k < 40; ++k) f += variable("v" + std::to_string(k), (int16_t)(100 + k), (int16_t)(-100 - k));
    const std::string path = "/tmp/msid-test-mat-small." + std::to_string(getpid()) + ".mat";
    FILE *fp = std::fopen(path.c_str(), "wb");
    assert_non_null(fp);
    assert_int_equal(std::fwrite(f.data(), 1, f.size(), fp), f.size());
    std::fclose(fp);
    const msidrec::Record r = msidrec::read_record_mat(path, {});
    msidrec::ColumnMap last;
    last.map = {{"u1", "v39"}, {"y1", "u1"}};
    const msidrec::Record q = msidrec::read_record_mat(path, last);
    std::remove(path.c_str());
    assert_int_equal(r.n_rows, 2);
    assert_int_equal(r.nu + r.ny, 2);
    const double *d = r.data();
    assert_true(d[0] == 11 && d[1] == 21 && d[2] == -12 && d[3] == -22);
    const double *e = q.data();
    assert_true(e[0] == 139 && e[1] == 11 && e[2] == -139 && e[3] == -12);
}

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_many_small_parts_keep_their_values)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
