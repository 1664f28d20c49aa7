// Monte Carlo tests (fixed seeds) of the stable pole-residue ML at the stability bound, through the
// real core (design -> simulated CT plant + noise -> msid_meas -> msid_frf -> weights -> pr_ml):
//  - a plant with one undamped mode: the stable fit holds that pole on the bound in about half the
//    runs, and there its bound direction gets no variance (no delta-method sd); every pole not held has
//    one; the other modes keep their sd: their natural frequency and damping
//    ratio have the empirical spread of the reported sd (within 15%) and their 95% intervals cover the
//    truth at a rate inside the binomial 99.9% range;
//  - the same plant with that mode damped (0.4%): no pole is held, the same sd and coverage, and the
//    stable fit is the unconstrained one (the same parameters and covariance);
//  - the continuation through a double real pole: two real poles started where the data want a pair
//    end as the pair (the cost it reaches with a pair start).
#include "fit_sim.hpp"
#include "poleres.hpp"
#include "stab_bound.hpp"
#include "stats.hpp"

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

namespace {

// fn [Hz] and zeta of a CT pole p = a + j b with their delta-method sd from the 2 x 2 covariance of (a, b).
struct Fz {
    double fn, zeta, sd_fn, sd_zeta;
};

Fz fn_zeta(cd p, const MatR &c)
{
    const double a = p.real(), b = p.imag(), r = std::abs(p);
    Eigen::RowVector2d gf(a / r, b / r), gz(-b * b / (r * r * r), a * b / (r * r * r));   // d|p|, d(-a/|p|)
    gf /= 2 * M_PI;
    return {r / (2 * M_PI), -a / r, std::sqrt((gf * c * gf.transpose())(0)), std::sqrt((gz * c * gz.transpose())(0))};
}

const double FN_TRUE[2] = {3.0, 5.1}, Z_TRUE[2] = {0.02, 0.01};

// Modes at 3.0 and 5.1 Hz and a third at 8.325 Hz (midway between two lines) of damping zeta3.
SSModel plant(double zeta3)
{
    MatR phi(1, 3), psi(1, 3);
    phi << 1.0, 0.8, 0.3;
    psi << 1.0, 1.0, 1.0;
    return fitsim::structure({3.0, 5.1, 8.325}, {0.02, 0.01, zeta3}, phi, psi);
}

PrOptions options(bool stable)
{
    PrOptions o;
    o.order = 6;
    o.feedthrough = Feedthrough::Yes;   // accelerance
    o.stable = stable;
    o.max_iter = 400;
    return o;
}

// Records of plant(zeta3) on 2.0 .. 10.7 Hz (180 lines, 8 periods) at the given SNR, weighted: one per next().
struct Records {
    fitsim::CtBench cb;
    fitsim::Runner run;
    msid_rng rng;
    double h = 0;
    Records(double zeta3, double snr_db, uint64_t seed) : cb(plant(zeta3), 2048, 180, 8, snr_db, seed, 41), run(cb.b)
    {
        msid_rng_seed(&rng, seed + 1950);
    }
    std::vector<WeightedLine> next()
    {
        const FrfData f = run.run(rng);
        h = f.h;
        return weigh(f, Domain::CT, Weight::Cov);
    }
};

// Index of the pole of `m` nearest to fn [Hz].
size_t nearest(const PoleResidueModel &m, double fn)
{
    size_t k = 0;
    for (size_t j = 1; j < m.poles.size(); ++j)
        if (std::abs(std::abs(m.poles[j]) / (2 * M_PI) - fn) < std::abs(std::abs(m.poles[k]) / (2 * M_PI) - fn)) k = j;
    return k;
}

// The parameter index of pole k's real part in PrResult::theta (poles first, 1 or 2 each).
Eigen::Index pole_index(const PoleResidueModel &m, size_t k)
{
    Eigen::Index i = 0;
    for (size_t j = 0; j < k; ++j) i += m.poles[j].imag() > 0 ? 2 : 1;
    return i;
}

}  // namespace

