#include "poleres.hpp"
#include "lmfd_fit.hpp"
#include "stats.hpp"
#include "subspace.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace msidfit {

// Reflect into the stable region: CT Re p -> -|Re p|, DT |p| -> 1/|p|.
static cd reflect(cd p, Domain d, int *count)
{
    if (d == Domain::CT && p.real() > 0) { if (count) ++*count; return cd(-p.real(), p.imag()); }
    if (d == Domain::DT && std::abs(p) > 1) { if (count) ++*count; return 1.0 / std::conj(p); }
    return p;
}

namespace {

struct Prob {
    Eigen::Index ny = 0, nu = 0, g = 0, rows = 0;
    Domain d = Domain::CT;
    double ws = 1.0;
    std::vector<cd> xt;                       // scaled frequency variable
    const std::vector<WeightedLine> *w = nullptr;
};

// Parameter layout: poles (1 or 2 each), then residues (g or 2g each), then D (g).
struct Layout {
    std::vector<char> pair;
    std::vector<Eigen::Index> po, ro;
    Eigen::Index dof = 0, n = 0, nlin = 0, npole = 0;
    bool D = true;
};

Layout make_layout(const std::vector<cd> &poles, Eigen::Index g, bool D)
{
    Layout L;
    L.D = D;
    for (const cd &p : poles) L.pair.push_back(p.imag() > 0);
    Eigen::Index t = 0;
    for (char pr : L.pair) { L.po.push_back(t); t += pr ? 2 : 1; }
    L.npole = t;
    for (char pr : L.pair) { L.ro.push_back(t); t += pr ? 2 * g : g; }
    L.dof = t;
    if (D) t += g;
    L.n = t;
    L.nlin = t - L.npole;
    return L;
}

double scan_ws(const std::vector<WeightedLine> &w, Domain d, double ws)
{
    if (d != Domain::CT) return 1.0;
    if (ws > 0) return ws;
    double lo = 1e300, hi = 0;
    for (const auto &l : w) {
        const double om = std::abs(l.x.imag());
        if (om > 0) { lo = std::min(lo, om); hi = std::max(hi, om); }
    }
    return hi > 0 ? std::sqrt(lo * hi) : 1.0;
}

Prob make_prob(const std::vector<WeightedLine> &w, Domain d, double ws)
{
    Prob P;
    P.w = &w;
    P.d = d;
    P.ny = w[0].G.rows();
    P.nu = w[0].G.cols();
    P.g = P.ny * P.nu;
    P.ws = scan_ws(w, d, ws);
    for (const auto &l : w) {
        P.xt.push_back(l.x / P.ws);
        P.rows += l.real ? P.g : 2 * P.g;
    }
    return P;
}

cd pole_of(const Layout &L, const VecR &th, size_t k)
{
    return L.pair[k] ? cd(th(L.po[k]), th(L.po[k] + 1)) : cd(th(L.po[k]), 0.0);
}

cd res_of(const Layout &L, const VecR &th, size_t k, Eigen::Index ij, Eigen::Index g)
{
    return L.pair[k] ? cd(th(L.ro[k] + ij), th(L.ro[k] + g + ij)) : cd(th(L.ro[k] + ij), 0.0);
}

// Model vec(G) at line li and, if Jc, the whitened Jacobian -Linv d vec(G) / d theta (g x n,
// scaled coordinates). The residue and D columns of d vec(G) are unit vectors times a scalar,
// so their whitened columns are multiples of the columns of Linv: only the pole block needs a product.
void line_terms(const Prob &P, const Layout &L, const VecR &th, size_t li, const MatC &Linv, VecC &gm, MatC *Jc, MatC &dGp)
{
    const Eigen::Index g = P.g;
    const cd x = P.xt[li], I(0, 1);
    gm.setZero(g);
    if (Jc) { dGp.setZero(g, L.npole); Jc->setZero(g, L.n); }
    for (size_t k = 0; k < L.pair.size(); ++k) {
        const cd p = pole_of(L, th, k), q = 1.0 / (x - p);
        const cd q2 = L.pair[k] ? 1.0 / (x - std::conj(p)) : 0.0;
        for (Eigen::Index ij = 0; ij < g; ++ij) {
            const cd R = res_of(L, th, k, ij, g);
            if (L.pair[k]) {
                gm(ij) += R * q + std::conj(R) * q2;
                if (Jc) {
                    const cd a = R * q * q, b = std::conj(R) * q2 * q2;
                    dGp(ij, L.po[k]) = a + b;
                    dGp(ij, L.po[k] + 1) = I * (a - b);
                    Jc->col(L.ro[k] + ij) = -(q + q2) * Linv.col(ij);
                    Jc->col(L.ro[k] + g + ij) = -(I * (q - q2)) * Linv.col(ij);
                }
            } else {
                gm(ij) += R * q;
                if (Jc) {
                    dGp(ij, L.po[k]) = R * q * q;
                    Jc->col(L.ro[k] + ij) = -q * Linv.col(ij);
                }
            }
        }
    }
    if (L.D)
        for (Eigen::Index ij = 0; ij < g; ++ij) {
            gm(ij) += th(L.dof + ij);
            if (Jc) Jc->col(L.dof + ij) = -Linv.col(ij);
        }
    if (Jc) Jc->leftCols(L.npole).noalias() = -(Linv * dGp);
}

// Whitened real residual r = Linv vec(G - G(theta)) (real lines scaled by sqrt 1/2) and J = dr/dtheta.
void resid(const Prob &P, const Layout &L, const VecR &th, VecR &r, MatR *J)
{
    const Eigen::Index g = P.g;
    r.resize(P.rows);
    if (J) J->resize(P.rows, L.n);   // every entry is written below (no memset of a large matrix)
    VecC gm(g);
    MatC dGp, Jc;
    Eigen::Index r0 = 0;
    for (size_t li = 0; li < P.xt.size(); ++li) {
        const WeightedLine &l = (*P.w)[li];
        line_terms(P, L, th, li, l.Linv, gm, J ? &Jc : nullptr, dGp);
        const VecC e = l.Linv * (Eigen::Map<const VecC>(l.G.data(), g) - gm);
        const double sc = l.real ? std::sqrt(0.5) : 1.0;
        r.segment(r0, g) = sc * e.real();
        if (!l.real) r.segment(r0 + g, g) = e.imag();
        if (J) {
            J->block(r0, 0, g, L.n) = sc * Jc.real();
            if (!l.real) J->block(r0 + g, 0, g, L.n) = Jc.imag();
        }
        r0 += l.real ? g : 2 * g;
    }
}

// J^T J (symmetric rank update: half the flops of the plain product).
template <class Mat> MatR gram(const Mat &J)
{
    MatR M = MatR::Zero(J.cols(), J.cols());
    M.selfadjointView<Eigen::Lower>().rankUpdate(J.transpose());
    return M.selfadjointView<Eigen::Lower>();
}

// Solve a scaled symmetric system (J^T J) x = b with column scaling; pseudo-inverse below rel. tol.
VecR scaled_solve(const MatR &JtJ, const VecR &b, double lambda)
{
    const VecR s = JtJ.diagonal().cwiseMax(1e-300).cwiseSqrt();
    MatR M = s.cwiseInverse().asDiagonal() * JtJ * s.cwiseInverse().asDiagonal();
    M.diagonal().array() += lambda;
    Eigen::LDLT<MatR> ldlt(M);
    VecR x = ldlt.solve(s.cwiseInverse().cwiseProduct(b));
    if (ldlt.info() != Eigen::Success || !x.allFinite() || !(ldlt.vectorD().minCoeff() > 1e-13 * ldlt.vectorD().maxCoeff())) {
        Eigen::SelfAdjointEigenSolver<MatR> es(M);
        const VecR ev = es.eigenvalues();
        const double tol = 1e-13 * std::max(ev.maxCoeff(), 1e-300);
        VecR inv = ev.unaryExpr([&](double v) { return v > tol ? 1.0 / v : 0.0; });
        x = es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose() * s.cwiseInverse().cwiseProduct(b);
    }
    return s.cwiseInverse().cwiseProduct(x);
}

// Residues and D by weighted least squares for the current poles (variable projection step):
// r is affine in them, r(c + dc) = r + J_lin dc; normal equations in unit-scaled columns.
void solve_linear(const Prob &P, const Layout &L, VecR &th, VecR &r, MatR &J)
{
    resid(P, L, th, r, &J);
    const auto Jl = J.rightCols(L.nlin);
    const VecR dl = scaled_solve(gram(Jl), -(Jl.transpose() * r), 0.0);
    if (dl.allFinite()) th.tail(L.nlin) += dl;
}

// Fix up after a step: poles with Im < 0 become their conjugate (residues conjugated), stable reflection.
void canonical(const Layout &L, VecR &th, Domain d, bool stable, Eigen::Index g, int *refl)
{
    for (size_t k = 0; k < L.pair.size(); ++k) {
        cd p = pole_of(L, th, k);
        if (L.pair[k] && p.imag() < 0) {
            p = std::conj(p);
            th.segment(L.ro[k] + g, g) *= -1.0;
        }
        if (stable) p = reflect(p, d, refl);
        th(L.po[k]) = p.real();
        if (L.pair[k]) th(L.po[k] + 1) = p.imag();
    }
}

struct LmOut {
    VecR th;
    double V = 0, gnorm = 0;
    bool conv = false;
    int iters = 0;
};

LmOut lm(const Prob &P, const Layout &L, VecR th, int max_iter, double tol, bool stable, int *refl)
{
    LmOut o;
    VecR r, r2;
    MatR J, J2;
    canonical(L, th, P.d, stable, P.g, refl);
    solve_linear(P, L, th, r, J);
    resid(P, L, th, r, &J);
    double V = r.squaredNorm(), lambda = 1e-3;
    int it = 0;
    for (; it < max_iter; ++it) {
        const MatR JtJ = gram(J);
        const VecR grad = J.transpose() * r;
        const VecR sd = JtJ.diagonal().cwiseMax(1e-300).cwiseSqrt();
        o.gnorm = grad.cwiseQuotient(sd).norm();
        if (o.gnorm <= 1e-9 * std::sqrt(std::max(V, 1e-300))) { o.conv = true; break; }
        bool stepped = false;
        for (int tries = 0; tries < 40 && !stepped; ++tries) {
            VecR th2 = th + scaled_solve(JtJ, -grad, lambda);
            canonical(L, th2, P.d, stable, P.g, nullptr);
            resid(P, L, th2, r2, nullptr);
            double V2 = r2.squaredNorm();
            if (std::isfinite(V2) && V2 < V) {
                solve_linear(P, L, th2, r2, J2);
                resid(P, L, th2, r2, &J2);
                const double V3 = r2.squaredNorm();
                if (std::isfinite(V3) && V3 <= V2) V2 = V3;
                const double rel = (V - V2) / std::max(V, 1e-300);
                th = th2;
                V = V2;
                r.swap(r2);
                J.swap(J2);
                lambda = std::max(lambda / 5.0, 1e-12);
                stepped = true;
                if (rel < tol) o.conv = true;
            } else {
                lambda *= 4.0;
            }
        }
        if (o.conv) { ++it; break; }
        if (!stepped) {
            // no descent possible from here: a (numerical) stationary point if the gradient is small
            o.conv = o.gnorm <= 1e-5 * std::sqrt(std::max(V, 1.0));
            break;
        }
    }
    if (stable) canonical(L, th, P.d, true, P.g, refl);
    resid(P, L, th, r, &J);
    o.V = r.squaredNorm();
    const MatR JtJ = gram(J);
    o.gnorm = (J.transpose() * r).cwiseQuotient(JtJ.diagonal().cwiseMax(1e-300).cwiseSqrt()).norm();
    o.th = th;
    o.iters = it;
    return o;
}

VecR theta_from_poles(const Layout &L, const std::vector<cd> &poles, double ws)
{
    VecR th = VecR::Zero(L.n);
    for (size_t k = 0; k < poles.size(); ++k) {
        th(L.po[k]) = poles[k].real() / ws;
        if (L.pair[k]) th(L.po[k] + 1) = poles[k].imag() / ws;
    }
    return th;
}

}  // namespace

