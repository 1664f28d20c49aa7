// Monte Carlo tests (fixed seeds) of the modal fit, through the real core
// (design -> simulated plant + noise -> msid_meas -> msid_frf -> fit):
//  - modal parameters of a lightly damped 3-mode structure (accelerance, CT ml):
//    the delta-method standard deviations of natural frequency, damping ratio and
//    residue match the empirical spread within 15%;
//  - order selection (p-value rule over a stabilisation scan) picks the true
//    order in >= 90% of runs at 40 dB; a noiseless scan marks the true poles stable;
//  - nonlinear distortion (robust BLA over random-phase realisations): with a
//    static cubic output nonlinearity the distortion is detected, the total
//    covariance and the distortion variance match the Monte Carlo spread, the
//    noise variance is unbiased; a linear plant gives distortion ~ 0 (negative control).
#include "bla.hpp"
#include "fit_sim.hpp"
#include "lmfd_fit.hpp"
#include "modal.hpp"
#include "order_select.hpp"
#include "stats.hpp"
#include "subspace.hpp"

#include <cmath>
#include <cstdio>
#include <cstdarg>
#include <cstddef>
#include <csetjmp>
#include <cstdint>
extern "C" {
#include <cmocka.h>
}

using namespace msidfit;
using msidstat::BlaLine;   // the robust BLA (tools/frfstat)
using msidstat::bla_line;
using msidstat::bla_summary;

static double min_dof(const std::vector<WeightedLine> &w)
{
    double n = 1e300;
    for (const auto &l : w) n = std::min(n, l.dof);
    return n;
}

using fitsim::CtBench;

// ---------------- modal parameters: delta-method sd against the Monte Carlo spread ----------------

static void modal_sd_matches_spread(void **)
{
    MatR phi(1, 3), psi(1, 3);
    phi << 1.0, 0.8, 0.6;
    psi << 1.0, 1.0, 1.0;
    const SSModel pl = fitsim::structure({3.0, 5.1, 8.3}, {0.02, 0.01, 0.005}, phi, psi);
    CtBench cb(pl, 2048, 180, 8, 40.0, 41, 41);   // 2.0 .. 10.7 Hz
    fitsim::Runner run(cb.b);
    LmfdSpec s;
    s.nD = 6;
    s.nN = 6;   // accelerance: feedthrough
    const double h = 0.01;
    msid_rng rng;
    msid_rng_seed(&rng, 2026);
    const std::vector<Mode> truth = modes_of(pl, 0);
    const int runs = 300, nm = 3, nq = 4;   // fn, zeta, Re R, Im R per mode
    std::vector<std::vector<double>> val(nm * nq), sd(nm * nq);
    LmfdModel start;
    MlOptions mo;
    for (int r = 0; r < runs; ++r) {
        const FrfData f = run.run(rng);
        const auto w = weigh(f, Domain::CT, Weight::Cov);
        if (r == 0) {
            std::vector<MatC> exact;
            for (const auto &l : w) exact.push_back(ss_eval(pl, l.x));
            start = lmfd_sk(w, Domain::CT, h, s, 50, &exact);   // the true LMFD coefficients
        }
        const MlResult res = lmfd_ml(w, Domain::CT, h, s, start, mo, false);
        double ws = 1.0;
        lmfd_realise_scaled(res.model, &ws);
        auto realise = [&](const VecR &t) {
            LmfdModel lm = lmfd_unpack(t, s, 1, 1, Domain::CT, h);
            for (int i = 1; i <= lm.nD; ++i) lm.Dm[(size_t)i - 1] *= std::pow(ws, i);
            for (int i = 0; i <= lm.nN; ++i) lm.Nm[(size_t)i] *= std::pow(ws, i);
            return lmfd_to_ss(lm);
        };
        const std::vector<Mode> m = modes_with_sd(realise, res.theta, res.cov, 0.0, ws);
        assert_int_equal((int)m.size(), nm);
        for (int k = 0; k < nm; ++k) {
            const double q[nq] = {m[k].fn, m[k].zeta, m[k].residue(0, 0).real(), m[k].residue(0, 0).imag()};
            const double e[nq] = {m[k].sd_fn, m[k].sd_zeta, m[k].sd_residue_re(0, 0), m[k].sd_residue_im(0, 0)};
            for (int i = 0; i < nq; ++i) { val[k * nq + i].push_back(q[i]); sd[k * nq + i].push_back(e[i]); }
        }
    }
    const char *names[nq] = {"fn", "zeta", "Re R", "Im R"};
    for (int k = 0; k < nm; ++k)
        for (int i = 0; i < nq; ++i) {
            const auto &v = val[k * nq + i], &e = sd[k * nq + i];
            double mu = 0, s2 = 0, rep = 0;
            for (double x : v) mu += x / runs;
            for (double x : v) s2 += (x - mu) * (x - mu) / (runs - 1);
            for (double x : e) rep += x * x / runs;
            const double ratio = std::sqrt(rep / s2);
            const double tv = i == 0 ? truth[k].fn : i == 1 ? truth[k].zeta
                              : i == 2 ? truth[k].residue(0, 0).real() : truth[k].residue(0, 0).imag();
            std::printf("mode %d %-5s true %-11.5g mean %-11.5g bias/sd %+6.3f  sd emp %-10.3g reported %-10.3g ratio %.3f\n",
                        k + 1, names[i], tv, mu, (mu - tv) / std::sqrt(s2), std::sqrt(s2), std::sqrt(rep), ratio);
            assert_true(ratio > 0.85 && ratio < 1.15);
            assert_true(std::fabs(mu - tv) < 4 * std::sqrt(s2 / runs) + 0.1 * std::sqrt(s2));
        }
}