// The Monte Carlo of the plant with its third mode's damping zeta3: the runs' modes at 3.0 and 5.1 Hz
// (fn, zeta, their sd) and how often the pole near 8.3 Hz was held on the bound (alone, without
// variance); where it was not, its damping's sd is finite and positive.
struct Mc {
    std::vector<double> v[2][2], e[2][2];
    int held = 0, used = 0;
};

static Mc run_mc(double zeta3, int runs, uint64_t seed)
{
    Records rec(zeta3, 40.0, seed);
    Mc mc;
    for (int r = 0; r < runs; ++r) {
        const auto w = rec.next();
        const PrResult res = pr_ml(w, Domain::CT, rec.h, options(true));
        assert_true(ss_stable(pr_to_ss(res.model)));
        const size_t k3 = nearest(res.model, 8.3);
        int n_held = 0;
        for (size_t k = 0; k < res.at_bound.size(); ++k) n_held += res.at_bound[k];
        const Eigen::Index i3 = pole_index(res.model, k3);
        const bool held = n_held == 1 && res.at_bound[k3] && res.cov.row(i3).cwiseAbs().maxCoeff() == 0.0 &&
                          res.model.poles[k3].real() < 0 && -res.model.poles[k3].real() < 1e-6 * std::abs(res.model.poles[k3]);
        mc.held += held;
        if (!held) {
            const Fz q3 = fn_zeta(res.model.poles[k3], res.cov.block(i3, i3, 2, 2));
            assert_true(std::isfinite(q3.sd_zeta) && q3.sd_zeta > 0);
        }
        // a held pole's bound direction has no variance; every other pole's damping has a variance
        for (size_t k = 0; k < res.model.poles.size(); ++k) {
            const Eigen::Index i = pole_index(res.model, k);
            if (res.at_bound[k]) assert_true(res.cov.row(i).cwiseAbs().maxCoeff() == 0.0);
            else assert_true(res.cov(i, i) > 0);
        }
        ++mc.used;
        for (int m = 0; m < 2; ++m) {
            const size_t k = nearest(res.model, FN_TRUE[m]);
            const Eigen::Index i = pole_index(res.model, k);
            const Fz q = fn_zeta(res.model.poles[k], res.cov.block(i, i, 2, 2));
            mc.v[m][0].push_back(q.fn);
            mc.v[m][1].push_back(q.zeta);
            mc.e[m][0].push_back(q.sd_fn);
            mc.e[m][1].push_back(q.sd_zeta);
        }
    }
    return mc;
}

// sd against the spread (within 15%), 95% coverage of the truth inside the binomial 99.9% range.
static void check_sd_and_coverage(const Mc &mc)
{
    const int n = mc.used;
    int lo = 0, hi = n;
    while (1.0 - binom_sf(n, 0.95, lo + 1) < 5e-4) ++lo;
    while (binom_sf(n, 0.95, hi - 1) < 5e-4) --hi;
    const char *nm[2] = {"fn", "zeta"};
    for (int m = 0; m < 2; ++m)
        for (int j = 0; j < 2; ++j) {
            const std::vector<double> &v = mc.v[m][j], &e = mc.e[m][j];
            const double tv = j ? Z_TRUE[m] : FN_TRUE[m];
            double mu = 0, s2 = 0, rep = 0;
            int cover = 0;
            for (double x : v) mu += x / n;
            for (double x : v) s2 += (x - mu) * (x - mu) / (n - 1);
            for (double x : e) rep += x * x / n;
            for (size_t r = 0; r < v.size(); ++r) cover += std::fabs(v[r] - tv) <= 1.959964 * e[r];
            const double ratio = std::sqrt(rep / s2);
            std::printf("mode %.1f Hz %-4s bias/sd %+6.3f  sd emp %-10.3g reported %-10.3g ratio %.3f  coverage %d/%d "
                        "(binomial range %d..%d)\n",
                        FN_TRUE[m], nm[j], (mu - tv) / std::sqrt(s2), std::sqrt(s2), std::sqrt(rep), ratio, cover, n, lo, hi);
            assert_true(ratio > 0.85 && ratio < 1.15);
            assert_true(cover >= lo && cover <= hi);
        }
}

