// msidfrf::dump's fast forms against its plain one-thread text, byte for byte, on
// FRF-shaped documents (fixed seed): the lines' array written in two halves by two
// threads (two_threads), and line_element() (the typed result's writer writes each line
// with it) against dump_element() of the tree. Numbers of every layout (integers as
// doubles, 1e-5 .. 1e+20 borders, subnormals, -0.0, 17 digits), 1 to 501 lines. A NaN or
// infinite number throws NonFinite in every form. Negative control: the same comparison
// with one number changed in its last digit reports a difference.
#include "frf_text.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <optional>
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
    Json other = doc;   // one number one ulp off
    const double v = other["lines"][41]["G"]["re"][1][0].get<double>();
    other["lines"][41]["G"]["re"][1][0] = std::nextafter(v, HUGE_VAL);
    std::string got;
    msidfrf::dump(other, 1, got, true);
    assert_true(got != want);
}

// line_element() against dump_element() of the tree line(position(p), s) built from the same
// row-major arrays: every shape (ny, nu 1..3; bin 0; DT with and without fs; CT folded or
// not), optional members set and unset, non-finite values where the tree writes null
// (snr, input_snr) and where it throws (G, cov, cond), two indents and levels, first and later
// elements. Negative control: one number changed by one ulp in the arrays changes the text.
struct ArrayLine {
    msidfrf::Position p;
    std::vector<msidfrf::cd> G, cov, cov_ki, noise;
    std::vector<double> snr;
    double dof = 0, dof_ki = 0;
    std::optional<double> cond, input_snr;
    size_t ny = 0, nu = 0;
    msidfrf::LineArrays arrays() const
    {
        msidfrf::LineArrays a;
        a.G = G.data();
        a.cov = cov.data();
        a.dof = dof;
        a.cov_ki = cov_ki.empty() ? nullptr : cov_ki.data();
        a.dof_ki = dof_ki;
        a.noise = noise.empty() ? nullptr : noise.data();
        a.snr = snr.data();
        a.ny = ny;
        a.nu = nu;
        a.cond = cond;
        a.input_snr = input_snr;
        return a;
    }
    Json tree() const
    {
        msidfrf::LineStats s;
        s.G = msidfrf::from_row_major(G.data(), ny, nu);
        s.cov = msidfrf::from_row_major(cov.data(), ny * nu, ny * nu);
        s.dof = dof;
        if (!cov_ki.empty()) s.cov_ki = msidfrf::from_row_major(cov_ki.data(), ny * nu, ny * nu);
        s.dof_ki = dof_ki;
        if (!noise.empty()) s.noise = msidfrf::from_row_major(noise.data(), ny, ny);
        s.snr = snr;
        s.cond = cond;
        s.input_snr = input_snr;
        return msidfrf::line(msidfrf::position(p), s);
    }
};

std::vector<msidfrf::cd> random_cvec(msid_rng &r, size_t n)
{
    std::vector<msidfrf::cd> v(n);
    for (auto &x : v) x = {random_value(r), random_value(r)};
    return v;
}

