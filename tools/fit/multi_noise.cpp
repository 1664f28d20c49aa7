// Coloured (AR) output noise for the multiple-experiment ML (multi.hpp): the exact whitening
// factor of a stationary AR(p) process and Yule-Walker estimation of the AR polynomial.
#include "multi.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>
#include <string>

namespace msidfit {

namespace {

// Levinson-Durbin on r(0..p): predictors pred[k] (e_k(t) = x(t) + sum_j pred[k](j-1) x(t-j))
// and prediction error variances P_k, k = 0..p. Throws when the Toeplitz matrix is not positive definite.
void levinson(const VecR &r, std::vector<VecR> &pred, VecR &P)
{
    const int p = (int)r.size() - 1;
    pred.assign((size_t)p + 1, VecR());
    P.resize(p + 1);
    P(0) = r(0);
    if (!(r(0) > 0)) throw FitError("the noise autocovariance r(0) must be positive");
    for (int k = 1; k <= p; ++k) {
        const VecR &a = pred[(size_t)k - 1];
        double acc = r(k);
        for (int j = 1; j < k; ++j) acc += a(j - 1) * r(k - j);
        const double kap = -acc / P(k - 1);
        if (!(std::abs(kap) < 1.0))
            throw FitError("the noise autocovariance is not positive definite at lag " + std::to_string(k) +
                           " (reflection coefficient " + std::to_string(kap) + ")");
        VecR b(k);
        for (int j = 1; j < k; ++j) b(j - 1) = a(j - 1) + kap * a(k - j - 1);
        b(k - 1) = kap;
        pred[(size_t)k] = b;
        P(k) = P(k - 1) * (1.0 - kap * kap);
    }
}

}  // namespace

void MultiNoise::apply(const double *x, double *out, Eigen::Index T) const
{
    const int p = (int)c.size();
    if (p == 0) {
        for (Eigen::Index t = 0; t < T; ++t) out[t] = x[t];
        return;
    }
    for (Eigen::Index t = 0; t < T; ++t) {
        const int k = (int)std::min<Eigen::Index>(t, p);
        const VecR &a = pred[(size_t)k];
        double acc = x[t];
        for (int j = 1; j <= k; ++j) acc += a(j - 1) * x[t - j];
        out[t] = acc / std::sqrt(P(k));
    }
}

double MultiNoise::logdet(Eigen::Index T) const
{
    double s = 0;
    const int p = (int)c.size();
    for (Eigen::Index t = 0; t < T && t < p; ++t) s += std::log(P(t));
    return s;   // P_k = 1 for k >= p
}

VecR multi_ar_autocov(const VecR &c, int L)
{
    const int p = (int)c.size();
    // sum_{j=0}^{p} c_j r(|k - j|) = delta_k, k = 0..p (E[v(t-k) e(t)] = delta_k for k >= 0), c_0 = 1
    MatR M = MatR::Zero(p + 1, p + 1);
    for (int k = 0; k <= p; ++k)
        for (int j = 0; j <= p; ++j) M(k, std::abs(k - j)) += j == 0 ? 1.0 : c(j - 1);
    VecR rhs = VecR::Zero(p + 1);
    rhs(0) = 1.0;
    const VecR r0 = M.fullPivLu().solve(rhs);
    VecR r(std::max(L, p) + 1);
    r.head(p + 1) = r0;
    for (int k = p + 1; k < r.size(); ++k) {
        double acc = 0;
        for (int j = 1; j <= p; ++j) acc -= c(j - 1) * r(k - j);
        r(k) = acc;
    }
    return r.head(L + 1);
}

MultiNoise multi_noise_from_ar(const VecR &c)
{
    MultiNoise w;
    w.c = c;
    const int p = (int)c.size();
    if (p == 0) return w;
    if (!c.allFinite()) throw FitError("the noise AR coefficients must be finite");
    // stationarity: roots of z^p + c_1 z^(p-1) + ... + c_p inside the unit circle
    MatR C = MatR::Zero(p, p);
    C.row(0) = -c.transpose();
    for (int k = 1; k < p; ++k) C(k, k - 1) = 1.0;
    const double rho = Eigen::EigenSolver<MatR>(C, false).eigenvalues().cwiseAbs().maxCoeff();
    if (!(rho < 1.0 - 1e-9))
        throw FitError("the noise AR model is not stationary: a root of c(z) has modulus " + std::to_string(rho) +
                       " (all must lie inside the unit circle)");
    levinson(multi_ar_autocov(c, p), w.pred, w.P);
    // normalised so that the innovations have unit variance: P_p = 1 up to rounding
    w.P /= w.P(p);
    return w;
}

VecR multi_ar_yule_walker(const std::vector<MatR> &x, int p)
{
    if (p < 1) throw FitError("the noise AR order must be at least 1");
    VecR r = VecR::Zero(p + 1);
    double n = 0;
    for (const auto &m : x)
        for (Eigen::Index j = 0; j < m.cols(); ++j) {
            const Eigen::Index T = m.rows();
            n += (double)T;
            for (int k = 0; k <= p; ++k)
                for (Eigen::Index t = k; t < T; ++t) r(k) += m(t, j) * m(t - k, j);
        }
    if (n <= 4.0 * p) throw FitError("too few noise samples (" + std::to_string((long)n) + ") for an AR(" + std::to_string(p) + ") model");
    r /= n;   // biased estimate: the Toeplitz matrix stays positive definite
    std::vector<VecR> pred;
    VecR P;
    levinson(r, pred, P);
    return pred[(size_t)p];
}

}  // namespace msidfit
