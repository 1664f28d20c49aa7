// The fit job (tools/fitjob) called as a library, without the command line: a 2x2 4th-order DT
// plant's FRF with seeded complex Gaussian errors of a known covariance (M = 8 periods) comes back
// from subspace, ml (LMFD and pole-residue) and the order scan within its uncertainty; the
// document carries what msid fit writes; bad requests are UsageError (exit 2), data that cannot
// be fitted msidfitjob::Error (exit 1), each with msid fit's message.
#include "msid_fit_job.hpp"

#include "models.hpp"

#include <cmath>
#include <random>
#include <string>
// cmocka last: it defines macros (fail, ...) that clash with the C++ library
#include <cstdarg>
#include <cstddef>
#include <csetjmp>
#include <cstdint>
extern "C" {
#include <cmocka.h>
}

using namespace msidfit;
using msidfitjob::FitOutcome;
using msidfitjob::FitRequest;
using msidfitjob::Json;

static const double VAR = 1e-4;   // variance of each complex FRF entry
static const uint32_t M_PERIODS = 8;

static SSModel plant()
{
    MatR A(4, 4), B(4, 2), C(2, 4), D(2, 2);
    A << 0.8, -0.4, 0, 0, 0.4, 0.8, 0, 0, 0, 0, 0.3, -0.6, 0, 0, 0.6, 0.3;
    B << 1.0, 0.2, 0.0, 0.5, 0.4, 1.0, 0.6, 0.0;
    C << 1.0, 0.0, 0.5, 0.3, 0.2, 0.7, 0.0, 1.0;
    D << 0.2, 0.0, 0.1, 0.3;
    SSModel m;
    m.domain = Domain::DT;
    m.A = A; m.B = B; m.C = C; m.D = D;
    return m;
}

// The plant's FRF at 60 lines of a 256-sample period with errors of covariance VAR I (M - 1 dof).
static FrfData noisy_frf(unsigned seed)
{
    const SSModel m = plant();
    std::mt19937_64 rng(seed);
    std::normal_distribution<double> nd(0.0, std::sqrt(VAR / 2));
    FrfData f;
    f.path = "<simulated>";
    f.domain = Domain::DT;
    f.nu = f.ny = f.m = 2;
    f.P = 256;
    for (uint32_t b = 2; b < 122; b += 2) {
        Line l;
        l.bin = b;
        l.freq = (double)b / f.P;
        l.omega = 2 * M_PI * l.freq;
        l.G = ss_eval(m, std::polar(1.0, l.omega));
        for (Eigen::Index i = 0; i < l.G.size(); ++i) l.G(i) += cd(nd(rng), nd(rng));
        l.cov = MatC::Identity(4, 4) * VAR;
        l.cov_ki = l.cov;
        l.dof = l.dof_ki = M_PERIODS - 1;
        l.noise = MatC::Identity(2, 2) * VAR;
        f.lines.push_back(l);
    }
    f.noise_time = MatC::Identity(2, 2) * VAR;
    return f;
}

static MatR matrix(const Json &v)
{
    MatR M((Eigen::Index)v.size(), v.empty() ? 0 : (Eigen::Index)v[0].size());
    for (Eigen::Index r = 0; r < M.rows(); ++r)
        for (Eigen::Index c = 0; c < M.cols(); ++c) M(r, c) = v[(size_t)r][(size_t)c].get<double>();
    return M;
}

// The document's state-space model against the plant: the largest error of its FRF at the lines,
// in standard deviations of one line's entry.
static double frf_error_sd(const Json &doc, const FrfData &f)
{
    SSModel m;
    m.domain = Domain::DT;
    m.A = matrix(doc["A"]); m.B = matrix(doc["B"]); m.C = matrix(doc["C"]); m.D = matrix(doc["D"]);
    const SSModel p = plant();
    double worst = 0;
    for (const auto &l : f.lines) {
        const cd z = std::polar(1.0, l.omega);
        worst = std::max(worst, (ss_eval(m, z) - ss_eval(p, z)).cwiseAbs().maxCoeff());
    }
    return worst / std::sqrt(VAR);
}

// What every model document holds, in the order of the format.
static void check_document(const Json &doc, const std::string &method, int order)
{
    const char *keys[] = {"format", "generator", "source", "domain", "method", "order", "n_inputs", "n_outputs",
                          "settings", "A", "B", "C", "D", "stable", "stability", "n_params"};
    size_t k = 0;
    for (auto it = doc.begin(); it != doc.end() && k < sizeof keys / sizeof *keys; ++it)
        if (it.key() == keys[k]) ++k;
    assert_int_equal(k, sizeof keys / sizeof *keys);
    assert_string_equal(doc["format"].get<std::string>().c_str(), "msid-model/1");
    assert_string_equal(doc["method"].get<std::string>().c_str(), method.c_str());
    assert_string_equal(doc["source"].get<std::string>().c_str(), "<simulated>");
    assert_int_equal(doc["order"].get<int>(), order);
    assert_true(doc["stable"].get<bool>());
    assert_true(doc.contains("cost") && doc.contains("frf") && doc.contains("modes"));
    assert_int_equal(doc["frf"].size(), 60);
}