// Exact modal parameters of the structure generator (negative control of the
// conversion: a wrong damping or frequency map fails here).
static void modal_exact_noiseless(void **)
{
    MatR phi(2, 2), psi(1, 2);
    phi << 1.0, 0.5, -0.4, 1.0;
    psi << 1.0, 2.0;
    const SSModel pl = fitsim::structure({1.5, 4.0}, {0.01, 0.02}, phi, psi);
    const std::vector<Mode> m = modes_of(pl, 0);
    assert_int_equal((int)m.size(), 2);
    assert_true(std::fabs(m[0].fn - 1.5) < 1e-9 && std::fabs(m[1].fn - 4.0) < 1e-9);
    assert_true(std::fabs(m[0].zeta - 0.01) < 1e-12 && std::fabs(m[1].zeta - 0.02) < 1e-12);
    // residue of s^2 phi psi^T / (s^2 + 2 z w s + w^2) at lambda: phi psi^T lambda^2 / (lambda - conj lambda)
    for (int k = 0; k < 2; ++k) {
        const cd l = m[k].pole;
        const MatC R = (phi.col(k) * psi.col(k).transpose()).cast<cd>() * (l * l / (l - std::conj(l)));
        assert_true((m[k].residue - R).norm() < 1e-9 * R.norm());
    }
    // the same structure sampled: DT poles map back through ln(z)/h
    SSModel d = pl;
    d.domain = Domain::DT;
    const double h = 0.01;
    Eigen::EigenSolver<MatR> es(pl.A);
    d.A = (es.eigenvectors() * (es.eigenvalues() * h).array().exp().matrix().asDiagonal() * es.eigenvectors().inverse()).real();
    const std::vector<Mode> md = modes_of(d, h);
    assert_true(std::fabs(md[1].fn - 4.0) < 1e-9 && std::fabs(md[1].zeta - 0.02) < 1e-9);
}

// ---------------- order selection ----------------

static std::function<OrderFit(int)> ml_fitter(const FrfData &f, const std::vector<WeightedLine> &w)
{
    return [&f, &w](int n) {
        LmfdSpec s;
        s.nD = n;
        s.nN = n;   // accelerance
        SubspaceOptions so;
        so.order = n;
        const SubspaceResult sr = fit_subspace(f, Domain::CT, w, true, so);
        std::vector<MatC> target;
        for (const auto &l : w) target.push_back(ss_eval(sr.model, l.x));
        const LmfdModel st = lmfd_sk(w, Domain::CT, f.h, s, 30, &target);
        const MlResult r = lmfd_ml(w, Domain::CT, f.h, s, st, MlOptions{}, false);
        OrderFit o;
        o.ok = true;
        o.model = lmfd_to_ss(r.model);
        o.cost = r.cost;
        o.dof = r.dof;
        const CostLaw law = cost_law(r.dof, min_dof(w), 1.0);
        o.expected = law.mean;
        o.p_value = cost_pvalue(law, r.cost);
        return o;
    };
}