std::vector<cd> vector_fit_poles(const std::vector<WeightedLine> &w, Domain d, int order, bool feedthrough, int iters,
                                 double wscale, bool relaxed)
{
    const Prob P = make_prob(w, d, wscale);
    const Eigen::Index F = (Eigen::Index)w.size(), g = P.g;
    // starting poles (Gustavsen & Semlyen 1999 §4): pairs spread over the band, Re = -Im/100
    std::vector<cd> poles;
    double lo = 1e300, hi = 0;
    for (const cd &x : P.xt) {
        const double a = d == Domain::CT ? std::abs(x.imag()) : std::abs(std::arg(x));
        if (a > 0) { lo = std::min(lo, a); hi = std::max(hi, a); }
    }
    if (!(hi > 0)) throw FitError("vector fitting needs lines above DC");
    const int npair = order / 2;
    for (int k = 0; k < npair; ++k) {
        const double f = npair > 1 ? (double)k / (npair - 1) : 0.5;
        if (d == Domain::CT) {
            const double om = relaxed ? lo + (hi - lo) * f : lo * std::pow(hi / lo, f);
            poles.push_back(cd(-om / 100.0, om));
        } else {
            const double th = lo + (hi - lo) * f;
            poles.push_back(std::polar(0.97, th));
        }
    }
    if (order % 2) poles.push_back(cd(d == Domain::CT ? -lo : 0.5, 0.0));
    // weights: 1/sqrt of the diagonal of each line covariance (real lines: sqrt(1/2))
    MatR wt(F, g);
    for (Eigen::Index l = 0; l < F; ++l)
        for (Eigen::Index ij = 0; ij < g; ++ij)
            wt(l, ij) = (w[(size_t)l].real ? std::sqrt(0.5) : 1.0) / std::sqrt(std::max(w[(size_t)l].cov(ij, ij).real(), 1e-300));
    const Eigen::Index nd = feedthrough ? 1 : 0;
    for (int it = 0; it < iters; ++it) {
        std::vector<char> pair;
        for (const cd &p : poles) pair.push_back(p.imag() > 0);
        const Eigen::Index N = (Eigen::Index)std::count(pair.begin(), pair.end(), 1) * 2 +
                               (Eigen::Index)std::count(pair.begin(), pair.end(), 0);
        // each response's 2F real rows must determine its 2N + nd (+1 relaxed) unknowns before the
        // sigma rows are taken from its QR: with fewer lines than that (several outputs can fit an
        // order that one response's lines cannot) the poles stay where they are
        if (2 * F < 2 * N + nd + (relaxed ? 1 : 0)) break;
        MatC Phi(F, N);
        for (Eigen::Index l = 0; l < F; ++l) {
            Eigen::Index c = 0;
            for (size_t k = 0; k < poles.size(); ++k) {
                const cd q = 1.0 / (P.xt[(size_t)l] - poles[k]);
                if (pair[k]) {
                    const cd q2 = 1.0 / (P.xt[(size_t)l] - std::conj(poles[k]));
                    Phi(l, c++) = q + q2;
                    Phi(l, c++) = cd(0, 1) * (q - q2);
                } else {
                    Phi(l, c++) = q;
                }
            }
        }
        // fast VF: per response QR, keep the rows that only involve the sigma coefficients.
        // Relaxed (Gustavsen 2006): sigma = sum c~ Phi + d~ with d~ free, every response's rows
        // homogeneous, and one more row Re sum_l sigma(x_l) = F (weighted by |w G| / F) against the
        // trivial solution; the new poles are the zeros of sigma, eig(A - b c~^T / d~).
        const Eigen::Index ns = N + (relaxed ? 1 : 0);   // sigma's unknowns
        MatR S(g * ns + (relaxed ? 1 : 0), ns);
        VecR sb = VecR::Zero(S.rows());
        double wg2 = 0.0;   // |w G|^2 over lines and responses (the extra row's weight)
        for (Eigen::Index ij = 0; ij < g; ++ij) {
            MatR A(2 * F, 2 * N + nd + (relaxed ? 1 : 0));
            VecR b(2 * F);
            for (Eigen::Index l = 0; l < F; ++l) {
                const double ww = wt(l, ij);
                const cd Gv = w[(size_t)l].G.data()[ij];
                for (Eigen::Index c = 0; c < N; ++c) {
                    const cd a = ww * Phi(l, c), s = -ww * Gv * Phi(l, c);
                    A(2 * l, c) = a.real(); A(2 * l + 1, c) = a.imag();
                    A(2 * l, N + nd + c) = s.real(); A(2 * l + 1, N + nd + c) = s.imag();
                }
                if (nd) { A(2 * l, N) = ww; A(2 * l + 1, N) = 0.0; }
                if (relaxed) {   // -G d~
                    A(2 * l, 2 * N + nd) = -ww * Gv.real();
                    A(2 * l + 1, 2 * N + nd) = -ww * Gv.imag();
                    wg2 += std::norm(ww * Gv);
                }
                b(2 * l) = relaxed ? 0.0 : ww * Gv.real();
                b(2 * l + 1) = relaxed ? 0.0 : ww * Gv.imag();
            }
            const Eigen::Index nc = A.cols();
            Eigen::HouseholderQR<MatR> qr(A);
            const MatR Rf = qr.matrixQR().topRows(nc).triangularView<Eigen::Upper>();
            S.block(ij * ns, 0, ns, ns) = Rf.block(N + nd, N + nd, ns, ns);
            if (!relaxed) sb.segment(ij * N, N) = (qr.householderQ().transpose() * b).head(nc).segment(N + nd, N);
        }
        if (relaxed) {
            const double we = std::sqrt(wg2) / (double)F;
            for (Eigen::Index c = 0; c < N; ++c) S(g * ns, c) = we * Phi.col(c).real().sum();
            S(g * ns, N) = we * (double)F;
            sb(g * ns) = we * (double)F;
        }
        VecR ct = S.colPivHouseholderQr().solve(sb);
        if (!ct.allFinite()) break;
        if (relaxed) {   // c~ / d~ (a d~ near zero: no relocation from this step)
            const double dt = ct(N);
            if (!(std::abs(dt) > 1e-8)) break;
            ct = (ct.head(N) / dt).eval();
        }
        // zeros of sigma = eig(A - b c~^T)
        MatR A = MatR::Zero(N, N);
        VecR bb = VecR::Zero(N);
        Eigen::Index c = 0;
        for (size_t k = 0; k < poles.size(); ++k) {
            if (pair[k]) {
                A(c, c) = A(c + 1, c + 1) = poles[k].real();
                A(c, c + 1) = poles[k].imag();
                A(c + 1, c) = -poles[k].imag();
                bb(c) = 2.0;
                c += 2;
            } else {
                A(c, c) = poles[k].real();
                bb(c) = 1.0;
                ++c;
            }
        }
        Eigen::EigenSolver<MatR> es(A - bb * ct.transpose(), false);
        std::vector<cd> np = pole_list(es.eigenvalues());
        for (cd &p : np) p = reflect(p, d, nullptr);
        if (np.empty()) break;
        // converged: the same pole list to 1e-10 relative (pole_list's order: by |p|, then Re p)
        bool same = np.size() == poles.size();
        for (size_t k = 0; same && k < np.size(); ++k) same = std::abs(np[k] - poles[k]) <= 1e-10 * std::abs(poles[k]);
        poles = np;
        if (same) break;
    }
    for (cd &p : poles) p *= P.ws;
    return poles;
}

