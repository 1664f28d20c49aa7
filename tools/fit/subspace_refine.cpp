// Weighted refinement of a subspace model at its order: a few
// Levenberg-Marquardt steps on the weighted cost (35) = eq. (40) of González et
// al. 2025 in the real modal realisation
//   A = blkdiag([[s_k, w_k], [-w_k, s_k]], ..., l_j, ...),  B, C, D free,
// the Gauss-Newton model of Pintelon & Schoukens (2012) sec. 9.4 for state-space
// models, with Marquardt's scaling D^2 = diag(J^T J) (the B_k/C_k scaling freedom
// of every block is a null direction of J that the damping handles). Only steps
// that lower the cost are taken, so the result never costs more than the start;
// with `stable` a step that leaves the stable region is refused as well.
#include "subspace.hpp"
#include "msid_cancel.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace msidfit {

namespace {

struct Modal {
    Domain d;
    std::vector<int> pair;     // per block: 1 = complex pair (2 states), 0 = real pole (1 state)
    std::vector<int> first;    // first state of each block
    Eigen::Index n = 0, nu = 0, ny = 0;
    bool estD = true;
    // parameter layout: block poles (2 or 1 each), then B (n x nu, column major), C (ny x n), D (ny x nu)
    Eigen::Index nb() const { return n; }
    Eigen::Index size() const { return n + n * nu + ny * n + (estD ? ny * nu : 0); }
};

// Real modal form of (A, B, C) by A's eigenvectors; false if A is (nearly) defective.
bool to_modal(const SSModel &m, Modal &L, VecR &th)
{
    const Eigen::Index n = m.A.rows();
    Eigen::EigenSolver<MatR> es(m.A, true);
    if (es.info() != Eigen::Success) return false;
    const VecC lam = es.eigenvalues();
    const MatC V = es.eigenvectors();
    MatR T(n, n);
    std::vector<double> poles;   // s, w per pair; l per real
    Eigen::Index c = 0;
    for (Eigen::Index k = 0; k < n; ++k) {
        const cd l = lam(k);
        if (std::abs(l.imag()) > 1e-12 * std::max(1.0, std::abs(l))) {
            if (l.imag() < 0) continue;   // the pair is handled by its Im > 0 member
            if (c + 2 > n) return false;
            T.col(c) = V.col(k).real();
            T.col(c + 1) = V.col(k).imag();
            L.pair.push_back(1);
            L.first.push_back((int)c);
            poles.push_back(l.real());
            poles.push_back(l.imag());
            c += 2;
        } else {
            if (c + 1 > n) return false;
            T.col(c) = V.col(k).real();
            L.pair.push_back(0);
            L.first.push_back((int)c);
            poles.push_back(l.real());
            c += 1;
        }
    }
    if (c != n) return false;
    Eigen::JacobiSVD<MatR> sv(T);
    const double cond = sv.singularValues()(0) / sv.singularValues()(n - 1);
    if (!(cond < 1e10)) return false;
    const Eigen::PartialPivLU<MatR> lu(T);
    const MatR B = lu.solve(m.B), C = m.C * T;
    L.d = m.domain;
    L.n = n;
    L.nu = m.B.cols();
    L.ny = m.C.rows();
    th.resize(L.size());
    for (Eigen::Index k = 0; k < n; ++k) th(k) = poles[(size_t)k];
    Eigen::Index o = n;
    for (Eigen::Index j = 0; j < L.nu; ++j)
        for (Eigen::Index i = 0; i < n; ++i) th(o++) = B(i, j);
    for (Eigen::Index j = 0; j < n; ++j)
        for (Eigen::Index i = 0; i < L.ny; ++i) th(o++) = C(i, j);
    if (L.estD)
        for (Eigen::Index j = 0; j < L.nu; ++j)
            for (Eigen::Index i = 0; i < L.ny; ++i) th(o++) = m.D(i, j);
    return true;
}

SSModel from_modal(const Modal &L, const VecR &th, const SSModel &like)
{
    SSModel m = like;
    const Eigen::Index n = L.n;
    m.A = MatR::Zero(n, n);
    Eigen::Index p = 0;
    for (size_t b = 0; b < L.pair.size(); ++b) {
        const Eigen::Index i = L.first[b];
        if (L.pair[b]) {
            m.A(i, i) = m.A(i + 1, i + 1) = th(p);
            m.A(i, i + 1) = th(p + 1);
            m.A(i + 1, i) = -th(p + 1);
            p += 2;
        } else {
            m.A(i, i) = th(p++);
        }
    }
    Eigen::Index o = n;
    m.B = Eigen::Map<const MatR>(th.data() + o, n, L.nu);
    o += n * L.nu;
    m.C = Eigen::Map<const MatR>(th.data() + o, L.ny, n);
    o += L.ny * n;
    if (L.estD) m.D = Eigen::Map<const MatR>(th.data() + o, L.ny, L.nu);
    return m;
}

bool stable_poles(const Modal &L, const VecR &th)
{
    Eigen::Index p = 0;
    for (size_t b = 0; b < L.pair.size(); ++b) {
        const double s = th(p), w = L.pair[b] ? th(p + 1) : 0.0;
        p += L.pair[b] ? 2 : 1;
        if (L.d == Domain::CT ? !(s < 0) : !(s * s + w * w < 1)) return false;
    }
    return true;
}

// Weighted cost (35) of theta and, if JtJ, the Gauss-Newton normal equations of its whitened residual
// r (real, imag stacked per line): JtJ = J^T J (lower triangle only) and Jtr = J^T r, J = d r / d theta.
// J is never formed whole: the rows of up to CHUNK lines at a time go into a small buffer (L2-resident)
// whose rank update is added, so the work is that of one J^T J without its 2 L g np doubles.
constexpr Eigen::Index CHUNK = 32;
struct NormalEq {
    MatR JtJ;      // np x np, lower triangle
    VecR Jtr;      // np
    MatR Jb;       // CHUNK 2g x np rows of J
    VecR rb;       // their residuals
    MatC Jc;       // g x np: d vec(Gm) / d theta (complex) of one line
};
double residual(const Modal &L, const VecR &th, const std::vector<WeightedLine> &w, NormalEq *ne)
{
    const Eigen::Index n = L.n, nu = L.nu, ny = L.ny, g = ny * nu, np = L.size();
    const Eigen::Map<const MatR> B(th.data() + n, n, nu), C(th.data() + n + n * nu, ny, n);
    const MatR D = L.estD ? MatR(Eigen::Map<const MatR>(th.data() + n + n * nu + ny * n, ny, nu)) : MatR::Zero(ny, nu);
    const bool J = ne != nullptr;
    if (J) {
        ne->JtJ.setZero(np, np);
        ne->Jtr.setZero(np);
        ne->Jb.resize(CHUNK * 2 * g, np);
        ne->rb.resize(CHUNK * 2 * g);
        ne->Jc.resize(g, np);
    }
    MatC Gm(ny, nu), dG(ny, nu);
    VecC e(g);
    Eigen::Index rows = 0;   // rows of the chunk buffer in use
    auto flush = [&]() {
        if (!rows) return;
        const auto Jr = ne->Jb.topRows(rows);
        ne->JtJ.selfadjointView<Eigen::Lower>().rankUpdate(Jr.transpose());
        ne->Jtr.noalias() += Jr.transpose() * ne->rb.head(rows);
        rows = 0;
    };
    double V = 0;
    for (size_t li = 0; li < w.size(); ++li) {
        const WeightedLine &l = w[li];
        const cd x = l.x;
        Gm = D.cast<cd>();
        MatC *Jcp = J ? &ne->Jc : nullptr;
        if (J) Jcp->setZero();
        Eigen::Index p = 0;
        for (size_t b = 0; b < L.pair.size(); ++b) {
            const Eigen::Index i0 = L.first[b];
            if (L.pair[b]) {
                const double s = th(p), om = th(p + 1);
                const cd a = x - s, den = 1.0 / (a * a + om * om);
                // R = (x I - A_k)^{-1} = den [[a, om], [-om, a]]
                const cd R00 = a * den, R01 = om * den, R10 = -om * den, R11 = a * den;
                // K = C_k R (ny x 2), M = R B_k (2 x nu)
                for (Eigen::Index i = 0; i < ny; ++i) {
                    const cd k0 = C(i, i0) * R00 + C(i, i0 + 1) * R10, k1 = C(i, i0) * R01 + C(i, i0 + 1) * R11;
                    for (Eigen::Index j = 0; j < nu; ++j) {
                        Gm(i, j) += k0 * B(i0, j) + k1 * B(i0 + 1, j);
                        if (!J) continue;
                        MatC &Jc = *Jcp;
                        const Eigen::Index ij = i + ny * j;
                        const cd m0 = R00 * B(i0, j) + R01 * B(i0 + 1, j), m1 = R10 * B(i0, j) + R11 * B(i0 + 1, j);
                        // d/ds: K M (dA/ds = I); d/dw: K [[0,1],[-1,0]] M = k0 m1 - k1 m0
                        Jc(ij, p) = k0 * m0 + k1 * m1;
                        Jc(ij, p + 1) = k0 * m1 - k1 * m0;
                        Jc(ij, n + j * n + i0) = k0;              // d/dB(i0, j)
                        Jc(ij, n + j * n + i0 + 1) = k1;
                        Jc(ij, n + n * nu + i0 * ny + i) = m0;     // d/dC(i, i0)
                        Jc(ij, n + n * nu + (i0 + 1) * ny + i) = m1;
                    }
                }
                p += 2;
            } else {
                const cd R = 1.0 / (x - th(p));
                for (Eigen::Index i = 0; i < ny; ++i)
                    for (Eigen::Index j = 0; j < nu; ++j) {
                        const cd t = C(i, i0) * R * B(i0, j);
                        Gm(i, j) += t;
                        if (!J) continue;
                        MatC &Jc = *Jcp;
                        const Eigen::Index ij = i + ny * j;
                        Jc(ij, p) = t * R;
                        Jc(ij, n + j * n + i0) = C(i, i0) * R;
                        Jc(ij, n + n * nu + i0 * ny + i) = R * B(i0, j);
                    }
                p += 1;
            }
        }
        if (J && L.estD)
            for (Eigen::Index ij = 0; ij < g; ++ij) (*Jcp)(ij, n + n * nu + ny * n + ij) = 1.0;
        dG = l.G - Gm;
        // e = Linv vec(dG); Linv is lower triangular (weigh(): the inverse Cholesky factor or I)
        for (Eigen::Index a = 0; a < g; ++a) {
            cd s = 0.0;
            for (Eigen::Index b = 0; b <= a; ++b) s += l.Linv(a, b) * dG.data()[b];
            e(a) = s;
        }
        const double sc = l.real ? std::sqrt(0.5) : 1.0;
        V += sc * sc * e.squaredNorm();
        if (J) {
            // residual = Linv (G - Gm): d r = -Linv d Gm, rows (Re, Im) of the line into the chunk buffer
            const MatC &Jc = *Jcp;
            for (Eigen::Index a = 0; a < g; ++a) {
                ne->rb(rows + a) = sc * e(a).real();
                ne->rb(rows + g + a) = sc * e(a).imag();
            }
            for (Eigen::Index c = 0; c < np; ++c)
                for (Eigen::Index a = 0; a < g; ++a) {
                    cd s = 0.0;
                    for (Eigen::Index b = 0; b <= a; ++b) s += l.Linv(a, b) * Jc(b, c);
                    ne->Jb(rows + a, c) = -sc * s.real();
                    ne->Jb(rows + g + a, c) = -sc * s.imag();
                }
            rows += 2 * g;
            if (rows == ne->Jb.rows()) flush();
        }
    }
    if (J) flush();
    return V;
}

// Marquardt's scaling diag(J^T J), with a floor for (near-)null columns of 1e-12 times the largest
// diagonal among the parameters in the same units: the poles; B's column j (1/input j); C's row i
// (output i); each D(i, j) alone (never a null column). A floor relative to the largest diagonal of
// all parameters made the damping depend on the units: with outputs in 1e-9 of the data's units the
// C and D columns grew by 1e18 against the poles', whose damping was then lifted 1e6-fold, steps
// became tiny and the 1e-6 stopping rule ended the refinement after one step.
void floor_by_units(const Modal &L, VecR &dg)
{
    const Eigen::Index n = L.n, nu = L.nu, ny = L.ny;
    auto floor_group = [&](auto idx, Eigen::Index count) {
        double mx = 0;
        for (Eigen::Index k = 0; k < count; ++k) mx = std::max(mx, dg(idx(k)));
        for (Eigen::Index k = 0; k < count; ++k) dg(idx(k)) = std::max(dg(idx(k)), 1e-12 * mx);
    };
    floor_group([&](Eigen::Index k) { return k; }, n);
    for (Eigen::Index j = 0; j < nu; ++j) floor_group([&](Eigen::Index k) { return n + j * n + k; }, n);
    for (Eigen::Index i = 0; i < ny; ++i) floor_group([&](Eigen::Index k) { return n + n * nu + k * ny + i; }, n);
}

}  // namespace

