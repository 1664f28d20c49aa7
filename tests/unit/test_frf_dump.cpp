// msidfrf::dump's fast forms against its plain one-thread text, byte for byte, on
// FRF-shaped documents (fixed seed): the lines' array written in two halves by two
// threads (two_threads), and the lines pre-rendered element by element with
// dump_element() and spliced in (Prerendered: msid frf writes each line's text as it
// builds it, without a tree of the lines; dump_around() leaves them for the writer to
// write after the text before them). Numbers of every layout (integers as
// doubles, 1e-5 .. 1e+20 borders, subnormals, -0.0, 17 digits), 1 to 501 lines, every
// split point class. A NaN or infinite number throws NonFinite in every form.
// Negative control: the same comparison on elements rendered one level too deep, or
// with one number changed in its last digit, reports a difference.
#include "frf_text.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
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

using msidfrf::Json;
using msidfrf::MatC;

// A double of a random layout class.
double random_value(msid_rng &r)
{
    const double u = msid_rng_uniform(&r), s = msid_rng_uniform(&r) < 0.5 ? -1.0 : 1.0;
    switch (msid_rng_u64(&r) % 8) {
    case 0: return s * std::floor(u * 1e6);                         // integer-valued: "12.0"
    case 1: return s * u * std::pow(10.0, -5.0 + 2.0 * msid_rng_uniform(&r));   // around 1e-5 / 0.0001
    case 2: return s * u * std::pow(10.0, 14.0 + 3.0 * msid_rng_uniform(&r));   // around 1e15 .. 1e17
    case 3: return s * u * 1e-310;                                  // subnormal
    case 4: return msid_rng_uniform(&r) < 0.5 ? -0.0 : 0.0;
    case 5: return s * u * std::pow(10.0, 600.0 * msid_rng_uniform(&r) - 300.0);
    default: return s * u;                                          // 17 significant digits
    }
}

MatC random_mat(msid_rng &r, Eigen::Index rows, Eigen::Index cols)
{
    MatC M(rows, cols);
    for (Eigen::Index i = 0; i < rows; ++i)
        for (Eigen::Index j = 0; j < cols; ++j) M(i, j) = {random_value(r), random_value(r)};
    return M;
}

Json random_line(msid_rng &r, uint32_t l, bool ct)
{
    msidfrf::Position p;
    p.bin = 3 + 2 * l;
    p.period = 4096;
    p.ct = ct;
    p.omega = ct ? 0.37 * (l + 1) : 0.0;
    p.folded = ct && l % 3 == 0;
    p.fs = ct ? 0.0 : 1000.0;
    msidfrf::LineStats s;
    s.G = random_mat(r, 2, 2);
    s.cov = random_mat(r, 4, 4);
    s.dof = 2.0 * l + 1.0;
    if (l % 2) {
        s.cov_ki = random_mat(r, 4, 4);
        s.dof_ki = l + 0.5;
    }
    s.noise = random_mat(r, 2, 2);
    s.snr = {random_value(r), l % 5 == 0 ? std::numeric_limits<double>::infinity() : random_value(r)};   // null
    if (l % 3) s.cond = random_value(r);
    s.input_snr = random_value(r);
    return msidfrf::line(msidfrf::position(p), s);
}

// An msid-frf/1-shaped document with L lines (members before and after "lines").
Json random_doc(msid_rng &r, uint32_t L, bool ct)
{
    Json doc;
    doc["format"] = "msid-frf/1";
    doc["period_samples"] = 4096;
    doc["noise_cov"] = msidfrf::cmat(random_mat(r, 2, 2));
    doc["experiments"] = Json::array({Json{{"source", "e1.csv"}, {"samples", 262144}}});
    Json lines = Json::array();
    for (uint32_t l = 0; l < L; ++l) lines.push_back(random_line(r, l, ct));
    doc["lines"] = std::move(lines);
    doc["detection_lines"] = Json::array({Json{{"bin", 4}, {"noise_var", {random_value(r), 0.5}}}});
    doc["nonlinear_distortion"] = Json{{"p_value", random_value(r)}, {"nl_to_noise_db", nullptr}};
    return doc;
}