ArrayLine random_array_line(msid_rng &r, uint32_t k)
{
    ArrayLine x;
    x.ny = 1 + k % 3;
    x.nu = 1 + k / 3 % 3;
    const size_t g = x.ny * x.nu;
    x.p.bin = k % 7 == 0 ? 0 : 1 + k;
    x.p.period = 1024 + 3 * k;
    x.p.ct = k % 4 == 1;
    x.p.omega = x.p.ct ? 1e3 * msid_rng_uniform(&r) : 0.0;
    x.p.folded = x.p.ct && k % 8 == 1;
    x.p.fs = !x.p.ct && k % 4 == 2 ? 48000.0 : 0.0;
    x.G = random_cvec(r, g);
    x.cov = random_cvec(r, g * g);
    x.dof = k % 2 ? 2.0 * k + 1.0 : random_value(r);
    if (k % 5 != 3) {
        x.cov_ki = random_cvec(r, g * g);
        x.dof_ki = random_value(r);
    }
    if (k % 6 != 4) x.noise = random_cvec(r, x.ny * x.ny);
    for (size_t y = 0; y < x.ny; ++y)
        x.snr.push_back(k % 9 == y ? (y ? -std::numeric_limits<double>::infinity() : std::nan("")) : random_value(r));
    if (k % 3 != 2) x.cond = random_value(r);
    if (k % 4 != 3) x.input_snr = k % 10 == 5 ? std::nan("") : random_value(r);
    if (k % 2 == 0) {   // Hermitian covariances, as the estimators give them (line_element reuses mirror texts)
        for (auto *M : {&x.cov, &x.cov_ki, &x.noise}) {
            if (M->empty()) continue;
            const size_t n = M == &x.noise ? x.ny : g;
            for (size_t i = 0; i < n; ++i)
                for (size_t j = 0; j < i; ++j) {
                    const msidfrf::cd u = (*M)[j * n + i];
                    (*M)[i * n + j] = std::conj(u);
                    switch (msid_rng_u64(&r) % 6) {   // the cases of the mirror test
                    case 0: (*M)[i * n + j] = {u.real(), std::nextafter(-u.imag(), HUGE_VAL)}; break;   // 1 ulp off
                    case 1: (*M)[j * n + i] = {u.real(), 0.0}; (*M)[i * n + j] = {u.real(), 0.0}; break;   // +0 twice
                    case 2: (*M)[j * n + i] = {u.real(), 0.0}; (*M)[i * n + j] = {u.real(), -0.0}; break;  // exact conj of 0
                    case 3: (*M)[i * n + j] = {std::nextafter(u.real(), -HUGE_VAL), -u.imag()}; break;
                    default: break;   // exact conjugate
                    }
                }
            for (size_t i = 0; i < n; ++i) (*M)[i * n + i] = {(*M)[i * n + i].real(), 0.0};
        }
    }
    return x;
}

std::string tree_text(const ArrayLine &x, size_t i, int indent, int level)
{
    std::string s;
    msidfrf::dump_element(x.tree(), i, indent, level, s);
    return s;
}

std::string direct_text(const ArrayLine &x, size_t i, int indent, int level)
{
    std::string s = "prefix";   // appends, as dump_element does
    msidfrf::line_element(x.p, x.arrays(), i, indent, level, s);
    return s.substr(6);
}

void test_line_element_equals_tree(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 14);
    for (uint32_t k = 0; k < 400; ++k) {
        const ArrayLine x = random_array_line(r, k);
        for (size_t i : {(size_t)0, (size_t)5})
            for (int indent : {1, 2})
                for (int level : {1, 2}) {
                    const std::string want = tree_text(x, i, indent, level), got = direct_text(x, i, indent, level);
                    if (got != want)
                        std::fprintf(stderr, "line_element differs: k = %u, i = %zu, indent %d, level %d\n%s\n---\n%s\n", k,
                                     i, indent, level, want.c_str(), got.c_str());
                    assert_true(got == want);
                }
    }
    // non-finite where the tree throws: both throw
    for (int where = 0; where < 3; ++where) {
        ArrayLine x = random_array_line(r, 11);
        if (where == 0) x.G[1] = {1.0, std::nan("")};
        if (where == 1) x.cov.back() = {std::numeric_limits<double>::infinity(), 0.0};
        if (where == 2) x.cond = std::nan("");
        int thrown = 0;
        try {
            tree_text(x, 0, 1, 1);
        } catch (const msidfrf::NonFinite &) {
            thrown++;
        }
        try {
            direct_text(x, 0, 1, 1);
        } catch (const msidfrf::NonFinite &) {
            thrown++;
        }
        assert_int_equal(thrown, 2);
    }
    // negative control: a number one ulp off in the arrays is seen in the text
    ArrayLine x = random_array_line(r, 13);
    const std::string want = tree_text(x, 0, 1, 1);
    x.cov[x.cov.size() / 2] = {x.cov[x.cov.size() / 2].real(), std::nextafter(x.cov[x.cov.size() / 2].imag(), HUGE_VAL)};
    assert_true(direct_text(x, 0, 1, 1) != want);
}

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_two_threads_equal_one),
        cmocka_unit_test(test_nonfinite_throws_in_every_form),
        cmocka_unit_test(test_negative_control),
        cmocka_unit_test(test_line_element_equals_tree),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