// An undamped third mode: the unconstrained estimate of its damping falls on either side of zero, so
// the stable fit holds the pole on the bound in about half the runs (a censored estimate: no sd there)
// and estimates it inside in the others; the other modes' sd and coverage hold over all runs.
static void held_pole_no_sd_others_keep_theirs(void **)
{
    const Mc mc = run_mc(0.0, 400, 77);
    std::printf("8.325 Hz pole held on the bound (and only it, without variance) in %d/400 runs\n", mc.held);
    assert_true(mc.held >= 100 && mc.held <= 300);
    check_sd_and_coverage(mc);
}

static void not_held_keeps_sd_and_coverage(void **)
{
    const Mc mc = run_mc(0.004, 400, 88);
    assert_int_equal(mc.held, 0);
    check_sd_and_coverage(mc);
}

static void no_held_pole_same_as_unconstrained(void **)
{
    Records rec(0.004, 40.0, 78);
    for (int r = 0; r < 20; ++r) {
        const auto w = rec.next();
        const PrResult s = pr_ml(w, Domain::CT, rec.h, options(true)), u = pr_ml(w, Domain::CT, rec.h, options(false));
        for (char c : s.at_bound) assert_int_equal((int)c, 0);
        assert_int_equal((int)s.theta.size(), (int)u.theta.size());
        const double dth = (s.theta - u.theta).cwiseAbs().maxCoeff() / u.theta.cwiseAbs().maxCoeff();
        const double dcov = (s.cov - u.cov).cwiseAbs().maxCoeff() / u.cov.cwiseAbs().maxCoeff();
        if (r < 3) std::printf("run %d: stable vs unconstrained: theta %.3g, cov %.3g (relative)\n", r, dth, dcov);
        assert_true(dth < 1e-9 && dcov < 1e-6);
        assert_int_equal(s.cov_rank, (int)s.theta.size());
    }
}

// Two real poles where the data want a lightly damped pair: the fit crosses the double pole.
static void real_poles_become_the_pair(void **)
{
    Records rec(0.004, 60.0, 79);
    const auto w = rec.next();
    PrOptions pairs = options(true), reals = options(true);
    const double w3 = 2 * M_PI * 8.3;
    const std::vector<cd> base = {std::polar(2 * M_PI * 3.0, M_PI / 2 + 0.02), std::polar(2 * M_PI * 5.1, M_PI / 2 + 0.01)};
    std::vector<cd> a = base, b = base;
    a.push_back(cd(-0.05 * w3, w3));                         // the pair
    b.push_back(cd(-0.5 * w3, 0.0));                         // two real poles in its place
    b.push_back(cd(-0.6 * w3, 0.0));
    pairs.pole_starts = {{"pair", a}};
    reals.pole_starts = {{"reals", b}};
    const PrResult rp = pr_ml(w, Domain::CT, rec.h, pairs), rr = pr_ml(w, Domain::CT, rec.h, reals);
    int npair = 0;
    for (const cd &p : rr.model.poles) npair += p.imag() > 0;
    std::printf("pair start: cost %.8g; two real poles: cost %.8g, %d pairs at the end\n", rp.cost, rr.cost, npair);
    assert_int_equal(npair, 3);
    assert_true(std::fabs(rr.cost - rp.cost) <= 1e-6 * rp.cost);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(no_held_pole_same_as_unconstrained),
        cmocka_unit_test(real_poles_become_the_pair),
        cmocka_unit_test(not_held_keeps_sd_and_coverage),
        cmocka_unit_test(held_pole_no_sd_others_keep_theirs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
