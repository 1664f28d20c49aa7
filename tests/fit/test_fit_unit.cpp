// Deterministic tests of the fitting library: closed forms of González et al.
// 2025 §V-B (cases G1, G2), exact recovery of known systems from noiseless
// FRFs (DT and CT, SISO and 2x2 4th order, by subspace, lmfd and ml), model
// conversions and distances, and the errors of bad requests and data.
#include "lmfd_fit.hpp"
#include "order_select.hpp"
#include "subspace.hpp"
#include <cmath>
#include <cstdio>
#include <functional>
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

// FRF data from exact values at the given frequency points.
static FrfData exact_data(Domain d, double h, const std::vector<double> &omega, const std::vector<MatC> &G, double var)
{
    FrfData f;
    f.path = "<exact>";
    f.domain = d;
    f.h = h;
    f.nu = (uint32_t)G[0].cols();
    f.ny = (uint32_t)G[0].rows();
    f.m = f.nu;
    f.P = 1000;
    const size_t g = f.g();
    for (size_t l = 0; l < omega.size(); ++l) {
        Line ln;
        ln.bin = (uint32_t)l + 1;
        ln.omega = omega[l];
        ln.freq = d == Domain::DT ? omega[l] / (2 * M_PI) : omega[l] * h / (2 * M_PI);
        ln.G = G[l];
        ln.cov = MatC::Identity(g, g) * var;
        ln.cov_ki = ln.cov;
        ln.dof = ln.dof_ki = 1e6;
        ln.noise = MatC::Identity(f.ny, f.ny) * var;
        f.lines.push_back(ln);
    }
    f.noise_time = MatC::Identity(f.ny, f.ny) * var;
    return f;
}

static SSModel ss(Domain d, MatR A, MatR B, MatR C, MatR D)
{
    SSModel m;
    m.domain = d;
    m.A = A; m.B = B; m.C = C; m.D = D;
    return m;
}

static SSModel siso_dt()
{
    MatR A(2, 2), B(2, 1), C(1, 2), D(1, 1);
    A << 1.2, -0.7, 1.0, 0.0; B << 1, 0; C << 0.5, 0.3; D << 0.1;
    return ss(Domain::DT, A, B, C, D);
}

static SSModel mimo_dt()
{
    MatR A(4, 4), B(4, 2), C(2, 4), D(2, 2);
    A << 0.8, -0.4, 0, 0, 0.4, 0.8, 0, 0, 0, 0, 0.3, -0.6, 0, 0, 0.6, 0.3;
    B << 1.0, 0.2, 0.0, 0.5, 0.4, 1.0, 0.6, 0.0;
    C << 1.0, 0.0, 0.5, 0.3, 0.2, 0.7, 0.0, 1.0;
    D << 0.2, 0.0, 0.1, 0.3;
    return ss(Domain::DT, A, B, C, D);
}

static SSModel mimo_ct()
{
    MatR A(4, 4), B(4, 2), C(2, 4), D = MatR::Zero(2, 2);
    A << -0.5, 10, 0, 0, -10, -0.5, 0, 0, 0, 0, -3, 40, 0, 0, -40, -3;
    B << 1, 0, 2, 1, 0, 3, 1, 1;
    C << 1, 0, 1, 0, 0, 2, 0, 1;
    return ss(Domain::CT, A, B, C, D);
}

static std::vector<MatC> eval_all(const SSModel &m, const std::vector<double> &om)
{
    std::vector<MatC> G;
    for (double w : om) G.push_back(ss_eval(m, m.domain == Domain::DT ? std::polar(1.0, w) : cd(0, w)));
    return G;
}

static double rel_err_on(const SSModel &a, const SSModel &b, const std::vector<double> &om)
{
    double e = 0, n = 0;
    for (double w : om) {
        const cd x = a.domain == Domain::DT ? std::polar(1.0, w) : cd(0, w);
        e += (ss_eval(a, x) - ss_eval(b, x)).squaredNorm();
        n += ss_eval(b, x).squaredNorm();
    }
    return std::sqrt(e / n);
}

