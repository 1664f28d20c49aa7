// The msid-frf/1 writer of the typed FRF result (msidjob::write_frf_text) against the tree writer
// (msidfrf::dump of msidjob::frf_document), byte for byte, on random results (fixed seed): 1 x 1 to
// 3 x 3, 1 to 200 lines (both sides of the two-thread split at 64), DT with and without fs, CT with
// folded lines, DC, signal names, detection lines, tail members (and one that replaces a member
// before the lines, which keeps that member's place), numbers of every layout, non-finite SNRs
// (null). A NaN in G or cov throws NonFinite in both writers. Negative control: one number one ulp
// off in the arrays changes the text.
#include "msid_frf_result.hpp"
#include "frf_text.hpp"

#include <cmath>
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

using msidjob::FrfResult;
using msidjob::Json;
using cd = FrfResult::cd;

double random_value(msid_rng &r)
{
    const double u = msid_rng_uniform(&r), s = msid_rng_uniform(&r) < 0.5 ? -1.0 : 1.0;
    switch (msid_rng_u64(&r) % 7) {
    case 0: return s * std::floor(u * 1e6);
    case 1: return s * u * std::pow(10.0, -5.0 + 2.0 * msid_rng_uniform(&r));
    case 2: return s * u * std::pow(10.0, 14.0 + 3.0 * msid_rng_uniform(&r));
    case 3: return s * u * 1e-310;
    case 4: return msid_rng_uniform(&r) < 0.5 ? -0.0 : 0.0;
    default: return s * u;
    }
}

void fill(msid_rng &r, std::vector<cd> &v, size_t n)
{
    for (size_t i = 0; i < n; ++i) v.push_back({random_value(r), random_value(r)});
}

FrfResult random_result(msid_rng &r, uint32_t k, uint32_t L)
{
    FrfResult x;
    const size_t ny = 1 + k % 3, nu = 1 + k / 3 % 3, g = ny * nu, m = nu + k % 2;
    msidfrf::Header &h = x.header;
    h.period = 4096;
    h.nu = (uint32_t)nu;
    h.ny = (uint32_t)ny;
    h.m = (uint32_t)m;
    h.ct = k % 4 == 1;
    h.sample_time = h.ct ? 1e-3 : 0.0;
    h.fs = k % 4 == 2 ? 48000.0 : 0.0;
    if (k % 5 == 0) {
        for (size_t i = 0; i < nu; ++i) h.input_names.push_back("u \"" + std::to_string(i) + "\"");
        for (size_t i = 0; i < ny; ++i) h.output_names.push_back("y" + std::to_string(i));
        h.output_units.assign(ny, "m/s\u00b2");
    }
    x.periods_used = 64 * m;
    x.periods_rejected = k % 3;
    x.dft_path = k % 2 ? "fft" : "stream";
    fill(r, x.noise_cov, ny * ny);
    for (size_t e = 0; e < m; ++e) {
        msidfrf::Experiment ex;
        ex.source = "e" + std::to_string(e) + ".csv";
        ex.samples = 262144;
        ex.periods_total = 64;
        ex.periods_used = 64 - e;
        ex.transient_tested = e % 2 == 0;
        ex.transient_flagged = {1, 2};
        ex.drift_block = true;
        ex.drift_p_value = e ? random_value(r) : std::nan("");
        x.experiments.push_back(ex);
    }
    for (uint32_t l = 0; l < L; ++l) {
        msidfrf::Position p;
        p.bin = k % 7 == 0 && l == 0 ? 0 : 1 + 3 * l;
        p.period = h.period;
        p.ct = h.ct;
        p.omega = h.ct ? 2 * M_PI * p.bin / (h.period * h.sample_time) : 0.0;
        p.folded = h.ct && l % 5 == 2;
        p.fs = h.fs;
        x.pos.push_back(p);
        fill(r, x.G, g);
        fill(r, x.cov, g * g);
        fill(r, x.cov_ki, g * g);
        fill(r, x.noise, ny * ny);
        x.dof.push_back(random_value(r));
        x.dof_ki.push_back(random_value(r));
        for (size_t y = 0; y < ny; ++y)
            x.snr.push_back(l % 9 == y ? -std::numeric_limits<double>::infinity() : random_value(r));
        x.cond.push_back(random_value(r));
        x.input_snr.push_back(l % 11 == 3 ? std::nan("") : random_value(r));
    }
    for (uint32_t d = 0; d < k % 3; ++d) {
        x.detect_bins.push_back(2 + 3 * d);
        fill(r, x.detect_mean, m * ny);
        for (size_t y = 0; y < ny; ++y) {
            x.detect_var.push_back(random_value(r));
            x.detect_p.push_back(random_value(r));
        }
    }
    if (k % 4 == 3) {
        x.tail["nonlinear_distortion"] = Json{{"p_value", random_value(r)}, {"nl_to_noise_db", nullptr}};
        x.tail["lines_auto"] = Json{{"bins", {1, 4, 7}}, {"unusable_bins", Json::array()}};
    }
    if (k % 8 == 6) x.tail["complete"] = false;
    return x;
}

std::string tree_text(const FrfResult &x)
{
    std::string s;
    msidfrf::dump(msidjob::frf_document(x), 1, s);
    return s + "\n";
}

std::string direct_text(const FrfResult &x)
{
    std::string s;
    msidjob::write_frf_text(x, s);
    return s;
}

void test_writer_equals_tree(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 21);
    for (uint32_t k = 0; k < 48; ++k)
        for (uint32_t L : {1u, 2u, 63u, 64u, 65u, 200u}) {
            if (L > 65 && k % 6) continue;   // the large ones for some shapes only (time)
            const FrfResult x = random_result(r, k, L);
            const std::string want = tree_text(x), got = direct_text(x);
            if (got != want) std::fprintf(stderr, "the writer differs from the tree: k = %u, L = %u\n", k, L);
            assert_true(got == want);
        }
    // a tail member that replaces a member before the lines keeps that member's place
    FrfResult x = random_result(r, 3, 70);
    x.tail["n_experiments"] = 7;
    const std::string want = tree_text(x);
    assert_true(direct_text(x) == want);
    assert_true(want.find("\"n_experiments\": 7,\n \"domain\"") != std::string::npos);
}

void test_nonfinite_throws_in_both(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 22);
    for (int where = 0; where < 3; ++where) {
        FrfResult x = random_result(r, 4, 100);
        if (where == 0) x.G[77] = {1.0, std::nan("")};
        if (where == 1) x.cov[5] = {std::numeric_limits<double>::infinity(), 0.0};
        if (where == 2) x.cond[90] = std::nan("");
        int thrown = 0;
        try {
            tree_text(x);
        } catch (const msidfrf::NonFinite &) {
            ++thrown;
        }
        try {
            direct_text(x);
        } catch (const msidfrf::NonFinite &) {
            ++thrown;
        }
        assert_int_equal(thrown, 2);
    }
}

void test_negative_control(void **)
{
    msid_rng r;
    msid_rng_seed(&r, 23);
    FrfResult x = random_result(r, 8, 80);
    const std::string want = tree_text(x);
    assert_true(direct_text(x) == want);
    x.cov_ki[100] = {x.cov_ki[100].real(), std::nextafter(x.cov_ki[100].imag(), HUGE_VAL)};
    assert_true(direct_text(x) != want);
}

}  // namespace

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_writer_equals_tree),
        cmocka_unit_test(test_nonfinite_throws_in_both),
        cmocka_unit_test(test_negative_control),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