static void order_selection_true_order(void **)
{
    MatR phi(1, 2), psi(1, 2);
    phi << 1.0, 0.7;
    psi << 1.0, 1.0;
    const SSModel pl = fitsim::structure({3.0, 8.0}, {0.02, 0.01}, phi, psi);
    CtBench cb(pl, 1024, 120, 8, 40.0, 7);
    fitsim::Runner run(cb.b);
    msid_rng rng;
    msid_rng_seed(&rng, 4040);
    const int runs = 100;
    int hit = 0, over = 0, under = 0;
    const std::vector<int> orders = parse_order_range("auto", 1, 10, nullptr);
    for (int r = 0; r < runs; ++r) {
        const FrfData f = run.run(rng);
        const auto w = weigh(f, Domain::CT, Weight::Cov);
        const OrderSelection sel = select_order(orders, ml_fitter(f, w), f.h, 0.05, StabTol{}, true);
        hit += sel.chosen == 4;
        over += sel.chosen > 4;
        under += sel.chosen < 4;
    }
    std::printf("order selection at 40 dB: true order 4 chosen in %d/%d runs (%d above, %d below)\n", hit, runs, over, under);
    assert_true(hit >= 90);
}

static void stabilisation_noiseless(void **)
{
    MatR phi(1, 2), psi(1, 2);
    phi << 1.0, 0.7;
    psi << 1.0, 1.0;
    const SSModel pl = fitsim::structure({3.0, 8.0}, {0.02, 0.01}, phi, psi);
    CtBench cb(pl, 1024, 120, 8, 120.0, 7);   // practically noiseless
    fitsim::Runner run(cb.b);
    msid_rng rng;
    msid_rng_seed(&rng, 5);
    const FrfData f = run.run(rng);
    const auto w = weigh(f, Domain::CT, Weight::Cov);
    // subspace: ml at orders above the truth is degenerate on noiseless data (pole-zero cancellations)
    auto sub = [&](int n) {
        SubspaceOptions so;
        so.order = n;
        const SubspaceResult sr = fit_subspace(f, Domain::CT, w, true, so);
        OrderFit o;
        o.ok = true;
        o.model = sr.model;
        o.cost = sr.cost;
        o.dof = real_equations(w) - n * 2 - 1;
        const CostLaw law = cost_law(o.dof, min_dof(w), 1.0);
        o.expected = law.mean;
        o.p_value = cost_pvalue(law, o.cost);
        return o;
    };
    const OrderSelection sel = select_order({2, 4, 5, 6}, sub, f.h);
    assert_int_equal(sel.chosen, 4);
    // at orders 5 and 6 both structural modes are settled against the previous order
    for (size_t i = 2; i < sel.rows.size(); ++i) {
        const auto &row = sel.rows[i];
        assert_true(row.fit.ok);
        int found = 0;
        for (const auto &p : row.poles)
            if (p.stable() && (std::fabs(p.mode.fn - 3.0) < 0.01 || std::fabs(p.mode.fn - 8.0) < 0.01)) ++found;
        assert_int_equal(found, 2);
    }
    assert_int_equal(sel.rows[1].n_stable, 0);   // order 4 after order 2: the 8 Hz mode is new
    const Json j = order_selection_json(sel);
    assert_true(j["chosen"] == 4 && j["orders"].size() == 4);
}

// ---------------- nonlinear distortion: robust BLA ----------------