static LmfdSpec spec(int nD, int nN)
{
    LmfdSpec s;
    s.nD = nD;
    s.nN = nN;
    return s;
}

// Cases G1, G2: one CT line at w1 (h = 0.1) with value G, variance 0.01, weighted by its covariance.
static std::vector<WeightedLine> one_line(double w1, cd G)
{
    const FrfData f = exact_data(Domain::CT, 0.1, {w1}, {MatC::Constant(1, 1, G)}, 0.01);
    return weigh(f, Domain::CT, Weight::Cov);
}

static void expect_error(const std::function<void()> &f, const std::string &phrase)
{
    try {
        f();
    } catch (const FitError &e) {
        const std::string m = e.what();
        if (m.find(phrase) == std::string::npos) {
            std::printf("message '%s' lacks '%s'\n", m.c_str(), phrase.c_str());
            fail();
        }
        return;
    }
    std::printf("no error, expected '%s'\n", phrase.c_str());
    fail();
}

// G1: fully constrained b0 / (a1 s + 1) from one line: eq. (56) exactly.
static void g1_closed_form(void **)
{
    const double w1 = 1.0 / std::sqrt(2.0);
    for (cd G : {cd(1.3, -0.6), cd(0.9, -0.85), cd(2.0, 0.3)}) {
        const auto w = one_line(w1, G);
        const ClosedForm cf = lmfd_closed_form(w, Domain::CT, 0.1, spec(1, 0));
        assert_true(cf.unique);
        const double a1 = -G.imag() / (w1 * G.real()), b0 = std::norm(G) / G.real();
        std::printf("G1: a1 %.15g vs %.15g, b0 %.15g vs %.15g\n", cf.model.Dm[0](0, 0), a1, cf.model.Nm[0](0, 0), b0);
        assert_true(std::abs(cf.model.Dm[0](0, 0) - a1) <= 1e-12 * std::abs(a1));
        assert_true(std::abs(cf.model.Nm[0](0, 0) - b0) <= 1e-12 * std::abs(b0));
    }
}

// G2: under-constrained (b1 s + b0)/(a1 s + 1): the kernel is (59), the family contains (56),
// and pinning b0 = 0 gives a1 = Re/(w Im), b1 = |G|^2/(w Im).
static void g2_family(void **)
{
    const double w1 = 1.0 / std::sqrt(2.0);
    const cd G(1.3, -0.6);
    const auto w = one_line(w1, G);
    LmfdSpec s = spec(1, 1);
    const ClosedForm cf = lmfd_closed_form(w, Domain::CT, 0.1, s);
    assert_false(cf.unique);
    assert_int_equal(cf.kernel.cols(), 1);
    VecR K59(3);
    K59 << 1.0 / G.real(), -w1 * G.imag() / G.real(), 1.0;   // order a1, b0, b1 = D1, N0, N1
    const double cosang = std::abs(cf.kernel.col(0).dot(K59)) / (cf.kernel.col(0).norm() * K59.norm());
    std::printf("G2: |cos| between kernel and (59) = %.15f\n", cosang);
    assert_true(std::abs(cosang - 1.0) < 1e-12);
    VecR th = lmfd_pack(cf.model), p56(3);
    p56 << -G.imag() / (w1 * G.real()), std::norm(G) / G.real(), 0.0;
    const VecR dlt = th - p56;
    assert_true((dlt - dlt.dot(K59) / K59.squaredNorm() * K59).norm() < 1e-12 * (1 + dlt.norm()));
    s.pins.push_back(parse_pin("N0=0"));
    const ClosedForm cp = lmfd_closed_form(w, Domain::CT, 0.1, s);
    const double a1 = G.real() / (w1 * G.imag()), b1 = std::norm(G) / (w1 * G.imag());
    assert_true(std::abs(cp.model.Dm[0](0, 0) - a1) <= 1e-12 * std::abs(a1));
    assert_true(std::abs(cp.model.Nm[1](0, 0) - b1) <= 1e-12 * std::abs(b1));
    assert_true(std::abs(cp.model.Nm[0](0, 0)) == 0.0);
}

