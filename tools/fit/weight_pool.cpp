// Pooled weights (`msid fit --weight-smooth H`): the covariance of a line averaged with those of its
// neighbours where the line's own weights are imprecise and the neighbours' covariance matrices are
// equal to its own by a likelihood-ratio test (frf_data.hpp, docs/fitting.md "Pooled weights").
#include "frf_data.hpp"
#include "stats.hpp"

#include <algorithm>
#include <cmath>

namespace msidfit {

size_t pool_block(const FrfData &f, Weight w)
{
    if (f.nu < 2) return 0;
    // the nonparametric covariance of several experiments is sum_e (w_e^T conj w_e) (x) S_e: one
    // experiment's ny x ny Wishart per block; known-input weights are Z^-1 (x) Sigma
    if (w == Weight::KnownInput) return f.ny;
    if (w == Weight::Cov && f.m > 1 && f.method != "lpm" && f.method != "etfe" && f.realisations < 2) return f.ny;
    return 0;
}

namespace {

// Upper alpha-quantile of a distribution by bisection on its survival function.
template <class Sf> double upper_quantile(Sf sf, double alpha)
{
    double lo = 0.0, hi = 1.0;
    while (sf(hi) >= alpha && hi < 1e12) hi *= 2.0;
    for (int it = 0; it < 100; ++it) {
        const double mid = 0.5 * (lo + hi);
        (sf(mid) >= alpha ? lo : hi) = mid;
    }
    return hi;
}

double log_det(const MatC &C)
{
    Eigen::LLT<MatC> llt(C);
    if (llt.info() != Eigen::Success) return -std::numeric_limits<double>::infinity();
    double s = 0;
    for (Eigen::Index i = 0; i < C.rows(); ++i) s += std::log(llt.matrixL()(i, i).real());
    return 2.0 * s;
}

// Equality of two covariances of one line each, scalar case (g = 1): the variance ratio against the
// central 99% of F(2n, 2n) (exact for complex Gaussian sample variances).
struct ScalarTest {
    double last_d = -1, inner = 0;
    bool equal(double ck, double cj, double nk, double nj)
    {
        const double q = cj / ck, d = 2.0 * std::min(nj, nk);
        // decided without incomplete beta functions when q lies well inside the central 99% (the
        // 99.5% quantile of F(d, d), found once per d, with a 1% margin)
        if (d != last_d) {
            inner = upper_quantile([&](double x) { return f_sf(d, d, x); }, 0.005) / 1.01;
            last_d = d;
        }
        if (q < inner && q * inner > 1.0) return true;
        return !(f_sf(d, d, q) < 0.005 || f_sf(d, d, 1.0 / q) < 0.005);
    }
};

}  // namespace

PoolStats smooth_weights(std::vector<WeightedLine> &w, int half, size_t block)
{
    PoolStats st;
    std::vector<size_t> cx;
    for (size_t i = 0; i < w.size(); ++i)
        if (!w[i].real) cx.push_back(i);
    const size_t n = cx.size(), win = std::min(n, (size_t)(2 * std::max(half, 0) + 1));
    st.lines = n;
    if (win <= 1) return st;
    std::vector<MatC> C(n);
    std::vector<double> dof(n), ld(n);
    for (size_t k = 0; k < n; ++k) {
        C[k] = w[cx[k]].cov;
        dof[k] = w[cx[k]].dof;
        ld[k] = log_det(C[k]);
    }
    const Eigen::Index g = C[0].rows();
    const double ny = (double)w[cx[0]].G.rows();
    // Likelihood-ratio test of two complex Wishart matrices S_k, S_j (n_k, n_j dof) for equal
    // covariance: 2 [(n_k + n_j) ln|S_p| - n_k ln|S_k| - n_j ln|S_j|], S_p the dof-weighted mean, times
    // Bartlett's factor rho = 1 - (2 b^2 - 1)/(6 b) (1/n_k + 1/n_j - 1/(n_k + n_j)) is chi2 with one dof
    // per free real entry: b^2 per b x b block, g b in all (Monte Carlo: the 99% quantile within 2% of
    // chi2's for b = 1..6, n = 8..200). The design factors of a multi-experiment covariance cancel
    // between the two lines when they are equal.
    const double b = block > 0 && (Eigen::Index)block < g && g % (Eigen::Index)block == 0 ? (double)block : (double)g;
    const double df = (double)g * b;
    const double qa = upper_quantile([&](double x) { return chi2_sf(df, x); }, POOL_TEST_LEVEL);
    ScalarTest scalar;
    auto equal = [&](size_t k, size_t j) {
        if (g == 1) return scalar.equal(C[k](0, 0).real(), C[j](0, 0).real(), dof[k], dof[j]);
        const double nk = dof[k], nj = dof[j], np = nk + nj;
        if (!std::isfinite(ld[k]) || !std::isfinite(ld[j]) || nk < b || nj < b) return false;
        const double lp = log_det((nk * C[k] + nj * C[j]) / np);
        const double rho = 1.0 - (2.0 * b * b - 1.0) / (6.0 * b) * (1.0 / nk + 1.0 / nj - 1.0 / np);
        return rho * 2.0 * (np * lp - nk * ld[k] - nj * ld[j]) <= qa;
    };
    for (size_t k = 0; k < n; ++k) {
        // per-line weights from n dof inflate the variance by n/(n - ny - 1) (sample ML): with many dof
        // they are as good as exact and pooling can only add bias
        const double nk = dof[k];
        if (nk > ny + 1.0 && nk / (nk - ny - 1.0) - 1.0 <= POOL_MIN_INFLATION) { ++st.precise; continue; }
        const size_t lo = std::min(k > (size_t)half ? k - (size_t)half : 0, n - win);
        MatC S = MatC::Zero(g, g);
        double nd = 0;
        bool any = false;
        for (size_t j = lo; j < lo + win; ++j) {   // in window order (the sum's rounding as before)
            if (j != k && !equal(k, j)) { ++st.left_out; continue; }   // the covariance changes there
            S += dof[j] * C[j];
            nd += dof[j];
            any = any || j != k;
        }
        if (!any) continue;
        ++st.pooled;
        WeightedLine &l = w[cx[k]];
        l.cov = S / nd;
        l.dof = nd;
        Eigen::LLT<MatC> llt(l.cov);
        l.Linv = MatC(llt.matrixL()).triangularView<Eigen::Lower>().solve(MatC::Identity(S.rows(), S.cols()));
    }
    return st;
}

}  // namespace msidfit