SubspaceRefine refine_subspace(SSModel &m, const std::vector<WeightedLine> &w, bool estimate_D, bool stable, int max_iter)
{
    SubspaceRefine out;
    if (m.A.rows() == 0 || max_iter <= 0) return out;
    Modal L;
    L.estD = estimate_D;
    VecR th;
    if (!to_modal(m, L, th)) { out.note = "A is (nearly) defective: not refined"; return out; }
    if (stable && !stable_poles(L, th)) { out.note = "start unstable: not refined"; return out; }
    NormalEq ne;
    double V = residual(L, th, w, &ne);
    out.cost_start = V;
    double lambda = 1e-3;
    int steps = 0;
    for (int it = 0; it < max_iter; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the subspace refinement");
        MatR &JtJ = ne.JtJ;
        JtJ.triangularView<Eigen::StrictlyUpper>() = JtJ.transpose();
        const VecR &Jtr = ne.Jtr;
        VecR dg = JtJ.diagonal();
        floor_by_units(L, dg);
        bool taken = false, done = false;
        for (int tries = 0; tries < 12; ++tries) {
            MatR H = JtJ;
            H.diagonal() += lambda * dg;
            const VecR step = -H.ldlt().solve(Jtr);
            const VecR tn = th + step;
            if (!step.allFinite() || (stable && !stable_poles(L, tn))) { lambda *= 10; continue; }
            // the cost of the trial alone (a few % of the normal equations): those only for an
            // accepted step that is not the last
            const double Vn = residual(L, tn, w, nullptr);
            if (std::isfinite(Vn) && Vn < V) {
                // converged when a step gains less than 1e-6 of the cost (far below the
                // statistical resolution of (35), whose spread is sqrt(2 dof))
                done = (V - Vn) < 1e-6 * V;
                th = tn;
                V = Vn;
                if (!done && it + 1 < max_iter) residual(L, th, w, &ne);   // the same V, with J^T J, J^T r
                lambda = std::max(lambda / 10, 1e-12);
                taken = true;
                ++steps;
                break;
            }
            lambda *= 10;
        }
        if (!taken || done) break;
    }
    out.iterations = steps;
    SSModel mr = from_modal(L, th, m);
    if (!estimate_D) mr.D = MatR::Zero(L.ny, L.nu);
    // B and D by the exact weighted LS given the refined A and C: never above the LM cost
    const double Vbd = fit_BD(mr, w, estimate_D);
    if (Vbd < V) V = Vbd; else mr = from_modal(L, th, m);
    if (!estimate_D) mr.D = MatR::Zero(L.ny, L.nu);
    // the same evaluation of (35) for the start and the result (the modal transform costs round-off)
    const double Vin = weighted_cost_ss(m, w), Vout = weighted_cost_ss(mr, w);
    if (Vout < Vin) { m = mr; V = Vout; } else { V = Vin; }
    out.cost_start = Vin;
    out.cost = V;
    out.refined = true;
    return out;
}

}  // namespace msidfit