static std::vector<double> dt_grid(int L) { std::vector<double> o; for (int k = 1; k <= L; ++k) o.push_back(M_PI * (k - 0.5) / L); return o; }
static std::vector<double> ct_grid(int L, double lo, double hi) { std::vector<double> o; for (int k = 0; k < L; ++k) o.push_back(lo * std::pow(hi / lo, (double)k / (L - 1))); return o; }

static void recover(const SSModel &truth, const std::vector<double> &om, int order, int nD, int nN)
{
    const Domain d = truth.domain;
    const double h = d == Domain::CT ? 0.01 : 0.0;
    FrfData f = exact_data(d, h, om, eval_all(truth, om), 1e-6);
    auto w = weigh(f, d, Weight::Cov);
    SubspaceOptions so;
    so.order = order;
    so.estimate_D = truth.D.norm() > 0;
    const SubspaceResult sr = fit_subspace(f, d, w, true, so);
    const double e_sub = rel_err_on(sr.model, truth, om);
    const LmfdSpec s = spec(nD, nN);
    const LmfdModel st = lmfd_sk(w, d, h, s, 30);
    MlOptions mo;
    const MlResult ml = lmfd_ml(w, d, h, s, st, mo, true);
    const SSModel mss = lmfd_to_ss(ml.model);
    const double e_ml = rel_err_on(mss, truth, om);
    std::printf("recover %s %zux%zu n=%d: subspace rel err %.2e (r=%d), ml rel err %.2e cost %.2e\n",
                d == Domain::DT ? "dt" : "ct", (size_t)truth.C.rows(), (size_t)truth.B.cols(), order, e_sub, sr.r, e_ml, ml.cost);
    assert_true(e_sub < 1e-8);
    assert_true(e_ml < 1e-9);
    assert_int_equal((int)sr.model.n(), order);
}

static void recover_dt_siso(void **) { recover(siso_dt(), dt_grid(40), 2, 2, 2); }
static void recover_dt_mimo(void **) { recover(mimo_dt(), dt_grid(60), 4, 2, 2); }
static void recover_ct_siso(void **)
{
    MatR A(2, 2), B(2, 1), C(1, 2), D = MatR::Zero(1, 1);
    A << 0, 1, -400, -8; B << 0, 400; C << 1, 0;
    recover(ss(Domain::CT, A, B, C, D), ct_grid(50, 1, 200), 2, 2, 1);
}
static void recover_ct_mimo(void **) { recover(mimo_ct(), ct_grid(80, 0.5, 400), 4, 2, 1); }

// lmfd_to_ss reproduces the LMFD's response (DT and CT, MIMO).
static void lmfd_realisation(void **)
{
    for (Domain d : {Domain::DT, Domain::CT}) {
        LmfdModel m;
        m.domain = d;
        m.nD = 2;
        m.nN = d == Domain::DT ? 2 : 1;
        MatR D1(2, 2), D2(2, 2), N0(2, 3), N1(2, 3), N2(2, 3);
        D1 << -1.2, 0.2, 0.1, -0.9; D2 << 0.5, 0.0, 0.05, 0.3;
        N0 << 0.1, 0.2, -0.3, 0.0, 0.4, 0.1; N1 << 1, 0, 0.5, 0.2, 1, -0.1; N2 << 0.3, -0.2, 0, 0.1, 0.1, 0.2;
        m.Dm = {D1, D2};
        m.Nm = d == Domain::DT ? std::vector<MatR>{N0, N1, N2} : std::vector<MatR>{N0, N1};
        const SSModel s = lmfd_to_ss(m);
        for (double w : {0.1, 0.7, 2.0}) {
            const cd x = d == Domain::DT ? std::polar(1.0, w) : cd(0, w);
            assert_true((ss_eval(s, x) - lmfd_eval(m, x)).norm() < 1e-12 * (1 + lmfd_eval(m, x).norm()));
        }
    }
}