static void test_subspace_and_ml_recover_the_plant(void **)
{
    const FrfData f = noisy_frf(1);
    for (const char *method : {"subspace", "ml"}) {
        FitRequest rq;
        rq.method = method;
        rq.order = "4";
        std::vector<std::string> seen;
        const FitOutcome o = msidfitjob::fit_frf(f, rq, [&](const std::string &n) { seen.push_back(n); });
        check_document(o.model, method, 4);
        assert_true(seen == o.notes);
        assert_true(o.converged);
        // 60 lines, 4 entries each: the worst of 240 complex errors of the data is ~3.5 sd; a model
        // with 20-24 parameters averages it down, a wrong one is off by far more
        const double e = frf_error_sd(o.model, f);
        assert_true(e < 2.0);
        // the cost is consistent with the noise (the p-value of a right model is uniform: 1e-3 fails 1 in 1000)
        assert_true(o.model["cost"]["p_value"].get<double>() > 1e-3);
        assert_true(o.tail.find(std::string(method) + " fit, order 4") != std::string::npos);
    }
}

static void test_pole_residue_ml_and_its_uncertainty(void **)
{
    const FrfData f = noisy_frf(2);
    FitRequest rq;
    rq.method = "ml";
    rq.order = "4";
    rq.param = "poles";
    const FitOutcome o = msidfitjob::fit_frf(f, rq);
    const Json &doc = o.model;
    assert_string_equal(doc["settings"]["param"].get<std::string>().c_str(), "poles");
    assert_true(doc.contains("pole_residue") && doc.contains("parameters"));
    // 4 poles, each a 2x2 residue matrix: state order 8 (each pole once per input), as msid fit says
    assert_int_equal(doc["order"].get<int>(), 8);
    assert_true(o.tail.find("(4 poles; state order 8") != std::string::npos);
    // the model FRF's reported covariance covers its error against the plant: per line a chi2 with
    // 8 real dof (40 is far in its tail), summed over 60 lines a mean of 480 (the lines share the
    // parameters' errors, so the sum spreads as a chi2 of about their number: a factor 3 either way
    // is a covariance wrong by that factor)
    const SSModel p = plant();
    double q = 0;
    for (size_t l = 0; l < f.lines.size(); ++l) {
        const Json &e = doc["frf"][l];
        MatC G(2, 2), C(4, 4);
        for (int r = 0; r < 2; ++r)
            for (int c = 0; c < 2; ++c) G(r, c) = cd(e["G"]["re"][r][c].get<double>(), e["G"]["im"][r][c].get<double>());
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c)
                C(r, c) = cd(e["cov"]["re"][r][c].get<double>(), e["cov"]["im"][r][c].get<double>());
        const MatC d = G - ss_eval(p, std::polar(1.0, f.lines[l].omega));
        const VecC v = Eigen::Map<const VecC>(d.data(), 4);
        const double ql = 2.0 * (v.adjoint() * C.ldlt().solve(v))(0, 0).real();
        assert_true(ql < 40);
        q += ql;
    }
    assert_true(q > 480.0 / 3 && q < 3 * 480.0);
}

static void test_order_scan_chooses_the_plant_order(void **)
{
    const FrfData f = noisy_frf(3);
    FitRequest rq;
    rq.method = "ml";   // no order: chosen (auto), as msid fit does
    const FitOutcome o = msidfitjob::fit_frf(f, rq);
    assert_int_equal(o.model["order_selection"]["chosen"].get<int>(), 4);
    assert_true(o.before.find("<- chosen") != std::string::npos);
    assert_true(o.head.rfind("chosen order 4", 0) == 0);
    assert_true(frf_error_sd(o.model, f) < 2.0);
}

static void test_bad_requests_and_data(void **)
{
    const FrfData f = noisy_frf(4);
    auto usage = [&](FitRequest rq, const char *want) {
        try {
            msidfitjob::fit_frf(f, rq);
        } catch (const msidutil::UsageError &e) {
            assert_int_equal(e.code, 2);
            assert_true(std::string(e.what()).find(want) != std::string::npos);
            return;
        }
        fail_msg("no usage error for '%s'", want);
    };
    FitRequest rq;
    rq.method = "ml";
    rq.order = "4";
    rq.stable = rq.allow_unstable = true;
    usage(rq, "--stable contradicts --allow-unstable");
    rq = FitRequest();
    rq.method = "magic";
    usage(rq, "--method must be subspace, lmfd, ml, multi or cissim (got 'magic')");
    rq = FitRequest();
    rq.method = "lmfd";
    rq.order = "3";
    usage(rq, "--order must be a positive multiple of the number of outputs for an LMFD");
    rq.order = "auto";
    usage(rq, "--order auto/a:b needs --method subspace or ml");
    // covariances of 2 dof: too few periods for weights from 2 outputs' sample covariance
    FrfData few = f;
    for (auto &l : few.lines) l.dof = l.dof_ki = 2;
    rq = FitRequest();
    rq.method = "subspace";
    rq.order = "4";
    try {
        msidfitjob::fit_frf(few, rq);
        fail_msg("3 periods were weighted");
    } catch (const msidfitjob::Error &e) {
        assert_int_equal(e.code, 1);
        assert_true(e.kind == msidutil::ErrorKind::data);
        if (std::string(e.what()).find("periods per experiment: weighting by the inverse sample covariance needs M >= 4") ==
            std::string::npos)
            fail_msg("%s", e.what());
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_subspace_and_ml_recover_the_plant),
        cmocka_unit_test(test_pole_residue_ml_and_its_uncertainty),
        cmocka_unit_test(test_order_scan_chooses_the_plant_order),
        cmocka_unit_test(test_bad_requests_and_data),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
