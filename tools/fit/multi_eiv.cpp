// Errors-in-variables (noisy inputs) for the multiple-experiment ML, single output (multi.hpp):
// Markovsky & Pintelon (ML) with w = (u, y) both noisy, the true inputs and every record's
// initial conditions eliminated analytically.
//
// The trajectories of length T of the model are the kernel of the banded annihilator A(theta):
// e(t) = a(q^-1) y(t) - sum_k b_k(q^-1) u_k(t), t = n..T-1 (ker A has dimension nu T + n: the
// inputs and n initial conditions). The least-norm distance of (sigma-scaled) data w to it is
//     M(theta, w) = min ||D^-1 (w - w_hat)||^2 = e^T (A D^2 A^T)^-1 e,      (MP §IV, M(B, w))
// D = diag(lambda for input samples, 1 for output samples), lambda = sigma_u / sigma_y known.
// A D^2 A^T is symmetric banded Toeplitz (bandwidth n): the autocovariance of the equation
// error's MA(n) process, r(l) = sum_m alpha_m alpha_m+l + lambda^2 sum_k sum_d beta_kd beta_k,d+l.
// Its banded Cholesky factor L whitens e: the residual L^-1 e, O(T n^2) per record. With
// lambda = 0 the cost equals the output-error cost ||Pi_perp y||^2 of multi_fit (a test).
#include "multi.hpp"

#include "msid_cancel.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <string>

