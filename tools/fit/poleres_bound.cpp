// The stability bound of the stable pole-residue ML: starts reflected, steps projected, the poles the
// data push out held on the bound (the active set), and the covariance of the directions left free
// (poleres_problem.hpp, stab_bound.hpp).
#include "poleres_problem.hpp"
#include "lmfd_fit.hpp"
#include "stab_bound.hpp"

#include <algorithm>
#include <cmath>

namespace msidfit {
namespace prfit {

// Reflect into the stable region: CT Re p -> -|Re p|, DT |p| -> 1/|p|.
cd reflect(cd p, Domain d, int *count)
{
    if (d == Domain::CT && p.real() > 0) { if (count) ++*count; return cd(-p.real(), p.imag()); }
    if (d == Domain::DT && std::abs(p) > 1) { if (count) ++*count; return 1.0 / std::conj(p); }
    return p;
}

// Fix up a parameter vector: poles with Im < 0 become their conjugate (residues conjugated); with
// `stable`, a start's unstable poles are reflected (as vector fitting flips them: the same |G| shape,
// counted in refl) and every pole is projected onto the feasible set (stab_bound.hpp). A trial step
// is only projected (refl null): the part of the step that crosses the bound ends on it.
void canonical(const Layout &L, VecR &th, Domain d, bool stable, Eigen::Index g, int *refl)
{
    for (size_t k = 0; k < L.pair.size(); ++k) {
        cd p = pole_of(L, th, k);
        if (L.pair[k] && p.imag() < 0) {
            p = std::conj(p);
            th.segment(L.ro[k] + g, g) *= -1.0;
        }
        if (stable) {
            if (refl) p = reflect(p, d, refl);
            p = stab_project(p, d);
        }
        th(L.po[k]) = p.real();
        if (L.pair[k]) th(L.po[k] + 1) = p.imag();
    }
}

// The active set of the stability bound at th: the poles on the bound whose descent direction
// (-grad, grad = J^T r) points out of the feasible set. Their outward coordinate is held on the bound
// in the step (a bound-constrained Gauss-Newton step: Bertsekas, "Projected Newton methods for
// optimization problems with simple constraints", SIAM J. Control Optim. 20(2), 1982): with the
// former reflection of every step a pole the data push across the boundary oscillated about it, and
// the fit ran out of iterations with the other poles unsettled.
std::vector<char> active_set(const Layout &L, const VecR &th, const VecR &grad, Domain d)
{
    std::vector<char> a(L.pair.size(), 0);
    for (size_t k = 0; k < L.pair.size(); ++k) {
        const cd p = pole_of(L, th, k);
        if (!stab_on_bound(p, d)) continue;
        const cd n = stab_normal(p, d);
        const double gn = grad(L.po[k]) * n.real() + (L.pair[k] ? grad(L.po[k] + 1) * n.imag() : 0.0);
        a[k] = gn < 0;   // the cost falls outwards
    }
    return a;
}

// Basis change for the active poles: Q (identity but for each active pole's coordinates, where its
// columns are (normal, tangent) of a pair, the normal alone of a real pole). In these coordinates
// the normal components are the ones held; Q is orthogonal.
MatR active_basis(const Layout &L, const VecR &th, const std::vector<char> &act, Domain d)
{
    MatR Q = MatR::Identity(L.n, L.n);
    for (size_t k = 0; k < L.pair.size(); ++k) {
        if (!act[k] || !L.pair[k]) continue;
        const cd n = stab_normal(pole_of(L, th, k), d);
        const Eigen::Index i = L.po[k];
        Q(i, i) = n.real();     Q(i, i + 1) = -n.imag();
        Q(i + 1, i) = n.imag(); Q(i + 1, i + 1) = n.real();
    }
    return Q;
}

// The Fisher information's pseudo-inverse (with its rank) in the directions free at the bound: J in
// the basis Q of active_basis without the held normals, inverted there and mapped back, so the held
// directions have exactly no variance (a zeroed column in the whole J leaked 1e270 through the
// column scaling of the inverse).
MatR held_fisher_cov(const Layout &L, const VecR &th, const std::vector<char> &act, Domain d, const MatR &J, int &rank)
{
    if (std::none_of(act.begin(), act.end(), [](char c) { return c != 0; })) return fisher_cov(J, rank);
    const MatR Q = active_basis(L, th, act, d);
    std::vector<Eigen::Index> keep;
    for (Eigen::Index i = 0; i < L.n; ++i) keep.push_back(i);
    for (size_t k = 0; k < L.pair.size(); ++k)
        if (act[k]) keep.erase(std::find(keep.begin(), keep.end(), L.po[k]));
    MatR Z(L.n, (Eigen::Index)keep.size());
    for (size_t c = 0; c < keep.size(); ++c) Z.col((Eigen::Index)c) = Q.col(keep[c]);
    const MatR cr = fisher_cov(MatR(J * Z), rank);
    return Z * cr * Z.transpose();
}

// The step: (J^T J + lambda S^2) dx = -grad in the free directions, the held normals fixed at zero.
VecR constrained_step(const Layout &L, const VecR &th, const MatR &JtJ, const VecR &grad, double lambda,
                      const std::vector<char> &act, Domain d)
{
    if (std::none_of(act.begin(), act.end(), [](char c) { return c != 0; })) return scaled_solve(JtJ, -grad, lambda);
    const MatR Q = active_basis(L, th, act, d);
    MatR M = Q.transpose() * JtJ * Q;
    VecR b = -(Q.transpose() * grad);
    for (size_t k = 0; k < L.pair.size(); ++k) {
        if (!act[k]) continue;
        const Eigen::Index i = L.po[k];
        M.row(i).setZero();
        M.col(i).setZero();
        M(i, i) = 1.0;
        b(i) = 0.0;
    }
    return Q * scaled_solve(M, b, lambda);
}

// The gradient's norm in the free directions, each component over its column norm sqrt((J^T J)_ii)
// (scale free); the held normal components of the active poles left out.
double free_gnorm(const Layout &L, const VecR &th, const MatR &JtJ, const VecR &grad, const std::vector<char> &act,
                  Domain d)
{
    VecR q = grad.cwiseQuotient(JtJ.diagonal().cwiseMax(1e-300).cwiseSqrt());
    for (size_t k = 0; k < L.pair.size(); ++k) {
        if (!act[k]) continue;
        const Eigen::Index i = L.po[k];
        q(i) = 0.0;
        if (!L.pair[k]) continue;
        const cd n = stab_normal(pole_of(L, th, k), d);   // the tangent t = (-n.im, n.re)
        const double tt = n.imag() * n.imag() * JtJ(i, i) - 2 * n.real() * n.imag() * JtJ(i, i + 1) +
                          n.real() * n.real() * JtJ(i + 1, i + 1);
        q(i + 1) = (-n.imag() * grad(i) + n.real() * grad(i + 1)) / std::sqrt(std::max(tt, 1e-300));
    }
    return q.norm();
}

}  // namespace prfit
}  // namespace msidfit
