// The pole-residue ML problem of poleres.cpp in its parts (internal to tools/fit): the weighted lines
// in the scaled variable and the parameter layout (poleres_problem.cpp), the normal equations and the
// residues' weighted least squares (poleres_normal.cpp), the stability bound's projection, active set
// and covariance (poleres_bound.cpp). Parameters are scaled: CT poles and residues divided by ws.
#pragma once
#include "poleres.hpp"

#include <vector>

namespace msidfit {
namespace prfit {

struct Prob {
    Eigen::Index ny = 0, nu = 0, g = 0, rows = 0;
    Domain d = Domain::CT;
    double ws = 1.0;
    std::vector<cd> xt;                       // scaled frequency variable
    const std::vector<WeightedLine> *w = nullptr;
    std::vector<MatC> W;                      // per line Linv^H Linv = inverse covariance (1/2 of it on a real line)
};

// Parameter layout: poles (1 or 2 each), then residues (g or 2g each), then D (g).
struct Layout {
    std::vector<char> pair;
    std::vector<Eigen::Index> po, ro;
    Eigen::Index dof = 0, n = 0, nlin = 0, npole = 0;
    bool D = true;
};

Layout make_layout(const std::vector<cd> &poles, Eigen::Index g, bool D);
// The CT frequency scale: ws if positive, else the geometric mean of the lowest and highest line frequency.
double scan_ws(const std::vector<WeightedLine> &w, Domain d, double ws);
Prob make_prob(const std::vector<WeightedLine> &w, Domain d, double ws);

inline cd pole_of(const Layout &L, const VecR &th, size_t k)
{
    return L.pair[k] ? cd(th(L.po[k]), th(L.po[k] + 1)) : cd(th(L.po[k]), 0.0);
}

inline cd res_of(const Layout &L, const VecR &th, size_t k, Eigen::Index ij, Eigen::Index g)
{
    return L.pair[k] ? cd(th(L.ro[k] + ij), th(L.ro[k] + g + ij)) : cd(th(L.ro[k] + ij), 0.0);
}

// Model vec(G) at line li and, if Jc, the whitened Jacobian -Linv d vec(G) / d theta (g x n).
void line_terms(const Prob &P, const Layout &L, const VecR &th, size_t li, const MatC &Linv, VecC &gm, MatC *Jc,
                MatC &dGp);
// Whitened real residual r = Linv vec(G - G(theta)) (real lines scaled by sqrt 1/2) and J = dr/dtheta.
void resid(const Prob &P, const Layout &L, const VecR &th, VecR &r, MatR *J);

// (J^T J + lambda diag J^T J) x = b in unit-scaled columns; a pseudo-inverse where it is singular.
VecR scaled_solve(const MatR &JtJ, const VecR &b, double lambda);
// The cost (40) at th.
double cost_at(const Prob &P, const Layout &L, const VecR &th);

// V = r^T r, grad = J^T r and JtJ = J^T J at th (poleres_normal.cpp).
struct Normal {
    MatR JtJ;
    VecR grad;
    double V = 0;
};
// What normal_eq computes besides V and grad: the block of the linear parameters (which depends on the
// poles alone), the blocks of the poles (which depend on the residues too), or both.
enum class Blocks { Linear, Poles, All };
void normal_eq(const Prob &P, const Layout &L, const VecR &th, Normal &N, Blocks what);
// The residues and D by weighted least squares for th's poles; N at the result.
void solve_linear(const Prob &P, const Layout &L, VecR &th, Normal &N);

// The stability bound (poleres_bound.cpp, stab_bound.hpp).
cd reflect(cd p, Domain d, int *count);
void canonical(const Layout &L, VecR &th, Domain d, bool stable, Eigen::Index g, int *refl);
std::vector<char> active_set(const Layout &L, const VecR &th, const VecR &grad, Domain d);
MatR active_basis(const Layout &L, const VecR &th, const std::vector<char> &act, Domain d);
MatR held_fisher_cov(const Layout &L, const VecR &th, const std::vector<char> &act, Domain d, const MatR &J, int &rank);
VecR constrained_step(const Layout &L, const VecR &th, const MatR &JtJ, const VecR &grad, double lambda,
                      const std::vector<char> &act, Domain d);
double free_gnorm(const Layout &L, const VecR &th, const MatR &JtJ, const VecR &grad, const std::vector<char> &act,
                  Domain d);

}  // namespace prfit
}  // namespace msidfit