namespace msidfit {

namespace {

struct EivLayout {
    int n = 0, nu = 0, d0 = 1, nb = 0;
};

// whitened equation error of one record (length T - n) for theta = (alpha, beta[k nb + d - d0])
bool eiv_residual(const MultiRecord &rec, const VecR &th, const EivLayout &L, double lambda, double *out)
{
    const int n = L.n;
    const Eigen::Index T = rec.y.rows(), m = T - n;
    // coefficient sequences: a_0 = 1, a_m = alpha_m; b_k,d
    VecR a(n + 1);
    a(0) = 1.0;
    a.tail(n) = th.head(n);
    // MA autocovariance r(0..n)
    VecR r = VecR::Zero(n + 1);
    for (int l = 0; l <= n; ++l) {
        for (int i = 0; i + l <= n; ++i) r(l) += a(i) * a(i + l);
        for (int k = 0; k < L.nu; ++k)
            for (int d = L.d0; d + l <= n; ++d)
                r(l) += lambda * lambda * th(n + k * L.nb + d - L.d0) * th(n + k * L.nb + d + l - L.d0);
    }
    // banded Cholesky of the m x m Toeplitz matrix, row-wise band storage B(i, j - i + n), j = i-n..i
    MatR B = MatR::Zero(m, n + 1);
    for (Eigen::Index i = 0; i < m; ++i)
        for (Eigen::Index j = std::max<Eigen::Index>(0, i - n); j <= i; ++j) {
            double s = r(i - j);
            for (Eigen::Index k = std::max<Eigen::Index>(0, i - n); k < j; ++k)
                if (k >= j - n) s -= B(i, k - i + n) * B(j, k - j + n);
            if (i == j) {
                if (!(s > 0)) return false;
                B(i, n) = std::sqrt(s);
            } else {
                B(i, j - i + n) = s / B(j, n);
            }
        }
    for (Eigen::Index i = 0; i < m; ++i) {
        const Eigen::Index t = i + n;
        double e = 0;
        for (int q = 0; q <= n; ++q) e += a(q) * rec.y(t - q, 0);
        for (int k = 0; k < L.nu; ++k)
            for (int d = L.d0; d <= n; ++d) e -= th(n + k * L.nb + d - L.d0) * rec.u(t - d, k);
        for (Eigen::Index k = std::max<Eigen::Index>(0, i - n); k < i; ++k) e -= B(i, k - i + n) * out[k];
        out[i] = e / B(i, n);
    }
    return true;
}

VecR eiv_residuals(const std::vector<MultiRecord> &recs, const VecR &th, const EivLayout &L, double lambda)
{
    Eigen::Index S = 0;
    for (const auto &r : recs) S += r.y.rows() - L.n;
    VecR res(S);
    Eigen::Index off = 0;
    for (const auto &r : recs) {
        // a residual of a long record is O(T n^2): the finite-difference Jacobian makes 2 p of them
        msidutil::checkpoint(msidutil::Step::solves, 0, "the multi fit");
        if (!eiv_residual(r, th, L, lambda, res.data() + off)) return VecR::Constant(S, NAN);
        off += r.y.rows() - L.n;
    }
    return res;
}

MatR fd_jacobian(const std::vector<MultiRecord> &recs, const VecR &th, const EivLayout &L, double lambda)
{
    const VecR r0 = eiv_residuals(recs, th, L, lambda);
    MatR J(r0.size(), th.size());
    for (Eigen::Index c = 0; c < th.size(); ++c) {
        const double h = 1e-6 * std::max(1.0, std::abs(th(c)));
        VecR tp = th, tm = th;
        tp(c) += h;
        tm(c) -= h;
        J.col(c) = (eiv_residuals(recs, tp, L, lambda) - eiv_residuals(recs, tm, L, lambda)) / (2 * h);
    }
    return J;
}

}  // namespace

double multi_eiv_cost(const std::vector<MultiRecord> &recs, const VecR &theta, int n, int d0, double lambda)
{
    EivLayout L;
    L.nu = (int)recs[0].u.cols();
    L.d0 = d0;
    L.n = n;
    L.nb = L.nu ? L.n - d0 + 1 : 0;
    return eiv_residuals(recs, theta, L, lambda).squaredNorm();
}

MultiEivResult multi_fit_eiv(const std::vector<MultiRecord> &recs, const MultiOptions &o, double lambda)
{
    if (!(lambda >= 0) || !std::isfinite(lambda)) throw FitError("the input noise ratio sigma_u / sigma_y must be finite and >= 0");
    if (recs.empty() || recs[0].y.cols() != 1)
        throw FitError("noisy inputs (errors-in-variables) are supported for one output");
    if (recs[0].u.cols() < 1) throw FitError("noisy inputs need input columns (free responses have none)");
    // start: the output-error fit (biased under input noise, close at moderate input noise)
    const MultiResult oe = multi_fit(recs, o);
    EivLayout L;
    L.n = oe.n;
    L.nu = oe.nu;
    L.d0 = oe.d0;
    L.nb = oe.nb;
    VecR th = oe.theta;
    VecR r = eiv_residuals(recs, th, L, lambda);
    double V = r.squaredNorm();
    double mu = 1e-3;
    bool conv = false;
    int it = 0;
    for (; it < o.max_iter && !conv; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the multi fit");
        const MatR J = fd_jacobian(recs, th, L, lambda);
        const MatR H = J.transpose() * J;
        const VecR g = J.transpose() * r;
        const VecR dsc = H.diagonal().cwiseMax(1e-300);
        bool acc = false;
        while (!acc) {
            MatR M = H;
            M.diagonal() += mu * dsc;
            const VecR step = -M.ldlt().solve(g);
            const VecR tn = th + step;
            const VecR rn = eiv_residuals(recs, tn, L, lambda);
            const double Vn = rn.squaredNorm();
            if (std::isfinite(Vn) && Vn <= V) {
                conv = V - Vn <= 1e-12 * V || step.norm() <= 1e-12 * (th.norm() + 1e-12);
                th = tn;
                r = rn;
                V = Vn;
                mu = std::max(1e-12, mu / 3);
                acc = true;
            } else {
                mu *= 4;
                if (mu > 1e16) { conv = true; break; }
            }
        }
    }
    MultiEivResult res;
    res.theta = th;
    res.names = oe.names;
    res.alpha = th.head(L.n);
    res.cost = V;
    res.dof = (double)r.size() - (double)th.size();
    res.s2 = V / res.dof;
    const MatR J = fd_jacobian(recs, th, L, lambda);
    res.cov = res.s2 * (J.transpose() * J).ldlt().solve(MatR::Identity(th.size(), th.size()));
    res.iterations = it;
    res.converged = conv;
    res.lambda = lambda;
    res.oe_theta = oe.theta;
    return res;
}

}  // namespace msidfit