// --stable: data of an unstable plant give a stable model (poles reflected, B and D refitted).
static void stability_enforced(void **)
{
    SSModel u = siso_dt();
    u.A << 2.1, -1.1025, 1.0, 0.0;              // poles 1.05 e^{+-j...}: unstable
    const auto om = dt_grid(40);
    FrfData f = exact_data(Domain::DT, 0, om, eval_all(u, om), 1e-6);
    auto w = weigh(f, Domain::DT, Weight::Cov);
    SubspaceOptions so;
    so.order = 2;
    const SubspaceResult plain = fit_subspace(f, Domain::DT, w, true, so);
    assert_false(ss_stable(plain.model));
    so.stable = true;
    const SubspaceResult st = fit_subspace(f, Domain::DT, w, true, so);
    std::printf("stability: %d poles reflected, stable %d\n", st.reflected, (int)ss_stable(st.model));
    assert_true(ss_stable(st.model));
    assert_int_equal(st.reflected, 2);
}

// The default of msid fit (stable_auto, refinement). Data of an unstable plant
// keep their unstable poles (the LR test rejects the reflected model); the refinement never raises
// the cost and, from a perturbed A, recovers the exact model (cost -> 0) with its poles kept stable.
static void subspace_refine_and_auto_stability(void **)
{
    SSModel u = siso_dt();
    u.A << 2.1, -1.1025, 1.0, 0.0;
    const auto om = dt_grid(40);
    FrfData f = exact_data(Domain::DT, 0, om, eval_all(u, om), 1e-6);
    auto w = weigh(f, Domain::DT, Weight::Cov);
    SubspaceOptions so;
    so.order = 2;
    so.stable_auto = true;
    so.refine_iter = 30;
    const SubspaceResult r = fit_subspace(f, Domain::DT, w, true, so);
    std::printf("stable by default, unstable plant: stable %d, LR p %.3g, cost %.3g (unconstrained %.3g)\n",
                (int)ss_stable(r.model), r.stable_lr_p, r.cost, r.cost_unconstrained);
    // stable by default, whatever the likelihood ratio says (it is reported, and tiny here: the data
    // are an unstable plant's, for which --allow-unstable is meant)
    assert_true(ss_stable(r.model));
    assert_true(r.stable_lr_p >= 0 && r.stable_lr_p < 0.01);
    so.stable_auto = false;   // --allow-unstable: the unconstrained refinement
    const SubspaceResult ru = fit_subspace(f, Domain::DT, w, true, so);
    assert_false(ss_stable(ru.model));
    assert_true(ru.cost <= ru.cost_unrefined * (1 + 1e-9) + 1e-6);   // exact data: both at round-off (1e-10)

    const SSModel t = mimo_dt();
    FrfData f2 = exact_data(Domain::DT, 0, om, eval_all(t, om), 1e-6);
    auto w2 = weigh(f2, Domain::DT, Weight::Cov);
    SSModel m = t;
    m.A *= 0.97;   // stable, off the truth
    const double V0 = fit_BD(m, w2, true);
    const SubspaceRefine rr = refine_subspace(m, w2, true, true, 60);
    std::printf("refinement from a perturbed A: cost %.3g -> %.3g in %d steps\n", V0, rr.cost, rr.iterations);
    assert_true(rr.refined && rr.cost <= V0);
    assert_true(rr.cost < 1e-6 * V0);
    assert_true(ss_stable(m));
    assert_true(weighted_cost_ss(m, w2) == rr.cost);
}