// DT plant x = G(q) u, y = x + a x^3 (static cubic output nonlinearity, per output).
static std::function<void(const tsim_design &, uint32_t, size_t, double *)> cubic_plant(const SSModel &m, double a)
{
    auto lin = fitsim::dt_plant(m);
    const uint32_t ny = (uint32_t)m.C.rows();
    return [lin, a, ny](const tsim_design &t, uint32_t e, size_t n, double *rows) {
        lin(t, e, n, rows);
        const uint32_t C = t.d.n_inputs + ny;
        for (size_t k = 0; k < n; ++k)
            for (uint32_t i = 0; i < ny; ++i) {
                double &y = rows[k * C + t.d.n_inputs + i];
                y += a * y * y * y;
            }
    };
}

struct BlaMc {
    std::vector<double> emp;            // per line and entry: empirical variance of G_BLA over runs
    std::vector<double> cov, noise, nl; // per line and entry: mean reported total, noise, distortion variance
    int detected = 0;
};

// SISO: a second-order DT plant; 2x2 (nu = 2, DFT pattern with m = 2 experiments per realisation):
// two coupled second-order channels.
static SSModel bla_plant(uint32_t n)
{
    SSModel m;
    m.domain = Domain::DT;
    if (n == 1) {
        m.A = MatR(2, 2);
        m.A << 1.5, -0.7, 1.0, 0.0;
        m.B = MatR(2, 1);
        m.B << 1.0, 0.0;
        m.C = MatR(1, 2);
        m.C << 0.5, 0.0;
    } else {
        m.A = MatR::Zero(4, 4);
        m.A.topLeftCorner(2, 2) << 1.5, -0.7, 1.0, 0.0;
        m.A.bottomRightCorner(2, 2) << 1.2, -0.6, 1.0, 0.0;
        m.B = MatR::Zero(4, 2);
        m.B(0, 0) = 1.0; m.B(2, 1) = 1.0; m.B(0, 1) = 0.3;
        m.C = MatR::Zero(2, 4);
        m.C(0, 0) = 0.5; m.C(1, 2) = 0.5; m.C(1, 0) = 0.2;
    }
    m.D = MatR::Zero(m.C.rows(), m.B.cols());
    return m;
}

static BlaMc bla_mc(double a, int runs, uint32_t R, uint32_t n = 1)
{
    const SSModel m = bla_plant(n);
    static std::vector<uint32_t> bins;
    bins.clear();
    for (uint32_t b = 1; b <= 40; ++b) bins.push_back(b);
    const size_t L = bins.size(), g = (size_t)n * n;
    BlaMc out;
    out.emp.assign(L * g, 0);
    out.cov.assign(L * g, 0);
    out.noise.assign(L * g, 0);
    out.nl.assign(L * g, 0);
    std::vector<cd> sum(L * g, 0.0);
    std::vector<double> sum2(L * g, 0.0);
    msid_rng rng;
    msid_rng_seed(&rng, 999 + n);
    for (int r = 0; r < runs; ++r) {
        std::vector<std::vector<MatC>> G(L), C(L);
        std::vector<std::vector<double>> dof(L);
        for (uint32_t q = 0; q < R; ++q) {
            fitsim::Bench b;
            b.design.period = 256; b.design.n_lines = (uint32_t)L; b.design.bins = bins.data();
            b.design.n_inputs = n; b.design.n_experiments = n; b.design.seed = 100000 + (uint64_t)r * R + q;
            b.ny = n; b.K = 4; b.sigma_y = 0.05; b.clean = cubic_plant(m, a);
            fitsim::Runner run(b);
            const FrfData f = run.run(rng);
            for (size_t l = 0; l < L; ++l) {
                G[l].push_back(f.lines[l].G);
                C[l].push_back(f.lines[l].cov);
                dof[l].push_back(f.lines[l].dof);
            }
        }
        std::vector<BlaLine> bl;
        for (size_t l = 0; l < L; ++l) {
            const BlaLine x = bla_line(G[l], C[l], dof[l]);
            for (size_t i = 0; i < g; ++i) {
                const size_t k = l * g + i;
                sum[k] += x.G.data()[i];
                sum2[k] += std::norm(x.G.data()[i]);
                out.cov[k] += x.cov((Eigen::Index)i, (Eigen::Index)i).real() / runs;
                out.noise[k] += x.cov_noise((Eigen::Index)i, (Eigen::Index)i).real() / runs;
                out.nl[k] += x.var_nl((Eigen::Index)i) / runs;
            }
            bl.push_back(x);
        }
        out.detected += bla_summary(bl).detected;
    }
    for (size_t k = 0; k < L * g; ++k) out.emp[k] = (sum2[k] - std::norm(sum[k]) / runs) / (runs - 1);
    return out;
}

