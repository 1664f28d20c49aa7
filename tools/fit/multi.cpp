// Multiple-experiment ML with eliminated initial conditions (see multi.hpp).
// Equation references: Markovsky & Pintelon, shared/papers/markovsky-pintelon-multiple-experiments.txt.
#include "multi.hpp"

#include "msid_cancel.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <string>

namespace msidfit {

namespace {

// s(t) = g(t) - sum_{m=1}^{n} alpha_m s(t - m), t = 0..T-1, with pre-initial values
// s(-j) = pre[j-1] (pre == nullptr: zero) and g == nullptr meaning g = 0: the
// response of 1 / a(q^-1).
void ar_filter(const VecR &alpha, const double *g, const double *pre, double *out, Eigen::Index T)
{
    const int n = (int)alpha.size();
    for (Eigen::Index t = 0; t < T; ++t) {
        double acc = g ? g[t] : 0.0;
        for (int m = 1; m <= n; ++m) {
            const Eigen::Index k = t - m;
            acc -= alpha(m - 1) * (k >= 0 ? out[k] : (pre ? pre[-k - 1] : 0.0));
        }
        out[t] = acc;
    }
}

struct Layout {
    int n = 0, nu = 0, ny = 0, d0 = 1, nb = 0;
    bool elim = true;
    const MultiNoise *W = nullptr;               // coloured noise: whitening factor (nullptr: white)
    int p() const { return nu * nb; }            // beta entries per output
    int q() const { return n + ny * p(); }        // theta entries
};

Layout layout_of(const std::vector<MultiRecord> &recs, const MultiOptions &o)
{
    Layout L;
    L.n = o.order;
    L.nu = (int)recs[0].u.cols();
    L.ny = (int)recs[0].y.cols();
    L.d0 = L.nu > 0 && o.feedthrough ? 0 : 1;
    L.nb = L.nu > 0 ? L.n - L.d0 + 1 : 0;
    L.elim = o.eliminate_ic;
    return L;
}

// M <- W M column by column (the whitening factor of the noise model, multi_noise.cpp)
void whiten(const Layout &L, Eigen::Ref<MatR> M)
{
    if (!L.W || L.W->white()) return;
    VecR tmp(M.rows());
    for (Eigen::Index j = 0; j < M.cols(); ++j) {
        L.W->apply(M.col(j).data(), tmp.data(), M.rows());
        M.col(j) = tmp;
    }
}

// Everything at one alpha: the linear parameters by least squares with the initial
// conditions projected out record by record (§IV: the problem decouples, cost linear in N).
struct Eval {
    double V = 0.0;
    MatR R;                       // residual, (sum T) x ny, records stacked
    MatR beta;                    // p x ny
    std::vector<MatR> c;          // per record n x ny pre-initial values
    MatR Ja;                      // Kaufman Jacobian wrt alpha, (ny sum T) x n, output-major
    MatR Jfull;                   // Jacobian wrt theta with the ICs projected out (for the covariance)
};

// The linear parameters of every record at once: the least squares of the stacked, projected rows
// (column-pivoting QR of Ft, then beta, the residual and the orthonormal basis of Ft's columns).
struct StackedLs {
    MatR beta, R, QF;
};

// Below this many multiply-adds (rows x columns^2, about a millisecond) the stacked least squares
// runs here: a thread costs more than the step.
constexpr double STACKED_ABANDONABLE_FLOPS = 1 << 20;

// The stacked least squares as one step of the caller's: the QR of a long stack (rows of every
// record, columns the inputs' numerator coefficients) is seconds of Eigen's work without a checkpoint
// inside, so from STACKED_ABANDONABLE_FLOPS on it runs abandonable (msid_cancel.hpp) on the rows it
// shares, and a stop lands while it runs. It counts one solve when it begins and one when it is done,
// either way; the arithmetic is the same on either thread.
StackedLs stacked_ls(std::shared_ptr<const MatR> Ft, std::shared_ptr<const MatR> Yt)
{
    auto work = [Ft, Yt] {
        Eigen::ColPivHouseholderQR<MatR> qf(*Ft);
        StackedLs ls;
        ls.beta = qf.solve(*Yt);
        ls.R = *Yt - *Ft * ls.beta;
        ls.QF = qf.householderQ() * MatR::Identity(Ft->rows(), qf.rank());
        return ls;
    };
    const double flops = (double)Ft->rows() * (double)Ft->cols() * (double)Ft->cols();
    if (flops >= STACKED_ABANDONABLE_FLOPS)
        return msidutil::abandonable<StackedLs>(std::function<StackedLs()>(work), msidutil::Step::solves, "the multi fit");
    msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");   // the step began
    StackedLs ls = work();
    msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");   // the step is done
    return ls;
}

Eval evaluate(const std::vector<MultiRecord> &recs, const Layout &L, const VecR &alpha, bool jac, bool full)
{
    const int n = L.n, p = L.p(), ny = L.ny;
    Eigen::Index S = 0;
    for (const auto &r : recs) S += r.y.rows();
    std::vector<Eigen::HouseholderQR<MatR>> qx(recs.size());
    std::vector<MatR> Q(recs.size()), F(recs.size()), Xs(recs.size()), Fw(recs.size()), Yw(recs.size());
    // the stacked rows, shared with the stacked least squares (which may finish on a thread of its own)
    const auto Ftp = std::make_shared<MatR>(S, p), Ytp = std::make_shared<MatR>(S, ny);
    MatR &Ft = *Ftp, &Yt = *Ytp;
    Eigen::Index off = 0;
    for (size_t i = 0; i < recs.size(); ++i) {
        // one record's filters and projection at a time: a long record is seconds of the evaluation
        msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");
        const Eigen::Index T = recs[i].y.rows();
        // filtered inputs: column k nb + (d - d0) is q^-d / a(q^-1) u_k, zero pre-initial values
        F[i].resize(T, p);
        VecR v(T);
        for (int k = 0; k < L.nu; ++k) {
            ar_filter(alpha, recs[i].u.col(k).data(), nullptr, v.data(), T);
            for (int d = L.d0; d <= n; ++d) {
                auto col = F[i].col(k * L.nb + (d - L.d0));
                for (Eigen::Index t = 0; t < T; ++t) col(t) = t >= d ? v(t - d) : 0.0;
            }
        }
        // coloured noise: the weighted norm ||W .|| (multi.hpp), everything whitened before the projections
        Fw[i] = F[i];
        Yw[i] = recs[i].y;
        whiten(L, Fw[i]);
        whiten(L, Yw[i]);
        msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");   // the record's filtered inputs
        MatR Fp = Fw[i], Yp = Yw[i];
        if (L.elim) {
            // free-response basis: pre-initial values e_k (§VI: the columns of P_T(theta) up to a change of basis)
            MatR X(T, n);
            for (int k = 0; k < n; ++k) {
                if (k % 4 == 3) msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");
                VecR e = VecR::Zero(n);
                e(k) = 1.0;
                ar_filter(alpha, nullptr, e.data(), X.col(k).data(), T);
            }
            Xs[i] = X;
            whiten(L, X);
            msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");
            qx[i].compute(X);
            Q[i] = qx[i].householderQ() * MatR::Identity(T, n);
            Fp -= Q[i] * (Q[i].transpose() * Fp);
            Yp -= Q[i] * (Q[i].transpose() * Yp);
        }
        Ft.middleRows(off, T) = Fp;
        Yt.middleRows(off, T) = Yp;
        off += T;
    }
    Eval e;
    MatR QF;
    if (p > 0) {
        StackedLs ls = stacked_ls(Ftp, Ytp);
        e.beta = std::move(ls.beta);
        e.R = std::move(ls.R);
        QF = std::move(ls.QF);
    } else {
        e.beta = MatR(0, ny);
        e.R = Yt;
    }
    e.V = e.R.squaredNorm();
    e.c.resize(recs.size());
    for (size_t i = 0; i < recs.size(); ++i) {
        if (L.elim)
            e.c[i] = qx[i].solve(MatR(Yw[i] - Fw[i] * e.beta));
        else
            e.c[i] = MatR::Zero(n, ny);
    }
    if (!jac) return e;
    // d yhat / d alpha_m = -(q^-m / a) yhat, with yhat's pre-initial values c (beta, c fixed)
    e.Ja.resize(S * ny, n);
    if (full) e.Jfull = MatR::Zero(S * ny, L.q());
    for (int j = 0; j < ny; ++j) {
        MatR D(S, n);
        off = 0;
        for (size_t i = 0; i < recs.size(); ++i) {
            msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");
            const Eigen::Index T = recs[i].y.rows();
            VecR ext(T + n);   // ext(n + t) = yhat(t), ext(n - k) = yhat(-k) = c(k-1)
            for (int k = 1; k <= n; ++k) ext(n - k) = e.c[i](k - 1, j);
            VecR yh = VecR::Zero(T);
            if (L.elim) yh = Xs[i] * e.c[i].col(j);
            if (p > 0) yh += F[i] * e.beta.col(j);
            ext.tail(T) = yh;
            VecR g(T);
            for (int m = 1; m <= n; ++m) {
                if (m % 4 == 0) msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");
                for (Eigen::Index t = 0; t < T; ++t) g(t) = -ext(n + t - m);
                ar_filter(alpha, g.data(), nullptr, D.col(m - 1).data() + off, T);
            }
            whiten(L, D.middleRows(off, T));
            if (L.elim) D.middleRows(off, T) -= Q[i] * (Q[i].transpose() * D.middleRows(off, T));
            off += T;
        }
        // residual r = Pi_perp y: dr/dalpha = -Pi_perp dyhat/dalpha (Kaufman)
        if (full) {
            e.Jfull.block(j * S, 0, S, n) = -D;
            if (p > 0) e.Jfull.block(j * S, n + j * p, S, p) = -Ft;
        }
        msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");
        if (p > 0) D -= QF * (QF.transpose() * D);
        e.Ja.middleRows(j * S, S) = -D;
    }
    return e;
}

VecR residual_vec(const MatR &R) { return Eigen::Map<const VecR>(R.data(), R.size()); }

void check_records(const std::vector<MultiRecord> &recs, const MultiOptions &o)
{
    if (recs.empty()) throw FitError("no records");
    if (o.order < 1) throw FitError("the order must be at least 1");
    const Eigen::Index nu = recs[0].u.cols(), ny = recs[0].y.cols();
    if (ny < 1) throw FitError("the records have no outputs");
    for (size_t i = 0; i < recs.size(); ++i) {
        const auto &r = recs[i];
        if (r.u.cols() != nu || r.y.cols() != ny)
            throw FitError("record " + std::to_string(i + 1) + " has " + std::to_string(r.u.cols()) + " input(s) and " +
                           std::to_string(r.y.cols()) + " output(s), record 1 has " + std::to_string(nu) + " and " +
                           std::to_string(ny) + ": every record must have the same channels");
        if (nu > 0 && r.u.rows() != r.y.rows())
            throw FitError("record " + std::to_string(i + 1) + ": inputs and outputs have different lengths");
        if (!r.u.allFinite() || !r.y.allFinite())
            throw FitError("record " + std::to_string(i + 1) + " holds NaN or Inf samples");
        if (o.eliminate_ic && r.y.rows() <= o.order)
            throw FitError("record " + std::to_string(i + 1) + " has " + std::to_string(r.y.rows()) +
                           " samples: too few for order " + std::to_string(o.order) + " (each record needs more than n = " +
                           std::to_string(o.order) + " samples, its " + std::to_string(o.order) +
                           " initial conditions per output are estimated from it)");
    }
    const Layout L = layout_of(recs, o);
    double S = 0;
    for (const auto &r : recs) S += (double)r.y.rows() * (double)ny;
    const double np = L.q() + (L.elim ? (double)recs.size() * ny * L.n : 0.0);
    if (S - np < 1)
        throw FitError("too few samples for order " + std::to_string(o.order) + ": " + std::to_string((long)S) +
                       " output samples against " + std::to_string((long)np) + " parameters (" + std::to_string(L.n) +
                       " pole coefficients, " + std::to_string(L.ny * L.p()) + " numerator coefficients, " +
                       std::to_string((long)(np - L.q())) + " initial conditions)");
}

VecR solve_normal(const MatR &A, const VecR &b)
{
    MatR M = A;
    const double tr = std::max(1e-300, M.diagonal().cwiseAbs().maxCoeff());
    M.diagonal().array() += 1e-13 * tr;
    return M.ldlt().solve(b);
}

// Equation-error least squares on a(q^-1) y_j = sum_k b_jk(q^-1) u_k for t >= n (where the
// record's initial conditions do not enter): the Prony / ARX estimate, alpha part.
VecR arx(const std::vector<MatR> &ys, const std::vector<MatR> &us, int n, int d0)
{
    const int ny = (int)ys[0].cols(), nu = (int)us[0].cols(), nb = nu > 0 ? n - d0 + 1 : 0, p = nu * nb, q = n + ny * p;
    MatR A = MatR::Zero(q, q);
    VecR b = VecR::Zero(q);
    VecR row(q);
    for (size_t i = 0; i < ys.size(); ++i) {
        const Eigen::Index T = ys[i].rows();
        for (int j = 0; j < ny; ++j)
            for (Eigen::Index t = n; t < T; ++t) {
                if ((t - n) % 4096 == 4095) msidutil::checkpoint(msidutil::Step::solves, 0, "the multi fit");
                row.setZero();
                for (int m = 1; m <= n; ++m) row(m - 1) = -ys[i](t - m, j);
                for (int k = 0; k < nu; ++k)
                    for (int d = d0; d <= n; ++d) row(n + j * p + k * nb + (d - d0)) = us[i](t - d, k);
                A.selfadjointView<Eigen::Lower>().rankUpdate(row);
                b += row * ys[i](t, j);
            }
    }
    A = A.selfadjointView<Eigen::Lower>();
    return solve_normal(A, b).head(n);
}

std::vector<cd> poly_roots(const VecR &alpha)
{
    const int n = (int)alpha.size();
    MatR C = MatR::Zero(n, n);
    C.row(0) = -alpha.transpose();
    for (int k = 1; k < n; ++k) C(k, k - 1) = 1.0;
    Eigen::EigenSolver<MatR> es(C, false);
    std::vector<cd> z(n);
    for (int k = 0; k < n; ++k) z[k] = es.eigenvalues()(k);
    return z;
}

}  // namespace

VecR multi_alpha_from_poles(const std::vector<cd> &z)
{
    std::vector<cd> c{1.0};
    for (const cd &zk : z) {
        std::vector<cd> d(c.size() + 1, 0.0);
        for (size_t k = 0; k < c.size(); ++k) {
            d[k] += c[k];
            d[k + 1] -= zk * c[k];
        }
        c = d;
    }
    VecR a((Eigen::Index)z.size());
    for (size_t k = 1; k < c.size(); ++k) a((Eigen::Index)k - 1) = c[k].real();
    return a;
}

VecR multi_reflect_unstable(const VecR &alpha, int *count)
{
    std::vector<cd> z = poly_roots(alpha);
    int m = 0;
    for (cd &zk : z)
        if (std::abs(zk) > 1.0) {
            zk = 1.0 / std::conj(zk);
            ++m;
        }
    if (count) *count = m;
    return m ? multi_alpha_from_poles(z) : alpha;
}

// Kung's realisation on the stacked data: the free responses of all records share the
// observability matrix, so [H_1 ... H_N] (block Hankel, L block rows) has rank n; the shift
// invariance of its dominant left singular vectors gives A and its eigenvalues the poles.
VecR multi_start_kung(const std::vector<MultiRecord> &recs, int n)
{
    const Eigen::Index ny = recs[0].y.cols();
    Eigen::Index Tmin = recs[0].y.rows();
    for (const auto &r : recs) Tmin = std::min(Tmin, r.y.rows());
    const Eigen::Index Lr = std::max<Eigen::Index>(n + 1, std::min<Eigen::Index>(3 * n, Tmin / 2));
    MatR G = MatR::Zero(Lr * ny, Lr * ny);
    VecR col(Lr * ny);
    bool any = false;
    for (const auto &r : recs) {
        const Eigen::Index T = r.y.rows();
        for (Eigen::Index c = 0; c + Lr <= T; ++c) {
            for (Eigen::Index k = 0; k < Lr; ++k) col.segment(k * ny, ny) = r.y.row(c + k).transpose();
            G.selfadjointView<Eigen::Lower>().rankUpdate(col);
            any = true;
        }
    }
    if (!any) throw FitError("every record is shorter than the " + std::to_string(Lr) + " samples of Kung's Hankel matrix");
    G = G.selfadjointView<Eigen::Lower>();
    Eigen::SelfAdjointEigenSolver<MatR> es(G);
    const MatR U = es.eigenvectors().rightCols(n);
    const MatR Uup = U.topRows((Lr - 1) * ny), Udn = U.bottomRows((Lr - 1) * ny);
    const MatR A = Uup.colPivHouseholderQr().solve(Udn);
    Eigen::EigenSolver<MatR> ea(A, false);
    std::vector<cd> z(n);
    for (int k = 0; k < n; ++k) z[k] = ea.eigenvalues()(k);
    return multi_alpha_from_poles(z);
}

VecR multi_start_prony(const std::vector<MultiRecord> &recs, int n, int d0)
{
    std::vector<MatR> ys, us;
    for (const auto &r : recs) {
        if (r.y.rows() <= n) continue;
        ys.push_back(r.y);
        us.push_back(r.u);
    }
    if (ys.empty()) throw FitError("every record is too short for the Prony start");
    return arx(ys, us, n, d0);
}

// Steiglitz-McBride: equation error on data prefiltered by 1 / a_prev (zero initial state). An iterate
// with poles outside the unit circle is reflected first: prefiltered by an unstable 1 / a, a long record
// grows like |z|^T, overflows, and the next iterate (returned before) was the unstable one.
VecR multi_start_sm(const std::vector<MultiRecord> &recs, int n, int d0, const VecR &a0, int iters)
{
    if (!a0.allFinite()) return a0;
    VecR a = multi_reflect_unstable(a0, nullptr);
    for (int it = 0; it < iters; ++it) {
        std::vector<MatR> ys, us;
        for (const auto &r : recs) {
            if (r.y.rows() <= n) continue;
            MatR yf(r.y.rows(), r.y.cols()), uf(r.u.rows(), r.u.cols());
            for (Eigen::Index j = 0; j < r.y.cols(); ++j) ar_filter(a, r.y.col(j).data(), nullptr, yf.col(j).data(), r.y.rows());
            for (Eigen::Index k = 0; k < r.u.cols(); ++k) ar_filter(a, r.u.col(k).data(), nullptr, uf.col(k).data(), r.u.rows());
            ys.push_back(yf);
            us.push_back(uf);
        }
        const VecR an = arx(ys, us, n, d0);
        if (!an.allFinite()) break;
        a = multi_reflect_unstable(an, nullptr);
    }
    return a;
}

// Plain recursion of the model (independent of evaluate()'s filters and projections).
MatR multi_simulate(const VecR &alpha, const std::vector<MatR> &beta, int d0, const MatR &u, const MatR &x0, int ny)
{
    const int n = (int)alpha.size();
    const Eigen::Index T = u.rows(), nu = u.cols();
    MatR y(T, ny);
    for (int j = 0; j < ny; ++j)
        for (Eigen::Index t = 0; t < T; ++t) {
            double acc = 0.0;
            for (int m = 1; m <= n; ++m) acc -= alpha(m - 1) * (t - m >= 0 ? y(t - m, j) : x0(j, m - t - 1));
            for (size_t b = 0; b < beta.size(); ++b) {
                const Eigen::Index d = (Eigen::Index)b + d0;
                if (t - d >= 0)
                    for (Eigen::Index k = 0; k < nu; ++k) acc += beta[b](j, k) * u(t - d, k);
            }
            y(t, j) = acc;
        }
    return y;
}

MatR multi_crb(const VecR &alpha, const std::vector<MatR> &beta, int d0, const std::vector<MatR> &u,
               const std::vector<MatR> &x0, int ny, double s2, const VecR &noise_ar)
{
    const MultiNoise W = multi_noise_from_ar(noise_ar);
    const int n = (int)alpha.size();
    const int nu = u.empty() ? 0 : (int)u[0].cols(), nb = (int)beta.size(), p = nu * nb, q = n + ny * p;
    const int nic = ny * n, P = q + (int)u.size() * nic;
    // theta -> (alpha, beta) in the documented order: alpha, then for j, k, d
    auto unpack = [&](const VecR &th, VecR &a, std::vector<MatR> &b) {
        a = th.head(n);
        b.assign((size_t)nb, MatR(ny, nu));
        for (int j = 0; j < ny; ++j)
            for (int k = 0; k < nu; ++k)
                for (int d = 0; d < nb; ++d) b[(size_t)d](j, k) = th(n + j * p + k * nb + d);
    };
    VecR th0(q);
    th0.head(n) = alpha;
    for (int j = 0; j < ny; ++j)
        for (int k = 0; k < nu; ++k)
            for (int d = 0; d < nb; ++d) th0(n + j * p + k * nb + d) = beta[(size_t)d](j, k);
    MatR Fi = MatR::Zero(P, P);
    for (size_t i = 0; i < u.size(); ++i) {
        const Eigen::Index T = u[i].rows();
        MatR J(T * ny, q + nic);
        for (int c = 0; c < q + nic; ++c) {
            msidutil::checkpoint(msidutil::Step::solves, 0, "the multi fit");   // two simulations of the record
            VecR thp = th0, thm = th0;
            MatR xp = x0[i], xm = x0[i];
            double h;
            if (c < q) {
                h = 1e-6 * std::max(1.0, std::abs(th0(c)));
                thp(c) += h;
                thm(c) -= h;
            } else {
                const int r = (c - q) % ny, m = (c - q) / ny;
                h = 1e-6 * std::max(1.0, std::abs(x0[i](r, m)));
                xp(r, m) += h;
                xm(r, m) -= h;
            }
            VecR ap, am;
            std::vector<MatR> bp, bm;
            unpack(thp, ap, bp);
            unpack(thm, am, bm);
            const MatR yp = multi_simulate(ap, bp, d0, u[i], xp, ny), ym = multi_simulate(am, bm, d0, u[i], xm, ny);
            J.col(c) = Eigen::Map<const VecR>(MatR((yp - ym) / (2 * h)).data(), T * ny);
        }
        if (!W.white()) {   // Fisher information J^T Sigma^-1 J / s2 = (W J)^T (W J) / s2
            VecR tmp(T);
            for (Eigen::Index c = 0; c < J.cols(); ++c)
                for (int j = 0; j < ny; ++j) {
                    W.apply(J.col(c).data() + j * T, tmp.data(), T);
                    J.col(c).segment(j * T, T) = tmp;
                }
        }
        const MatR JtJ = J.transpose() * J / s2;
        const int o = q + (int)i * nic;
        Fi.topLeftCorner(q, q) += JtJ.topLeftCorner(q, q);
        Fi.block(0, o, q, nic) += JtJ.topRightCorner(q, nic);
        Fi.block(o, 0, nic, q) += JtJ.bottomLeftCorner(nic, q);
        Fi.block(o, o, nic, nic) += JtJ.bottomRightCorner(nic, nic);
    }
    return Fi.fullPivLu().inverse().topLeftCorner(q, q);
}

std::vector<MultiMode> multi_modes(const VecR &alpha, const MatR &cov_alpha, double h)
{
    const int n = (int)alpha.size();
    const double hh = h > 0 ? h : 1.0;
    const bool have_cov = cov_alpha.rows() == n && cov_alpha.allFinite();
    std::vector<MultiMode> out;
    for (const cd &z : poly_roots(alpha)) {
        const double tol = 1e-9 * std::max(1.0, std::abs(z));
        if (z.imag() < -tol) continue;
        MultiMode md;
        md.real = std::abs(z.imag()) <= tol;
        md.z = md.real ? cd(z.real(), 0.0) : z;
        md.s = std::log(md.z) / hh;
        md.wn = std::abs(md.s);
        md.fn = md.wn / (2 * M_PI);
        md.zeta = md.wn > 0 ? -md.s.real() / md.wn : 0.0;
        if (have_cov) {
            // dz/dalpha_m = -z^(n-m) / p'(z)
            cd dp = 0.0;
            for (int k = 0; k < n; ++k) dp += (double)(n - k) * (k == 0 ? 1.0 : alpha(k - 1)) * std::pow(md.z, n - k - 1);
            MatR G(2, n);
            for (int m = 1; m <= n; ++m) {
                const cd g = -std::pow(md.z, n - m) / dp;
                G(0, m - 1) = g.real();
                G(1, m - 1) = md.real ? 0.0 : g.imag();
            }
            const MatR Cz = G * cov_alpha * G.transpose();
            md.sd_z_re = std::sqrt(std::max(0.0, Cz(0, 0)));
            md.sd_z_im = std::sqrt(std::max(0.0, Cz(1, 1)));
            // s = ln z / h: ds = k dz, k = 1 / (z h)
            const cd kk = 1.0 / (md.z * hh);
            MatR K(2, 2);
            K << kk.real(), -kk.imag(), kk.imag(), kk.real();
            const double sg = md.s.real(), om = md.s.imag(), w = md.wn;
            MatR W(2, 2);   // (wn, zeta) wrt (sigma, omega_d)
            W << sg / w, om / w, -1.0 / w + sg * sg / (w * w * w), sg * om / (w * w * w);
            const MatR Cq = W * K * Cz * K.transpose() * W.transpose();
            md.sd_wn = std::sqrt(std::max(0.0, Cq(0, 0)));
            md.sd_fn = md.sd_wn / (2 * M_PI);
            md.sd_zeta = std::sqrt(std::max(0.0, Cq(1, 1)));
        }
        out.push_back(md);
    }
    std::sort(out.begin(), out.end(), [](const MultiMode &a, const MultiMode &b) { return a.wn < b.wn; });
    return out;
}

namespace {

// From this many rows and multiply-adds (rows x parameters^2, about 10 ms) the normal matrix of the
// covariance is made in blocks of columns; below, in one product.
constexpr Eigen::Index NORMAL_SPLIT_ROWS = 4096;
constexpr double NORMAL_BLOCK_FLOPS = 1 << 24;

// J^T J of the full Jacobian (every sample's rows by the parameters: seconds on long records with many
// parameters), in blocks of columns of at least NORMAL_BLOCK_FLOPS each, one counted solve before
// each block. Every entry is the one product's: a block is that product's columns, a multiple of 8
// of them starting at a multiple of 8 (the fewer than 8 last columns with the block before them), so
// Eigen's kernel takes each column in the same group of its register tile and sums each entry over the
// rows in the same order (its depth blocks depend on the rows alone, once there are more rows than one
// of them: NORMAL_SPLIT_ROWS); and never one column alone, which would be a matrix-vector product.
MatR normal_matrix(const MatR &J)
{
    const Eigen::Index q = J.cols(), rows = J.rows();
    const double per_col = (double)rows * (double)q;
    if (rows < NORMAL_SPLIT_ROWS || q < 16 || per_col * (double)q < 2 * NORMAL_BLOCK_FLOPS) return J.transpose() * J;
    const Eigen::Index w = 8 * std::max<Eigen::Index>(1, (Eigen::Index)(NORMAL_BLOCK_FLOPS / per_col / 8.0));
    MatR JtJ(q, q);
    for (Eigen::Index c = 0; c < q;) {
        Eigen::Index n = std::min(w, q - c);
        if (q - c - n < 8) n = q - c;
        msidutil::checkpoint(msidutil::Step::solves, 1, "the multi fit");
        JtJ.middleCols(c, n).noalias() = J.transpose() * J.middleCols(c, n);
        c += n;
    }
    return JtJ;
}

// Fill a MultiResult from an evaluation at alpha (with the full Jacobian).
MultiResult result_at(const std::vector<MultiRecord> &recs, const Layout &L, const VecR &alpha, const MultiOptions &o)
{
    const Eval e = evaluate(recs, L, alpha, true, true);
    MultiResult r;
    r.n = L.n; r.nu = L.nu; r.ny = L.ny; r.d0 = L.d0; r.nb = L.nb;
    r.alpha = alpha;
    r.beta.assign((size_t)L.nb, MatR(L.ny, L.nu));
    for (int j = 0; j < L.ny; ++j)
        for (int k = 0; k < L.nu; ++k)
            for (int d = 0; d < L.nb; ++d) r.beta[(size_t)d](j, k) = e.beta(k * L.nb + d, j);
    for (const auto &c : e.c) r.x0.push_back(c.transpose());
    r.theta.resize(L.q());
    r.theta.head(L.n) = alpha;
    for (int m = 1; m <= L.n; ++m) r.names.push_back("alpha" + std::to_string(m));
    for (int j = 0; j < L.ny; ++j)
        for (int k = 0; k < L.nu; ++k)
            for (int d = 0; d < L.nb; ++d) {
                r.theta(L.n + j * L.p() + k * L.nb + d) = e.beta(k * L.nb + d, j);
                r.names.push_back("b[y" + std::to_string(j + 1) + ",u" + std::to_string(k + 1) + "," +
                                  std::to_string(d + L.d0) + "]");
            }
    r.cost = e.V;
    size_t S = 0;
    for (const auto &rc : recs) S += (size_t)rc.y.rows() * (size_t)L.ny;
    r.n_samples = S;
    r.dof = (double)S - L.q() - (L.elim ? (double)recs.size() * L.ny * L.n : 0.0);
    r.s2 = e.V / r.dof;
    // cov(theta) = s2 (J^T J)^-1 (pseudo-inverse with its rank if J is rank deficient)
    const MatR JtJ = normal_matrix(e.Jfull);
    Eigen::SelfAdjointEigenSolver<MatR> es(JtJ);
    const VecR ev = es.eigenvalues();
    const double tol = ev.cwiseAbs().maxCoeff() * 1e-14 * JtJ.rows();
    VecR inv(ev.size());
    r.cov_rank = 0;
    for (Eigen::Index k = 0; k < ev.size(); ++k) {
        inv(k) = ev(k) > tol ? 1.0 / ev(k) : 0.0;
        r.cov_rank += ev(k) > tol;
    }
    r.cov = r.s2 * es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
    r.grad_norm = (e.Ja.transpose() * residual_vec(e.R)).norm();
    r.modes = multi_modes(alpha, r.cov.topLeftCorner(L.n, L.n), o.h);
    if (L.W && !L.W->white()) {
        r.noise_ar = L.W->c;
        r.noise_source = "given";
        for (const auto &rc : recs) r.logdet += (double)L.ny * L.W->logdet(rc.y.rows());
    }
    return r;
}

}  // namespace

MultiResult multi_evaluate(const std::vector<MultiRecord> &recs, const VecR &alpha, const MultiOptions &o)
{
    check_records(recs, o);
    if (alpha.size() != o.order) throw FitError("alpha has the wrong length");
    const MultiNoise W = multi_noise_from_ar(o.noise_ar);
    Layout L = layout_of(recs, o);
    L.W = &W;
    return result_at(recs, L, alpha, o);
}

namespace {

// One fit with a fixed noise model W (nullptr: white); extra: a further start value (may be empty).
MultiResult fit_core(const std::vector<MultiRecord> &recs, const MultiOptions &o, const MultiNoise *W, const VecR &extra)
{
    Layout L = layout_of(recs, o);
    L.W = W;
    // start values (Kung on the stacked Hankel matrix for free responses; Prony / ARX; SM)
    std::vector<std::pair<std::string, VecR>> cand;
    const std::string st = o.start;
    if (st != "auto" && st != "kung" && st != "prony" && st != "sm")
        throw FitError("the start must be auto, kung, prony or sm (got '" + st + "')");
    if (st == "kung" && L.nu > 0) throw FitError("the Kung start needs free responses (records without inputs)");
    if ((st == "auto" || st == "kung") && L.nu == 0) cand.emplace_back("kung", multi_start_kung(recs, L.n));
    VecR pr;
    if (st == "auto" || st == "prony" || st == "sm") {
        pr = multi_start_prony(recs, L.n, L.d0);
        if (st != "sm") cand.emplace_back("prony", pr);
    }
    if ((st == "auto" && L.nu > 0) || st == "sm") cand.emplace_back("sm", multi_start_sm(recs, L.n, L.d0, pr, 5));
    if (extra.size() == L.n) cand.emplace_back("previous", extra);
    // A start whose values, linear parameters or cost are not finite is listed as failed and takes no
    // part in the choice. Poles outside the unit circle are its usual cause (the free responses and the
    // filtered inputs grow like |z|^T and overflow on a long record): the start is then tried once more
    // with those poles reflected to 1 / conj(z), as "<name>-reflected".
    std::vector<MultiStart> starts;
    VecR a;
    double V = INFINITY;
    std::string best;
    for (size_t ci = 0; ci < cand.size(); ++ci) {
        const std::string name = cand[ci].first;
        const VecR al = cand[ci].second;
        MultiStart s{name, NAN, ""};
        if (!al.allFinite()) {
            s.failed = "its pole coefficients are not finite";
        } else {
            const Eval ev = evaluate(recs, L, al, false, false);
            int unstable = 0;
            multi_reflect_unstable(al, &unstable);
            if (std::isfinite(ev.V) && ev.beta.allFinite()) {
                s.cost = ev.V;
                if (ev.V < V) { V = ev.V; a = al; best = name; }
            } else {
                s.failed = unstable ? "the cost is not finite: " + std::to_string(unstable) +
                                          " pole(s) outside the unit circle, the model response overflows over the records"
                                    : "the cost is not finite";
                if (unstable && name.find("-reflected") == std::string::npos)
                    cand.emplace_back(name + "-reflected", multi_reflect_unstable(al, nullptr));
            }
        }
        starts.push_back(s);
    }
    if (!std::isfinite(V)) {
        std::string why;
        for (const auto &s : starts) why += (why.empty() ? "" : "; ") + s.name + ": " + s.failed;
        throw FitError("no start value gives a finite cost (" + why + "): the records do not fit an order-" +
                       std::to_string(L.n) + " model");
    }
    // Levenberg-Marquardt on V(alpha) with the variable-projection Jacobian (Marquardt scaling)
    Eval e = evaluate(recs, L, a, true, false);
    double lambda = 1e-3;
    bool converged = false;
    int it = 0;
    for (; it < o.max_iter && !converged; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the multi fit");
        const VecR r = residual_vec(e.R);
        const MatR JtJ = e.Ja.transpose() * e.Ja;
        const VecR g = e.Ja.transpose() * r;
        VecR dsc = JtJ.diagonal().cwiseMax(1e-300);
        bool accepted = false;
        while (!accepted) {
            MatR M = JtJ;
            M.diagonal() += lambda * dsc;
            const VecR step = -M.ldlt().solve(g);
            const VecR an = a + step;
            Eval en = evaluate(recs, L, an, true, false);
            if (std::isfinite(en.V) && en.V <= e.V) {
                const double dec = e.V - en.V;
                const bool small_step = step.norm() <= 1e-12 * (a.norm() + 1e-12);
                a = an;
                e = std::move(en);
                lambda = std::max(1e-12, lambda / 3);
                accepted = true;
                if (dec <= 1e-13 * e.V || small_step) converged = true;
            } else {
                lambda *= 4;
                if (lambda > 1e16) { converged = true; break; }   // no descent left: a (local) minimum
            }
        }
    }
    MultiResult res = result_at(recs, L, a, o);
    res.iterations = it;
    res.converged = converged;
    res.starts = starts;
    res.best_start = best;
    return res;
}

}  // namespace

MultiResult multi_fit(const std::vector<MultiRecord> &recs, const MultiOptions &o)
{
    check_records(recs, o);
    if (o.noise_ar.size() > 0) {
        const MultiNoise W = multi_noise_from_ar(o.noise_ar);
        return fit_core(recs, o, &W, VecR());
    }
    MultiResult r = fit_core(recs, o, nullptr, VecR());
    if (o.noise_ar_order <= 0) return r;
    // two-stage GLS: AR(p) by Yule-Walker on the raw residuals y - yhat of the previous fit
    // (initial conditions eliminated: the residuals are the noise up to n ny dimensions per record), refit
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<MatR> res;
        for (size_t i = 0; i < recs.size(); ++i)
            res.push_back(recs[i].y - multi_simulate(r.alpha, r.beta, r.d0, recs[i].u.rows() ? recs[i].u : MatR(recs[i].y.rows(), 0),
                                                     r.x0[i], r.ny));
        const MultiNoise W = multi_noise_from_ar(multi_ar_yule_walker(res, o.noise_ar_order));
        r = fit_core(recs, o, &W, r.alpha);
    }
    r.noise_source = "estimated from residuals";
    return r;
}

}  // namespace msidfit