// A DT state-space model carried over exactly into the LMFD of degree nD = n / ny (ml's LMFD start),
// and the pooled weights: pooled where the dof are few and the covariances equal, not where a
// neighbour's correlations differ at the same trace (the whole-matrix test), nor where the dof are many.
static void lmfd_from_ss_and_pooling(void **)
{
    const SSModel t = mimo_dt();
    LmfdModel l;
    assert_true(ss_to_lmfd_dt(t, (int)t.n() / (int)t.C.rows(), l));
    for (double w : {0.05, 0.7, 2.0, 3.1}) {
        const cd z = std::polar(1.0, w);
        assert_true((lmfd_eval(l, z) - ss_eval(t, z)).norm() < 1e-10 * ss_eval(t, z).norm());
    }
    assert_false(ss_to_lmfd_dt(t, 1, l));   // another order

    // 2 x 1 FRF (g = 2), 40 lines of equal covariance, except line 20 whose correlation flips sign
    // (the same trace: the trace test pooled it)
    auto lines = [](double dof) {
        std::vector<WeightedLine> w(40);
        for (size_t k = 0; k < w.size(); ++k) {
            WeightedLine &l = w[k];
            l.x = std::polar(1.0, 0.05 * (double)(k + 1));
            l.real = false;
            l.G = MatC::Zero(2, 1);
            l.cov = MatC(2, 2);
            const double c = k == 20 ? -0.8 : 0.8;
            l.cov << 1.0, c, c, 1.0;
            l.dof = dof;
            l.Linv = MatC(Eigen::LLT<MatC>(l.cov).matrixL()).inverse();
        }
        return w;
    };
    auto w = lines(10);
    const PoolStats st = smooth_weights(w, 4);
    std::printf("pooling, 10 dof: %zu of %zu lines pooled, %zu neighbours left out\n", st.pooled, st.lines, st.left_out);
    assert_true(st.pooled == 39 && st.precise == 0);   // line 20 has no equal neighbour
    assert_true(st.left_out == 16);   // line 20 refused by its 8 neighbours, and they by it
    assert_true(std::abs(w[20].dof - 10.0) < 1e-12 && std::abs(w[19].dof - 80.0) < 1e-12);
    assert_true(std::abs(w[19].cov(0, 1).real() - 0.8) < 1e-12);
    auto wp = lines(1000);   // 1000/997: precise own weights
    const PoolStats sp = smooth_weights(wp, 4);
    assert_true(sp.pooled == 0 && sp.precise == 40 && wp[19].dof == 1000.0);
}

static void distances(void **)
{
    const SSModel a = mimo_dt();
    SSModel b = a;
    b.C *= 2.0;
    b.D *= 2.0;
    const Distance d0 = ss_distance(a, a), d1 = ss_distance(a, b);
    std::printf("distance: self %.2e %.2e, half %.6f %.6f\n", d0.h2, d0.hinf, d1.h2, d1.hinf);
    assert_true(d0.h2 < 1e-12 && d0.hinf < 1e-12);
    assert_true(std::abs(d1.h2 - 0.5) < 1e-9 && std::abs(d1.hinf - 0.5) < 1e-6);
    const SSModel c = mimo_ct();
    SSModel c2 = c;
    c2.C *= 2.0;
    const Distance dc = ss_distance(c, c2);
    assert_true(std::abs(dc.h2 - 0.5) < 1e-8 && std::abs(dc.hinf - 0.5) < 1e-6);
    SSModel u = a;
    u.A(0, 0) = 1.5;
    expect_error([&] { ss_distance(u, a); }, "stable");
}

