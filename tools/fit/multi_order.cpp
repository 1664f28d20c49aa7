// Order selection and validation on records for the multiple-experiment ML (multi.hpp).
#include "multi.hpp"
#include "stats.hpp"

#include "msid_cancel.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <string>

namespace msidfit {

VecR multi_hankel_sv(const std::vector<MultiRecord> &recs, int Lr)
{
    const Eigen::Index ny = recs.empty() ? 0 : recs[0].y.cols();
    MatR G = MatR::Zero(Lr * ny, Lr * ny);
    VecR col(Lr * ny);
    bool any = false;
    for (const auto &r : recs)
        for (Eigen::Index c = 0; c + Lr <= r.y.rows(); ++c) {
            for (Eigen::Index k = 0; k < Lr; ++k) col.segment(k * ny, ny) = r.y.row(c + k).transpose();
            G.selfadjointView<Eigen::Lower>().rankUpdate(col);
            any = true;
        }
    if (!any) return VecR();
    G = G.selfadjointView<Eigen::Lower>();
    const VecR ev = Eigen::SelfAdjointEigenSolver<MatR>(G, Eigen::EigenvaluesOnly).eigenvalues();
    VecR sv(ev.size());
    for (Eigen::Index k = 0; k < ev.size(); ++k) sv(k) = std::sqrt(std::max(0.0, ev(ev.size() - 1 - k)));
    return sv;
}

MultiOrderSelection multi_select_order(const std::vector<MultiRecord> &recs, const MultiOptions &o,
                                       const std::vector<int> &orders, const std::string &rule, bool count_ic)
{
    if (rule != "mdl" && rule != "aic") throw FitError("the order rule must be mdl or aic (got '" + rule + "')");
    if (orders.empty()) throw FitError("no orders to try");
    if (recs.empty()) throw FitError("no records");
    MultiOrderSelection sel;
    sel.rule = rule;
    const double N = (double)recs.size(), ny = (double)recs[0].y.cols(), nu = (double)recs[0].u.cols();
    double S = 0;
    Eigen::Index Tmin = recs[0].y.rows();
    for (const auto &r : recs) {
        S += (double)r.y.rows() * ny;
        Tmin = std::min(Tmin, r.y.rows());
    }
    // the singular values of the stacked block Hankel matrix (reported beside the criterion)
    const int nmax = *std::max_element(orders.begin(), orders.end());
    const int Lr = std::max<int>(nmax + 1, std::min<int>(2 * nmax + 2, (int)(Tmin / 2)));
    if (nu == 0) {
        sel.hankel_sv = multi_hankel_sv(recs, Lr);
        double best = 0;
        for (int n : orders)
            if (n < sel.hankel_sv.size() && sel.hankel_sv(n) > 0 && sel.hankel_sv(n - 1) / sel.hankel_sv(n) > best) {
                best = sel.hankel_sv(n - 1) / sel.hankel_sv(n);
                sel.hankel_gap_order = n;
            }
    }
    double best = INFINITY;
    for (int n : orders) {
        MultiOrderRow row;
        row.order = n;
        MultiOptions on = o;
        on.order = n;
        try {
            MultiResult r = multi_fit(recs, on);
            row.ok = std::isfinite(r.cost) && r.cost > 0;
            if (!row.ok) row.error = "cost " + std::to_string(r.cost);
            row.converged = r.converged;
            row.cost = r.cost;
            row.s2 = r.s2;
            const double nb = nu > 0 ? (double)r.nb : 0.0;
            row.k = n + ny * nu * nb + (count_ic && o.eliminate_ic ? N * ny * n : 0.0);
            row.m2logl = S * std::log(r.cost / S) + r.logdet;
            row.aic = row.m2logl + 2.0 * row.k;
            row.mdl = row.m2logl + row.k * std::log(S);
            const double crit = rule == "mdl" ? row.mdl : row.aic;
            if (row.ok && crit < best) {
                best = crit;
                sel.chosen = n;
                sel.best = std::move(r);
            }
        } catch (const FitError &e) {
            row.error = e.what();
        }
        sel.rows.push_back(row);
    }
    if (sel.chosen < 0) throw FitError("no order in the range gave a model: " + sel.rows.back().error);
    return sel;
}

MultiCheck multi_check(const std::vector<MultiRecord> &recs, const VecR &alpha, const std::vector<MatR> &beta, int d0,
                       const VecR &noise_c, double s2_model, double dof_model, int lags)
{
    if (recs.empty()) throw FitError("no records");
    const MultiNoise W = multi_noise_from_ar(noise_c);
    const int n = (int)alpha.size();
    const Eigen::Index ny = recs[0].y.cols();
    MultiCheck c;
    double M = 0;   // recursive residuals in all
    for (size_t i = 0; i < recs.size(); ++i) {
        const MultiRecord &r = recs[i];
        const Eigen::Index T = r.y.rows();
        if (T <= n)
            throw FitError("record " + std::to_string(i + 1) + " has " + std::to_string(T) + " samples: the model's " +
                           std::to_string(n) + " initial conditions need more");
        // forced response from zero initial conditions, and the free-response basis (unit pre-initial values)
        const MatR u = r.u.rows() == T ? r.u : MatR(T, 0);
        MatR E = r.y - multi_simulate(alpha, beta, d0, u, MatR::Zero(ny, n), (int)ny);
        MatR X(T, n);
        for (int k = 0; k < n; ++k) {
            MatR x0 = MatR::Zero(1, n);
            x0(0, k) = 1.0;
            X.col(k) = multi_simulate(alpha, {}, 1, MatR(T, 0), x0, 1).col(0);
        }
        VecR tmp(T);
        for (Eigen::Index j = 0; j < E.cols(); ++j) { W.apply(E.col(j).data(), tmp.data(), T); E.col(j) = tmp; }
        for (int k = 0; k < n; ++k) { W.apply(X.col(k).data(), tmp.data(), T); X.col(k) = tmp; }
        // recursive residuals (Brown, Durbin & Evans 1975): the standardised one-step prediction errors of the
        // initial conditions' least squares in time order; T - n per output, independent N(0, s^2) under the model
        MatR Rw(T - n, ny);
        for (Eigen::Index j = 0; j < ny; ++j) {
            const MatR X0 = X.topRows(n);
            Eigen::FullPivLU<MatR> lu(X0);
            if (lu.rank() < n) throw FitError("the model's free-response basis is singular on record " + std::to_string(i + 1));
            VecR b = lu.solve(VecR(E.col(j).head(n)));
            MatR P = lu.inverse() * lu.inverse().transpose();   // (X0^T X0)^-1
            for (Eigen::Index t = n; t < T; ++t) {
                if ((t - n) % 4096 == 4095) msidutil::checkpoint(msidutil::Step::rows, 4096, "the validation");
                const VecR x = X.row(t).transpose();
                const VecR Px = P * x;
                const double f = 1.0 + x.dot(Px);
                const double e = E(t, j) - x.dot(b);
                Rw(t - n, j) = e / std::sqrt(f);
                b += Px * (e / f);
                P -= Px * Px.transpose() / f;
            }
        }
        c.cost += Rw.squaredNorm();
        M += (double)Rw.size();
        c.residuals.push_back(Rw);
    }
    c.dof = M;
    c.s2 = c.cost / c.dof;
    if (s2_model > 0 && dof_model > 0) {
        c.f_stat = c.s2 / s2_model;
        c.p_cost = f_sf(c.dof, dof_model, c.f_stat);
    }
    // whiteness: pooled autocorrelation at lags 1..m within every record and output, each standardised
    // by its number of products (var of sum_t w_t w_t-k is npairs s^4 for white w)
    Eigen::Index Tmin = recs[0].y.rows();
    for (const auto &m : c.residuals) Tmin = std::min(Tmin, m.rows());
    c.lags = std::max(1, std::min<int>(lags, (int)(Tmin / 4)));
    c.rho = VecR::Zero(c.lags);
    c.q_lb = 0;
    for (int k = 1; k <= c.lags; ++k) {
        double s = 0, npairs = 0;
        for (const auto &m : c.residuals)
            for (Eigen::Index j = 0; j < m.cols(); ++j)
                for (Eigen::Index t = k; t < m.rows(); ++t) {
                    s += m(t, j) * m(t - k, j);
                    npairs += 1;
                }
        c.rho(k - 1) = s / c.cost;
        const double z = npairs > 0 ? s / (c.s2 * std::sqrt(npairs)) : 0.0;
        c.q_lb += z * z;
    }
    c.p_white = chi2_sf(c.lags, c.q_lb);
    return c;
}

}  // namespace msidfit
