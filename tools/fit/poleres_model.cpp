// The pole-residue model itself (poleres.hpp): its order, its FRF, its real state-space
// realisation, and the pole list of a state-space model. Apart from the ML fit (poleres.cpp) so that
// reading and realising a pole-residue model does not compile the fit (the demo build leaves the fit out).
#include "poleres.hpp"

#include <algorithm>
#include <cmath>

namespace msidfit {

int PoleResidueModel::order() const
{
    int n = 0;
    for (const cd &p : poles) n += p.imag() > 0 ? 2 : 1;
    return n;
}

MatC pr_eval(const PoleResidueModel &m, cd x)
{
    MatC G = m.D.cast<cd>();
    for (size_t k = 0; k < m.poles.size(); ++k) {
        const cd p = m.poles[k];
        G += m.R[k] / (x - p);
        if (p.imag() > 0) G += m.R[k].conjugate() / (x - std::conj(p));
    }
    return G;
}

SSModel pr_to_ss(const PoleResidueModel &m)
{
    const Eigen::Index nu = m.D.cols(), ny = m.D.rows(), n = (Eigen::Index)m.order() * nu;
    SSModel s;
    s.domain = m.domain;
    s.h = m.h;
    s.A = MatR::Zero(n, n);
    s.B = MatR::Zero(n, nu);
    s.C = MatR::Zero(ny, n);
    s.D = m.D;
    const MatR I = MatR::Identity(nu, nu);
    Eigen::Index o = 0;
    for (size_t k = 0; k < m.poles.size(); ++k) {
        const cd p = m.poles[k];
        if (p.imag() > 0) {
            // [[s, w], [-w, s]] kron I, B = [2I; 0], C = [Re R, Im R]: 2(Re R a - Im R w)/(a^2 + w^2), a = x - s
            s.A.block(o, o, nu, nu) = p.real() * I;
            s.A.block(o, o + nu, nu, nu) = p.imag() * I;
            s.A.block(o + nu, o, nu, nu) = -p.imag() * I;
            s.A.block(o + nu, o + nu, nu, nu) = p.real() * I;
            s.B.block(o, 0, nu, nu) = 2.0 * I;
            s.C.block(0, o, ny, nu) = m.R[k].real();
            s.C.block(0, o + nu, ny, nu) = m.R[k].imag();
            o += 2 * nu;
        } else {
            s.A.block(o, o, nu, nu) = p.real() * I;
            s.B.block(o, 0, nu, nu) = I;
            s.C.block(0, o, ny, nu) = m.R[k].real();
            o += nu;
        }
    }
    return s;
}

std::vector<cd> pole_list(const VecC &ev)
{
    std::vector<cd> out;
    for (Eigen::Index k = 0; k < ev.size(); ++k) {
        const cd l = ev(k);
        const double tol = 1e-10 * std::max(std::abs(l), 1e-300);
        if (std::abs(l.imag()) <= tol) out.push_back(cd(l.real(), 0.0));
        else if (l.imag() > 0) out.push_back(l);
    }
    std::sort(out.begin(), out.end(), [](cd a, cd b) {
        if (std::abs(a) != std::abs(b)) return std::abs(a) < std::abs(b);
        return a.real() < b.real();
    });
    return out;
}

std::vector<cd> ss_poles(const SSModel &m)
{
    if (m.A.rows() == 0) return {};
    Eigen::EigenSolver<MatR> es(m.A, false);
    return pole_list(es.eigenvalues());
}

}  // namespace msidfit
