// The pole-residue ML problem: the lines in the scaled variable, the parameter layout, the model and
// its whitened residual and Jacobian at the lines (poleres_problem.hpp).
#include "poleres_problem.hpp"

#include <algorithm>
#include <cmath>

namespace msidfit {
namespace prfit {

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
        P.W.push_back((l.real ? 0.5 : 1.0) * (l.Linv.adjoint() * l.Linv));
    }
    return P;
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

}  // namespace prfit
}  // namespace msidfit
