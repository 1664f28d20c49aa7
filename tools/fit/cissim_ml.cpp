// ML refinement of a discrete-cISSIM model and its uncertainty (cissim.hpp, docs/fitting.md "cissim").
// Not in You et al. 2023: their Alg. 4 + 5 is a subspace estimate, consistent but not efficient; on few
// lines near lightly damped poles it loses most of the information in the data. Here the cissim model
// starts a weighted output-error (maximum likelihood) fit on the same ISP phasors:
//   e_l = Y_l - G(z_l) U_l,  W_l = [-G_l I] S_l [-G_l I]^H,  V = sum e_l^H W_l^-1 e_l,
// with S_l the sample covariance of the per-period phasors (the FRF step's estimate; exact finite-sample
// distribution: K - 1 complex dof). Jacobian of G = C X B + D, X = (z I - A)^-1:
//   dG/dA_ij = (C X)_:i (X B)_j: ,  dG/dB_ij = (C X)_:i e_j^T,  dG/dC_ij = e_i (X B)_j: ,  dG/dD_ij = e_i e_j^T.
#include "cissim.hpp"
#include "lmfd_fit.hpp"
#include "small_lu.hpp"
#include "msid_cancel.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <vector>

namespace msidfit {

namespace {

struct Dims {
    Eigen::Index n, nu, ny, pA, pB, pC, pD, p;
    explicit Dims(const SSModel &m)
        : n(m.A.rows()), nu(m.B.cols()), ny(m.C.rows()), pA(n * n), pB(n * nu), pC(ny * n), pD(ny * nu),
          p(pA + pB + pC + pD)
    {
    }
};

VecR pack(const SSModel &m)
{
    const Dims d(m);
    VecR th(d.p);
    th << Eigen::Map<const VecR>(m.A.data(), d.pA), Eigen::Map<const VecR>(m.B.data(), d.pB),
        Eigen::Map<const VecR>(m.C.data(), d.pC), Eigen::Map<const VecR>(m.D.data(), d.pD);
    return th;
}

SSModel unpack(const SSModel &like, const VecR &th)
{
    const Dims d(like);
    SSModel m = like;
    m.A = Eigen::Map<const MatR>(th.data(), d.n, d.n);
    m.B = Eigen::Map<const MatR>(th.data() + d.pA, d.n, d.nu);
    m.C = Eigen::Map<const MatR>(th.data() + d.pA + d.pB, d.ny, d.n);
    m.D = Eigen::Map<const MatR>(th.data() + d.pA + d.pB + d.pC, d.ny, d.nu);
    return m;
}

struct Term {
    cd z;
    bool dc;
    VecC U, Y;
    MatC Li;   // inverse Cholesky factor of W_l (ny x ny)
};

// W_l = [-G I] S [-G I]^H at the model's G; its inverse Cholesky factor.
std::vector<Term> make_terms(const SSModel &m, const std::vector<IspResult> &isp)
{
    std::vector<Term> t;
    const Eigen::Index ny = m.C.rows(), nu = m.B.cols();
    for (const auto &r : isp) {
        if (r.line_cov.size() != r.bins.size())
            throw FitError("the ML refinement of cissim needs the per-line noise covariance of the phasors: at least 2 "
                           "whole periods per experiment after the skipped ones");
        for (size_t l = 0; l < r.bins.size(); ++l) {
            Term tm;
            tm.z = std::polar(1.0, 2.0 * M_PI * (double)r.bins[l] / r.period);
            tm.dc = r.bins[l] == 0;
            tm.U = r.U.col((Eigen::Index)l);
            tm.Y = r.Y.col((Eigen::Index)l);
            MatC M(ny, nu + ny);
            M << -cissim_eval(m, tm.z), MatC::Identity(ny, ny);
            MatC W = M * r.line_cov[l] * M.adjoint();
            W = 0.5 * (W + W.adjoint()).eval();
            const double tr = W.diagonal().real().sum();
            if (!(tr > 0) || !std::isfinite(tr))
                throw FitError("the ML refinement of cissim: the output noise of line " + std::to_string(r.bins[l]) +
                               " is zero or not finite (a noise-free record needs no refinement: use --refine none)");
            Eigen::LLT<MatC> llt(W);
            if (llt.info() != Eigen::Success)
                throw FitError("the ML refinement of cissim: the noise covariance of line " + std::to_string(r.bins[l]) +
                               " is singular (more outputs than periods - 1?)");
            tm.Li = llt.matrixL().solve(MatC::Identity(ny, ny));
            t.push_back(tm);
        }
    }
    return t;
}

// One evaluation of G(z) U and its Jacobian over the terms, with the matrices of one model and
// working memory reused from term to term (a fit evaluates hundreds of terms per step).
struct TermEval {
    Dims d;
    MatC A, B, C, D, Ct, XB, CXt;
    VecC XBU, GU;
    SmallLu lu;
    explicit TermEval(const SSModel &m)
        : d(m), A(m.A.cast<cd>()), B(m.B.cast<cd>()), C(m.C.cast<cd>()), D(m.D.cast<cd>()), Ct(C.transpose()),
          XB(d.n, d.nu), CXt(d.n, d.ny), XBU(d.n), GU(d.ny), lu(d.n)
    {
    }
    // GU = C (z I - A)^-1 B U + D U; with `jac` also (C X)^T for the Jacobian (residual()): one LU of
    // z I - A serves X B and, transposed, C X.
    void at(cd z, const VecC &U, bool jac)
    {
        lu.compute(A, z);
        lu.solve(B, XB);
        XBU.noalias() = XB.lazyProduct(U);
        GU.noalias() = C.lazyProduct(XBU);
        GU.noalias() += D.lazyProduct(U);
        if (!jac) return;
        lu.solve_t(Ct, CXt);   // (C X)^T
    }
    // The real Jacobian [Re; Im] of vec G(z) (2 ny nu x p): row a + ny b of the complex one is
    // dG_ab/dtheta, dG/dA_ij = (C X)_:i (X B)_j:, dG/dB_ij = (C X)_:i e_j^T, dG/dC_ij = e_i (X B)_j:,
    // dG/dD_ij = e_i e_j^T.
    void jac_G(cd z, MatR &Jr)
    {
        lu.compute(A, z);
        lu.solve(B, XB);
        lu.solve_t(Ct, CXt);
        const Eigen::Index g = d.ny * d.nu, n = d.n;
        Jr.setZero(2 * g, d.p);
        for (Eigen::Index b = 0; b < d.nu; ++b)
            for (Eigen::Index a = 0; a < d.ny; ++a) {
                const Eigen::Index row = a + d.ny * b;
                for (Eigen::Index j = 0; j < n; ++j)
                    for (Eigen::Index i = 0; i < n; ++i) {
                        const cd v = CXt(i, a) * XB(j, b);
                        Jr(row, i + n * j) = v.real(), Jr(g + row, i + n * j) = v.imag();
                    }
                for (Eigen::Index i = 0; i < n; ++i)
                    Jr(row, d.pA + i + n * b) = CXt(i, a).real(), Jr(g + row, d.pA + i + n * b) = CXt(i, a).imag();
                for (Eigen::Index j = 0; j < n; ++j)
                    Jr(row, d.pA + d.pB + a + d.ny * j) = XB(j, b).real(),
                            Jr(g + row, d.pA + d.pB + a + d.ny * j) = XB(j, b).imag();
                Jr(row, d.pA + d.pB + d.pC + row) = 1.0;
            }
    }
};

// Real residual r (components of variance 1/2 under the model) and optionally its Jacobian.
void residual(const SSModel &m, const std::vector<Term> &terms, VecR &r, MatR *J)
{
    TermEval ev(m);
    const Dims &d = ev.d;
    Eigen::Index rows = 0;
    for (const auto &t : terms) rows += t.dc ? d.ny : 2 * d.ny;
    r.resize(rows);
    if (J) J->resize(rows, d.p);
    Eigen::Index row = 0;
    VecC w(d.ny), e(d.ny);
    MatC LCX(d.ny, d.n);
    const Eigen::Index n = d.n, ny = d.ny, ld = rows;
    for (const auto &t : terms) {
        ev.at(t.z, t.U, J != nullptr);
        e = t.Y - ev.GU;
        w.noalias() = t.Li.lazyProduct(e);
        const double s = t.dc ? std::sqrt(0.5) : 1.0;
        r.segment(row, ny) = s * w.real();
        if (!t.dc) r.segment(row + ny, ny) = w.imag();
        if (J) {
            // the whitened Jacobian Li Jc column by column: every column of Jc is a column of C X
            // (A, B) or of I (C, D) times an entry of X B U or U, so Li Jc is that of Li C X or Li
            LCX.noalias() = t.Li.lazyProduct(ev.CXt.transpose());
            double *Jd = J->data();
            auto put = [&](Eigen::Index col, const cd *v, cd f) {   // column `col`: -(v f), v of ny entries
                double *c = Jd + col * ld + row;
                for (Eigen::Index i = 0; i < ny; ++i) {
                    const cd x = v[i] * f;
                    c[i] = -s * x.real();
                    if (!t.dc) c[ny + i] = -x.imag();
                }
            };
            for (Eigen::Index j = 0; j < n; ++j)
                for (Eigen::Index i = 0; i < n; ++i) put(i + n * j, LCX.col(i).data(), ev.XBU(j));
            for (Eigen::Index j = 0; j < d.nu; ++j)
                for (Eigen::Index i = 0; i < n; ++i) put(d.pA + i + n * j, LCX.col(i).data(), t.U(j));
            for (Eigen::Index j = 0; j < n; ++j)
                for (Eigen::Index i = 0; i < ny; ++i) put(d.pA + d.pB + i + ny * j, t.Li.col(i).data(), ev.XBU(j));
            for (Eigen::Index j = 0; j < d.nu; ++j)
                for (Eigen::Index i = 0; i < ny; ++i) put(d.pA + d.pB + d.pC + i + ny * j, t.Li.col(i).data(), t.U(j));
        }
        row += t.dc ? ny : 2 * ny;
    }
}

double max_pole(const MatR &A)
{
    Eigen::EigenSolver<MatR> es(A, false);
    double w = 0;
    for (Eigen::Index k = 0; k < A.rows(); ++k) w = std::max(w, std::abs(es.eigenvalues()(k)));
    return w;
}

// Levenberg-Marquardt (Marquardt's diagonal scaling); steps that would make a stable model unstable
// are refused like steps that raise the cost (Assumption 1).
SSModel lm(const SSModel &start, const std::vector<Term> &terms, const CissimMlOptions &o, int &iters, bool &conv,
           double &cost)
{
    SSModel m = start;
    const bool keep_stable = max_pole(m.A) < 1.0;
    VecR r;
    MatR J;
    residual(m, terms, r, &J);
    cost = r.squaredNorm();
    double lambda = 1e-3;
    conv = false;
    for (int it = 0; it < o.max_iter; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the cissim fit");
        ++iters;
        const VecR g = J.transpose() * r;
        MatR H = MatR::Zero(J.cols(), J.cols());
        H.selfadjointView<Eigen::Lower>().rankUpdate(J.transpose());
        H = H.selfadjointView<Eigen::Lower>();
        const VecR dg = H.diagonal().cwiseMax(1e-300 * std::max(1.0, H.diagonal().maxCoeff()));
        bool accepted = false;
        for (int tries = 0; tries < 30; ++tries) {
            // a try is a factorisation of the p x p normal matrix (p = n^2 + ...: a part of a second at order 40)
            msidutil::checkpoint(msidutil::Step::solves, 0, "the cissim fit");
            MatR Hl = H;
            Hl.diagonal() += lambda * dg;
            const VecR step = -Hl.ldlt().solve(g);
            const SSModel mt = unpack(m, pack(m) + step);
            VecR rt;
            bool ok = step.allFinite() && (!keep_stable || max_pole(mt.A) < 1.0);
            if (ok) {
                residual(mt, terms, rt, nullptr);
                ok = rt.allFinite() && rt.squaredNorm() < cost;
            }
            if (ok) {
                const double rel = (cost - rt.squaredNorm()) / std::max(cost, 1e-300);
                m = mt;
                cost = rt.squaredNorm();
                residual(m, terms, r, &J);
                lambda = std::max(lambda / 5.0, 1e-12);
                accepted = true;
                if (rel < o.tol) conv = true;
                break;
            }
            lambda *= 10.0;
            if (lambda > 1e12) break;
        }
        if (!accepted) {
            conv = true;   // no descent step left: a (local) minimum to working precision
            break;
        }
        if (conv) break;
    }
    return m;
}

}  // namespace

MatC cissim_eval(const SSModel &m, cd z)
{
    const Eigen::Index n = m.A.rows();
    if (n == 0) return m.D.cast<cd>();
    SmallLu lu(n);
    lu.compute(m.A, z);
    MatC XB;
    lu.solve(m.B.cast<cd>(), XB);
    return m.C.cast<cd>() * XB + m.D.cast<cd>();
}

MatR cissim_frf_cov(const SSModel &m, const MatR &cov, cd z)
{
    TermEval ev(m);
    MatR Jr;
    ev.jac_G(z, Jr);
    return Jr * cov * Jr.transpose();
}

CissimMlResult cissim_refine(const SSModel &start, const std::vector<IspResult> &isp, const CissimMlOptions &o)
{
    if (isp.empty()) throw FitError("cissim refinement needs at least one experiment");
    CissimMlResult res;
    SSModel m = start;
    m.domain = Domain::DT;
    std::vector<Term> terms = make_terms(m, isp);
    {
        VecR r0;
        residual(m, terms, r0, nullptr);
        res.cost_start = r0.squaredNorm();
    }
    bool conv = false;
    double cost = 0;
    for (int pass = 0; pass <= std::max(0, o.reweight); ++pass) {
        if (pass > 0) terms = make_terms(m, isp);   // W_l at the refined G (input noise enters through G)
        m = lm(m, terms, o, res.iterations, conv, cost);
    }
    res.model = m;
    res.converged = conv;
    res.cost = cost;
    VecR r;
    MatR J;
    residual(m, terms, r, &J);
    // the covariance's two decompositions of the p x p Fisher information: seconds at order 40, abandoned on a stop
    struct Cov {
        MatR cov;
        int rank = 0;
    };
    Cov fc = msidutil::abandonable<Cov>(
        [J] {
            Cov c;
            c.cov = fisher_cov(J, c.rank);
            return c;
        },
        msidutil::Step::solves, "the cissim fit");
    res.cov = std::move(fc.cov);
    res.cov_rank = fc.rank;
    // sample-ML factor for weights with K - 1 complex dof (lmfd_fit.cpp, sample_ml_factor)
    double kmin = 1e300;
    for (const auto &e : isp) kmin = std::min(kmin, (double)e.periods - 1.0);
    const double p = (double)m.C.rows();
    res.cov_factor = kmin > p + 1.0 ? kmin / (kmin - p - 1.0) : std::numeric_limits<double>::infinity();
    if (std::isfinite(res.cov_factor)) res.cov *= res.cov_factor;   // else: too few periods, no uncertainty (caller)
    res.dof = (double)r.size() - res.cov_rank;
    res.bins = isp[0].bins;
    // J_G cov J_G^T at every line through a factor cov = Q Q^T of the rank of the Fisher information
    // (cov is positive semi-definite): a third of the products of J_G cov J_G^T per line
    const Eigen::SelfAdjointEigenSolver<MatR> es = msidutil::abandonable<Eigen::SelfAdjointEigenSolver<MatR>>(
        [C = MatR(0.5 * (res.cov + res.cov.transpose()))] { return Eigen::SelfAdjointEigenSolver<MatR>(C); },
        msidutil::Step::solves, "the cissim fit");
    const VecR ev = es.eigenvalues();
    const double floor = 1e-14 * std::max(ev.maxCoeff(), 1e-300);
    Eigen::Index keep = 0;
    for (Eigen::Index k = 0; k < ev.size(); ++k) keep += ev(k) > floor;
    const MatR Q = es.eigenvectors().rightCols(keep) * ev.tail(keep).cwiseSqrt().asDiagonal();
    TermEval te(m);
    MatR Jr, JQ;
    for (uint32_t b : res.bins) {
        const cd z = std::polar(1.0, 2.0 * M_PI * (double)b / isp[0].period);
        res.G.push_back(cissim_eval(m, z));
        te.jac_G(z, Jr);
        JQ.noalias() = Jr * Q;
        res.Gcov.push_back(JQ * JQ.transpose());
        msidutil::checkpoint(msidutil::Step::lines, 1, "the cissim fit");
    }
    return res;
}

}  // namespace msidfit
