// The normal equations of the pole-residue ML from per-line blocks, and the residues' weighted least
// squares for given poles (poleres_problem.hpp).
#include "poleres_problem.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace msidfit {
namespace prfit {

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

// The cost (40) at th: sum_l e_l^H W_l e_l, e_l = G_l - G(x_l) (the trial steps need no derivatives).
double cost_at(const Prob &P, const Layout &L, const VecR &th)
{
    const Eigen::Index g = P.g;
    VecC gm(g);
    MatC none;
    double V = 0;
    for (size_t li = 0; li < P.xt.size(); ++li) {
        const WeightedLine &l = (*P.w)[li];
        line_terms(P, L, th, li, l.Linv, gm, nullptr, none);
        const VecC e = Eigen::Map<const VecC>(l.G.data(), g) - gm;
        V += (e.adjoint() * P.W[li] * e)(0).real();
    }
    return V;
}

// The normal equations of the whitened problem at th: V = r^T r, grad = J^T r and JtJ = J^T J, from
// per-line blocks, J never formed. With W_l = Linv^H Linv and dG = [dGp | psi (x) I_g] (the pole
// derivatives, then the basis of the linear parameters: q + q2 and i (q - q2) per pair, q per real pole,
// 1 for D), J^T J = Re sum_l dG^H W_l dG and J^T r = -Re sum_l dG^H W_l e_l: each block one complex
// product over the lines (the Gram matrix of J, 2 L g rows, cost several times as much and its formation
// most of an iteration). The block of the linear parameters depends on the poles alone: Blocks::Poles
// keeps it from the previous call at the same poles (after the residues are re-solved).
// Complex products over the lines are real ones on stacked real and imaginary parts (Re(A B) = Ar Br -
// Ai Bi): Eigen's real matrix kernels are several times faster than its complex ones here. The stacked
// matrices are entry-major (row or column j F + l for entry j at line l), so that one entry's lines are a
// contiguous block.
void normal_eq(const Prob &P, const Layout &L, const VecR &th, Normal &N, Blocks what)
{
    const Eigen::Index g = P.g, F = (Eigen::Index)P.xt.size(), np = L.npole;
    std::vector<Eigen::Index> col;   // first column of each basis function's g linear parameters
    for (size_t k = 0; k < L.pair.size(); ++k) {
        col.push_back(L.ro[k]);
        if (L.pair[k]) col.push_back(L.ro[k] + g);
    }
    if (L.D) col.push_back(L.dof);
    const Eigen::Index nb = (Eigen::Index)col.size();
    const bool poles = what != Blocks::Linear, lin = what != Blocks::Poles;
    MatR PsiR(F, nb), PsiI(F, nb), FvR(F, g), FvI(F, g);
    MatR DgR, DgI, BsR, BsI;   // dGp (g F x np) and dGp^H W (np x g F), entry-major
    if (poles) { DgR.resize(g * F, np); DgI.resize(g * F, np); BsR.resize(np, g * F); BsI.resize(np, g * F); }
    VecC gm(g);
    MatC dgp(g, np);
    const cd I(0, 1);
    N.V = 0;
    for (Eigen::Index l = 0; l < F; ++l) {
        const cd x = P.xt[(size_t)l];
        gm.setZero();
        Eigen::Index b = 0;
        for (size_t k = 0; k < L.pair.size(); ++k) {
            const cd p = pole_of(L, th, k), q = 1.0 / (x - p);
            const Eigen::Index c = L.po[k];
            if (L.pair[k]) {
                const cd q2 = 1.0 / (x - std::conj(p)), s1 = q + q2, s2 = I * (q - q2);
                PsiR(l, b) = s1.real(); PsiI(l, b++) = s1.imag();
                PsiR(l, b) = s2.real(); PsiI(l, b++) = s2.imag();
                for (Eigen::Index ij = 0; ij < g; ++ij) {
                    const cd R = res_of(L, th, k, ij, g), a = R * q * q, bb = std::conj(R) * q2 * q2;
                    gm(ij) += R * q + std::conj(R) * q2;
                    dgp(ij, c) = a + bb;
                    dgp(ij, c + 1) = I * (a - bb);
                }
            } else {
                PsiR(l, b) = q.real(); PsiI(l, b++) = q.imag();
                for (Eigen::Index ij = 0; ij < g; ++ij) {
                    const cd R = res_of(L, th, k, ij, g);
                    gm(ij) += R * q;
                    dgp(ij, c) = R * q * q;
                }
            }
        }
        if (L.D) {
            PsiR(l, b) = 1.0; PsiI(l, b) = 0.0;
            for (Eigen::Index ij = 0; ij < g; ++ij) gm(ij) += th(L.dof + ij);
        }
        const MatC &W = P.W[(size_t)l];
        const VecC e = Eigen::Map<const VecC>((*P.w)[(size_t)l].G.data(), g) - gm, f = W * e;
        N.V += e.dot(f).real();
        FvR.row(l) = f.real().transpose();
        FvI.row(l) = f.imag().transpose();
        if (!poles) continue;
        const MatC B = dgp.adjoint() * W;   // np x g
        for (Eigen::Index j = 0; j < g; ++j) {
            DgR.row(j * F + l) = dgp.row(j).real();
            DgI.row(j * F + l) = dgp.row(j).imag();
            BsR.col(j * F + l) = B.col(j).real();
            BsI.col(j * F + l) = B.col(j).imag();
        }
    }
    if (N.JtJ.rows() != L.n) N.JtJ = MatR::Zero(L.n, L.n);
    N.grad.resize(L.n);
    // gradient -Re sum dG^H f: poles, then the linear parameters
    const Eigen::Map<const VecR> fR(FvR.data(), g * F), fI(FvI.data(), g * F);   // column-major F x g: entry-major
    if (poles) N.grad.head(np) = -(DgR.transpose() * fR + DgI.transpose() * fI);
    const MatR gl = PsiR.transpose() * FvR + PsiI.transpose() * FvI;   // nb x g
    for (Eigen::Index bb = 0; bb < nb; ++bb)
        for (Eigen::Index ij = 0; ij < g; ++ij) N.grad(col[(size_t)bb] + ij) = -gl(bb, ij);
    if (poles) {
        N.JtJ.topLeftCorner(np, np).noalias() = BsR * DgR - BsI * DgI;
        for (Eigen::Index j = 0; j < g; ++j) {
            const MatR A = BsR.middleCols(j * F, F) * PsiR - BsI.middleCols(j * F, F) * PsiI;   // np x nb
            for (Eigen::Index bb = 0; bb < nb; ++bb) {
                N.JtJ.col(col[(size_t)bb] + j).head(np) = A.col(bb);
                N.JtJ.row(col[(size_t)bb] + j).head(np) = A.col(bb).transpose();
            }
        }
    }
    // linear-linear block: Re sum_l conj(psi_b) W_l(i, j) psi_c at (b, i), (c, j)
    if (lin) {
        MatR S(2 * F, nb), T(2 * F, nb);
        S << PsiR, PsiI;
        for (Eigen::Index i = 0; i < g; ++i)
            for (Eigen::Index j = i; j < g; ++j) {
                for (Eigen::Index l = 0; l < F; ++l) {
                    const cd w = P.W[(size_t)l](i, j);
                    T.row(l) = w.real() * PsiR.row(l) - w.imag() * PsiI.row(l);
                    T.row(F + l) = w.real() * PsiI.row(l) + w.imag() * PsiR.row(l);
                }
                const MatR M = S.transpose() * T;   // nb x nb
                for (Eigen::Index bb = 0; bb < nb; ++bb)
                    for (Eigen::Index cc = 0; cc < nb; ++cc) {
                        N.JtJ(col[(size_t)bb] + i, col[(size_t)cc] + j) = M(bb, cc);
                        N.JtJ(col[(size_t)cc] + j, col[(size_t)bb] + i) = M(bb, cc);
                    }
            }
    }
}

// Residues and D by weighted least squares for the current poles (variable projection step): the cost
// is quadratic in them, so one Gauss-Newton step on their block is their LS solution (normal equations
// in unit-scaled columns). N holds the normal equations at the result; a solution that does not lower
// the cost (an ill-conditioned block) is not taken.
void solve_linear(const Prob &P, const Layout &L, VecR &th, Normal &N)
{
    normal_eq(P, L, th, N, Blocks::Linear);
    const double V0 = N.V;
    const VecR dl = scaled_solve(N.JtJ.bottomRightCorner(L.nlin, L.nlin), -N.grad.tail(L.nlin), 0.0);
    if (dl.allFinite()) {
        const VecR keep = th.tail(L.nlin);
        th.tail(L.nlin) += dl;
        normal_eq(P, L, th, N, Blocks::Poles);
        if (N.V <= V0) return;
        th.tail(L.nlin) = keep;
    }
    normal_eq(P, L, th, N, Blocks::Poles);
}

}  // namespace prfit
}  // namespace msidfit