static double ratio_sum(const std::vector<double> &a, const std::vector<double> &b)
{
    double x = 0, y = 0;
    for (size_t i = 0; i < a.size(); ++i) { x += a[i]; y += b[i]; }
    return x / y;
}

static void bla_case(uint32_t n, int runs, double a)
{
    const uint32_t R = 6;
    const BlaMc lin = bla_mc(0.0, runs, R, n), cub = bla_mc(a, runs, R, n);
    // linear plant: the noise covariance is the spread, no distortion (negative control)
    const double lin_noise = ratio_sum(lin.noise, lin.emp), lin_total = ratio_sum(lin.cov, lin.emp);
    const double lin_nl = ratio_sum(lin.nl, lin.noise);
    // cubic plant: total covariance = spread; distortion = spread - noise spread; noise unbiased
    const double cub_total = ratio_sum(cub.cov, cub.emp), cub_noise = ratio_sum(cub.noise, lin.emp);
    std::vector<double> nl_emp(cub.emp.size());
    for (size_t l = 0; l < nl_emp.size(); ++l) nl_emp[l] = cub.emp[l] - lin.emp[l];
    const double cub_nl = ratio_sum(cub.nl, nl_emp), nl_db = 10 * std::log10(ratio_sum(cub.nl, cub.noise));
    std::printf("%ux%u linear: noise/spread %.3f total/spread %.3f distortion/noise %+.3f detected %d/%d\n", n, n,
                lin_noise, lin_total, lin_nl, lin.detected, runs);
    std::printf("%ux%u cubic:  total/spread %.3f noise/linear spread %.3f distortion/(spread - noise spread) %.3f "
                "(distortion %.1f dB over noise) detected %d/%d\n",
                n, n, cub_total, cub_noise, cub_nl, nl_db, cub.detected, runs);
    assert_true(lin_noise > 0.9 && lin_noise < 1.1);
    assert_true(lin_total > 0.9 && lin_total < 1.1);
    assert_true(std::fabs(lin_nl) < 0.1);
    assert_true(lin.detected <= runs / 10);
    assert_true(cub_total > 0.85 && cub_total < 1.15);
    assert_true(cub_noise > 0.9 && cub_noise < 1.1);
    assert_true(cub_nl > 0.85 && cub_nl < 1.15);
    assert_true(cub.detected >= runs * 95 / 100);
    assert_true(nl_db > 3.0);
}

static void bla_noise_and_distortion(void **) { bla_case(1, 150, 1e-4); }        // mild: ~27 dB over the noise
static void bla_noise_and_distortion_2x2(void **) { bla_case(2, 100, 1e-4); }

// F and binomial tails against values known in closed form.
static void tails(void **)
{
    // F(2, 2n): P(F > x) = (1 + x/n)^-n
    for (double n : {3.0, 10.0, 57.0})
        for (double x : {0.1, 1.0, 4.0}) assert_true(std::fabs(f_sf(2, 2 * n, x) - std::pow(1 + x / n, -n)) < 1e-12);
    // P(Bin(10, 0.5) >= 8) = 56/1024
    assert_true(std::fabs(binom_sf(10, 0.5, 8) - 56.0 / 1024) < 1e-12);
    assert_true(binom_sf(10, 0.01, 0) == 1.0);
}

int main()
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(tails),
        cmocka_unit_test(modal_exact_noiseless),
        cmocka_unit_test(modal_sd_matches_spread),
        cmocka_unit_test(stabilisation_noiseless),
        cmocka_unit_test(order_selection_true_order),
        cmocka_unit_test(bla_noise_and_distortion),
        cmocka_unit_test(bla_noise_and_distortion_2x2),
    };
    return cmocka_run_group_tests(tests, nullptr, nullptr);
}