// Covariance, model FRF and its covariance at scaled theta.
static void finish(const Prob &P, const Layout &L, const VecR &th, bool known_noise, PrResult &res)
{
    const Eigen::Index g = P.g;
    const std::vector<WeightedLine> &w = *P.w;
    VecR r;
    MatR J;
    resid(P, L, th, r, &J);
    res.cost = r.squaredNorm();
    // scaled -> unscaled: poles and residues times ws, D unchanged
    VecR S = VecR::Ones(L.n);
    S.head(L.dof).setConstant(P.ws);
    PoleResidueModel &m = res.model;
    m.domain = P.d;
    m.feedthrough = L.D;
    m.poles.clear();
    m.R.clear();
    for (size_t k = 0; k < L.pair.size(); ++k) {
        m.poles.push_back(pole_of(L, th, k) * P.ws);
        MatC R(P.ny, P.nu);
        for (Eigen::Index ij = 0; ij < g; ++ij) R.data()[ij] = res_of(L, th, k, ij, g) * P.ws;
        m.R.push_back(R);
    }
    m.D = MatR::Zero(P.ny, P.nu);
    if (L.D) m.D = Eigen::Map<const MatR>(th.data() + L.dof, P.ny, P.nu);
    res.theta = S.cwiseProduct(th);
    res.names.clear();
    auto ent = [&](Eigen::Index ij) { return "[" + std::to_string(ij % P.ny + 1) + "," + std::to_string(ij / P.ny + 1) + "]"; };
    for (size_t k = 0; k < L.pair.size(); ++k) {
        const std::string p = "p" + std::to_string(k + 1);
        if (L.pair[k]) { res.names.push_back(p + ".re"); res.names.push_back(p + ".im"); }
        else res.names.push_back(p);
    }
    for (size_t k = 0; k < L.pair.size(); ++k)
        for (int part = 0; part < (L.pair[k] ? 2 : 1); ++part)
            for (Eigen::Index ij = 0; ij < g; ++ij)
                res.names.push_back("R" + std::to_string(k + 1) + ent(ij) + (L.pair[k] ? (part ? ".im" : ".re") : ""));
    if (L.D)
        for (Eigen::Index ij = 0; ij < g; ++ij) res.names.push_back("D" + ent(ij));
    // Fisher information 2 J^T J (residual components have variance 1/2): pseudo-inverse with its rank
    MatR covs = fisher_cov(J, res.cov_rank);
    res.cov_factor = sample_ml_factor(w, (size_t)P.ny, known_noise);
    covs *= res.cov_factor;
    res.cov = S.asDiagonal() * covs * S.asDiagonal();
    res.G.clear();
    res.Gcov.clear();
    VecC gm;
    MatC dG, dGp;
    const MatC cc = covs.cast<cd>(), I = MatC::Identity(g, g);
    for (size_t li = 0; li < w.size(); ++li) {
        line_terms(P, L, th, li, I, gm, &dG, dGp);   // with Linv = I: -d vec(G) / d theta
        res.G.push_back(Eigen::Map<const MatC>(gm.data(), P.ny, P.nu));
        res.Gcov.push_back(dG * cc * dG.adjoint());
    }
}