std::string plain(const Json &doc)
{
    std::string s;
    msidfrf::dump(doc, 1, s);
    return s;
}

// The document's lines rendered by dump_element() at `level` in two parts split at h, and
// the document with an empty "lines" in their place.
struct Rendered {
    Json doc;
    msidfrf::Prerendered pre;
};

Rendered prerender(const Json &doc, size_t h, int level)
{
    Rendered x{doc, {}};
    const Json &lines = doc["lines"];
    x.pre.key = "lines";
    x.pre.n = lines.size();
    x.pre.parts.resize(2);
    for (size_t i = 0; i < lines.size(); ++i) msidfrf::dump_element(lines[i], i, 1, level, x.pre.parts[i < h]);
    std::swap(x.pre.parts[0], x.pre.parts[1]);   // parts[1] held [0, h): put it first
    x.doc["lines"] = Json::array();
    return x;
}

const uint32_t SIZES[] = {1, 2, 63, 64, 65, 200, 501};

void test_two_threads_equal_one(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 10);
    for (uint32_t L : SIZES)
        for (bool ct : {false, true}) {
            const Json doc = random_doc(r, L, ct);
            std::string two;
            msidfrf::dump(doc, 1, two, true);
            if (two != plain(doc)) std::fprintf(stderr, "two threads differ: L = %u, ct = %d\n", L, (int)ct);
            assert_true(two == plain(doc));
        }
}

void test_prerendered_equal_tree(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 11);
    for (uint32_t L : SIZES)
        for (bool ct : {false, true}) {
            const Json doc = random_doc(r, L, ct);
            const std::string want = plain(doc);
            for (size_t h : {(size_t)0, (size_t)1, (size_t)L / 2, (size_t)L - 1, (size_t)L}) {
                const Rendered x = prerender(doc, h, 1);
                for (bool two : {false, true}) {
                    std::string got;
                    msidfrf::dump(x.doc, 1, got, two, &x.pre);
                    if (got != want) std::fprintf(stderr, "pre-rendered differs: L = %u, h = %zu\n", L, h);
                    assert_true(got == want);
                    // the writer's form: the text around the parts, the parts written after `at`
                    std::string around;
                    const size_t at = msidfrf::dump_around(x.doc, 1, around, two, x.pre);
                    assert_true(at != std::string::npos);
                    around.insert(at, x.pre.parts[0] + x.pre.parts[1]);
                    assert_true(around == want);
                }
            }
        }
}

void test_nonfinite_throws_in_every_form(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 12);
    for (double bad : {std::nan(""), std::numeric_limits<double>::infinity()}) {
        Json doc = random_doc(r, 100, false);
        doc["lines"][77]["cov"]["im"][2][3] = bad;
        for (bool two : {false, true}) {
            std::string s;
            bool thrown = false;
            try {
                msidfrf::dump(doc, 1, s, two);
            } catch (const msidfrf::NonFinite &) {
                thrown = true;
            }
            assert_true(thrown);
        }
        std::string s;
        bool thrown = false;
        try {
            msidfrf::dump_element(doc["lines"][77], 77, 1, 1, s);
        } catch (const msidfrf::NonFinite &) {
            thrown = true;
        }
        assert_true(thrown);
    }
}

void test_negative_control(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 13);
    const Json doc = random_doc(r, 80, false);
    const std::string want = plain(doc);
    const Rendered deep = prerender(doc, 40, 2);   // one level too deep: other indentation
    std::string got;
    msidfrf::dump(deep.doc, 1, got, false, &deep.pre);
    assert_true(got != want);
    Json other = doc;   // one number one ulp off
    const double v = other["lines"][41]["G"]["re"][1][0].get<double>();
    other["lines"][41]["G"]["re"][1][0] = std::nextafter(v, HUGE_VAL);
    const Rendered x = prerender(other, 40, 1);
    got.clear();
    msidfrf::dump(x.doc, 1, got, true, &x.pre);
    assert_true(got != want);
}

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_two_threads_equal_one),
        cmocka_unit_test(test_prerendered_equal_tree),
        cmocka_unit_test(test_nonfinite_throws_in_every_form),
        cmocka_unit_test(test_negative_control),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