static void errors(void **)
{
    const SSModel t = siso_dt();
    const auto om = dt_grid(6);
    FrfData f = exact_data(Domain::DT, 0, om, eval_all(t, om), 1e-4);
    auto w = weigh(f, Domain::DT, Weight::Cov);
    SubspaceOptions so;
    so.order = 5;
    expect_error([&] { fit_subspace(f, Domain::DT, w, true, so); }, "the largest order these lines support is");
    // too few periods behind the weights (dof 2 = 3 periods)
    FrfData f3 = f;
    for (auto &l : f3.lines) l.dof = 2;
    auto w3 = weigh(f3, Domain::DT, Weight::Cov);
    so.order = 1;
    expect_error([&] { fit_subspace(f3, Domain::DT, w3, true, so); }, "need M >= 4");
    // singular weights, naming the line
    FrfData fz = f;
    fz.lines[3].cov.setZero();
    expect_error([&] { weigh(fz, Domain::DT, Weight::Cov); }, "singular weights at line bin 4");
    // missing covariance
    FrfData fm = f;
    fm.lines[1].cov.resize(0, 0);
    expect_error([&] { weigh(fm, Domain::DT, Weight::Cov); }, "needs the FRF covariance");
    // over-constrained closed form
    LmfdSpec s = spec(1, 1);
    expect_error([&] { lmfd_closed_form(w, Domain::DT, 0, s); }, "over-constrained");
    // non-convergence: one iteration from a poor start
    MlOptions mo;
    mo.max_iter = 1;
    s = spec(2, 2);
    LmfdModel st = lmfd_sk(w, Domain::DT, 0, s, 0);
    st.Dm[0](0, 0) += 0.3;
    // (not an error any more — the best iterate comes back marked not converged, with its gradient)
    {
        const MlResult nc = lmfd_ml(w, Domain::DT, 0, s, st, mo, true);
        assert_false(nc.converged);
        assert_int_equal(nc.iterations, 1);
        assert_true(nc.grad_norm > 0 && std::isfinite(nc.cost));
        mo.max_iter = 200;
        assert_true(lmfd_ml(w, Domain::DT, 0, s, st, mo, true).converged);   // negative control
    }
    // a CT file fitted with a DT model
    FrfData fc = exact_data(Domain::CT, 0.1, {1.0, 2.0, 3.0}, {MatC::Ones(1, 1), MatC::Ones(1, 1), MatC::Ones(1, 1)}, 1e-3);
    expect_error([&] { weigh(fc, Domain::DT, Weight::Cov); }, "continuous-time FRF");
    expect_error([&] { parse_pin("Q0=1"); }, "expected e.g.");
}

// --pin and --order a:b are read by hand (text_scan.hpp, no <regex>: compile time); the
// grammars they replaced, ^\s*([DN])(\d+)(?:\[(\d+),(\d+)\])?\s*=\s*([-+0-9.eE]+)\s*$ and
// ^(\d+):(?:(\d+):)?(\d+)$, accept exactly these and refuse every near miss below.
static void option_parsers(void **)
{
    const Pin a = parse_pin(" D12[3,4] = -1.5e-2 ");
    assert_int_equal(a.mat, 'D');
    assert_int_equal(a.index, 12);
    assert_int_equal(a.row, 2);
    assert_int_equal(a.col, 3);
    assert_true(a.value == -1.5e-2);
    const Pin b = parse_pin("N0=0");
    assert_int_equal(b.mat, 'N');
    assert_int_equal(b.index, 0);
    assert_int_equal(b.row, -1);   // every entry
    assert_true(b.value == 0.0);
    for (const char *bad : {"Q0=1", "D=1", "D1", "D1=", "D1[1,2]=", "D1[1,]=0", "D1[,2]=0", "D1[1,2=0", "D1[12]=0",
                            "D1[1,2]=0.5x", "d1=0", "D1 [1,2]=0", "D1[1, 2]=0", "", "=1", "D1==1"})
        expect_error([&] { parse_pin(bad); }, "expected e.g.");
    expect_error([&] { parse_pin("N0=e"); }, "bad value");   // the characters fit, the number does not
    const std::vector<int> r = parse_order_range("2:6", 2, 100, nullptr);
    assert_true(r == std::vector<int>({2, 4, 6}));
    const std::vector<int> st = parse_order_range("1:3:10", 1, 100, nullptr);
    assert_true(st == std::vector<int>({1, 4, 7, 10}));
    for (const char *bad : {"3:", ":3", "3:5:", "3::5", "3:5:7:9", "a:b", "3-5", " 3:5", "3:5 ", "+3:5"})
        expect_error([&] { parse_order_range(bad, 1, 100, nullptr); }, "expected a positive integer");
}

int main()
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(g1_closed_form),
        cmocka_unit_test(g2_family),
        cmocka_unit_test(recover_dt_siso),
        cmocka_unit_test(recover_dt_mimo),
        cmocka_unit_test(recover_ct_siso),
        cmocka_unit_test(recover_ct_mimo),
        cmocka_unit_test(lmfd_realisation),
        cmocka_unit_test(stability_enforced),
        cmocka_unit_test(subspace_refine_and_auto_stability),
        cmocka_unit_test(lmfd_from_ss_and_pooling),
        cmocka_unit_test(distances),
        cmocka_unit_test(errors),
        cmocka_unit_test(option_parsers),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