PrResult pr_ml(const std::vector<WeightedLine> &w, Domain d, double h, const PrOptions &o)
{
    if (w.empty()) throw FitError("no lines");
    if (o.order < 1) throw FitError("the order must be positive");
    const Prob P = make_prob(w, d, o.wscale);
    const Eigen::Index g = P.g;
    const bool tryD = o.feedthrough != Feedthrough::No;
    {
        const Eigen::Index npar = o.order + (Eigen::Index)o.order * g + (tryD ? g : 0);
        if (npar >= P.rows) {
            const Eigen::Index nmax = (P.rows - 1 - (tryD ? g : 0)) / (1 + g);
            throw FitError("order " + std::to_string(o.order) + " needs " + std::to_string(npar) + " parameters for " +
                           std::to_string(P.rows) + " real data: the largest order these lines support is " +
                           std::to_string(std::max<Eigen::Index>(nmax, 0)));
        }
    }
    PrResult res;
    int refl = 0;
    // starts: vector fitting, then the subspace models (several block-row counts)
    struct Cand { std::string name; std::vector<cd> poles; };
    std::vector<Cand> cands;
    // given poles (a model to refine) replace the other starts
    for (const auto &ps : o.pole_starts) cands.push_back({ps.first, ps.second});
    if (cands.empty()) {
        cands.push_back({"vector-fitting", vector_fit_poles(w, d, o.order, tryD, o.vf_iter, o.wscale, false)});
        if (o.rvf_iter > 0)
            cands.push_back({"vector-fitting-relaxed", vector_fit_poles(w, d, o.order, tryD, o.rvf_iter, o.wscale, true)});
        for (size_t k = 0; k < o.subspace_starts.size(); ++k) {
            std::vector<cd> p = ss_poles(o.subspace_starts[k]);
            const bool refined = o.refined_subspace_start && k + 1 == o.subspace_starts.size();
            if (!p.empty()) cands.push_back({refined ? "subspace-refined" : "subspace#" + std::to_string(k + 1), p});
        }
    }
    LmOut best;
    best.V = std::numeric_limits<double>::infinity();
    Layout bestL;
    for (const Cand &c : cands) {
        const Layout L = make_layout(c.poles, g, tryD);
        if (L.n >= P.rows) continue;
        int rc = 0;
        const LmOut r = lm(P, L, theta_from_poles(L, c.poles, P.ws), std::min(o.start_iter, o.max_iter), o.tol, o.stable, &rc);
        res.starts.push_back({c.name, r.V});
        if (r.V < best.V) { best = r; bestL = L; res.best_start = c.name; refl = rc; }
    }
    if (!std::isfinite(best.V)) throw FitError("no start gave a finite cost (order " + std::to_string(o.order) + ")");
    // the best start continues; --max-iter bounds its iterations in total (start + refinement)
    LmOut fin = best;
    if (!best.conv) {
        fin = lm(P, bestL, best.th, std::max(0, o.max_iter - best.iters), o.tol, o.stable, &refl);
        fin.iters += best.iters;
    }
    Layout finL = bestL;
    if (o.feedthrough == Feedthrough::Auto) {
        // likelihood-ratio test of D = 0: 2 (V0 - V1) ~ chi2_g (eq. 40 residual components have variance 1/2)
        std::vector<cd> poles;
        for (size_t k = 0; k < bestL.pair.size(); ++k) poles.push_back(pole_of(bestL, fin.th, k) * P.ws);
        const Layout L0 = make_layout(poles, g, false);
        VecR th0 = fin.th.head(L0.n);
        // The D = 0 fit gets start_iter iterations from the poles of the D fit: its cost is an upper
        // bound of the D = 0 optimum, so the test errs towards keeping D (never a bias, one more
        // parameter per entry); when D = 0 is accepted it continues to convergence.
        LmOut f0 = lm(P, L0, th0, o.start_iter, o.tol, o.stable, nullptr);
        res.feedthrough_lr_p = chi2_sf((double)g, std::max(0.0, 2.0 * (f0.V - fin.V)));
        if (res.feedthrough_lr_p >= o.auto_alpha) {
            const int done = f0.iters;
            f0 = lm(P, L0, f0.th, o.max_iter, o.tol, o.stable, nullptr);
            f0.iters += done;
            res.feedthrough_lr_p = chi2_sf((double)g, std::max(0.0, 2.0 * (f0.V - fin.V)));
            fin = f0;
            finL = L0;
        }
    }
    res.converged = fin.conv;
    res.iterations = fin.iters;
    res.grad_norm = fin.gnorm;
    res.reflected = refl;
    finish(P, finL, fin.th, o.known_noise, res);
    res.model.h = h;
    return res;
}

PrResult pr_ml_fit(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted, PrOptions o)
{
    if (!o.pole_starts.empty()) return pr_ml(w, d, f.h, o);   // a model to refine: its poles are the start
    try {
        SubspaceOptions so;
        so.order = o.order;
        so.estimate_D = o.feedthrough != Feedthrough::No;
        so.refine_iter = 30;        // msid fit --method subspace's model: refined ...
        so.stable_auto = o.stable;  // ... and stable by default
        const std::vector<WeightedLine> &ws = o.subspace_scan_w ? *o.subspace_scan_w : w;
        if (&ws != &w) so.refine_w = &w;   // refined on the weights ml minimises
        const SubspaceResult sr = fit_subspace(f, d, ws, weighted, so);
        o.subspace_starts.insert(o.subspace_starts.end(), sr.candidates.begin(), sr.candidates.end());
        o.subspace_starts.push_back(sr.model);
        o.refined_subspace_start = true;
    } catch (const FitError &) {
        // subspace cannot start this order (too few lines for its block rows): vector fitting still does
    }
    return pr_ml(w, d, f.h, o);
}

}  // namespace msidfit
