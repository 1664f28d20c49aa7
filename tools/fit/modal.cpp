#include "modal.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace msidfit {

SSModel lmfd_realise_scaled(const LmfdModel &m, double *ws)
{
    *ws = 1.0;
    if (m.domain != Domain::CT || m.nD == 0) return lmfd_to_ss(m);
    const double det = std::abs(m.Dm[(size_t)m.nD - 1].determinant());
    if (!(det > 0) || !std::isfinite(det)) return lmfd_to_ss(m);
    *ws = std::pow(det, -1.0 / (double)(m.ny() * (size_t)m.nD));
    LmfdModel t = m;   // coefficients of s~ = s / ws
    for (int i = 1; i <= m.nD; ++i) t.Dm[(size_t)i - 1] *= std::pow(*ws, i);
    for (int j = 0; j <= m.nN; ++j) t.Nm[(size_t)j] *= std::pow(*ws, j);
    return lmfd_to_ss(t);
}

std::vector<Mode> modes_of(const SSModel &m, double h, double xscale)
{
    std::vector<Mode> out;
    const Eigen::Index n = m.A.rows();
    if (n == 0) return out;
    Eigen::EigenSolver<MatR> es(m.A, true);
    const VecC lam = es.eigenvalues();
    const MatC V = es.eigenvectors();
    const MatC W = V.partialPivLu().inverse();
    const MatC Cc = m.C.cast<cd>(), Bc = m.B.cast<cd>();
    const double hs = h > 0 ? h : 1.0;
    for (Eigen::Index k = 0; k < n; ++k) {
        const cd l = lam(k);
        const double scale = std::max(std::abs(l), 1e-300);
        const bool isreal = std::abs(l.imag()) <= 1e-12 * scale;
        if (!isreal && l.imag() < 0) continue;   // the conjugate member of a pair
        Mode md;
        md.pole = (isreal ? cd(l.real(), 0.0) : l) * xscale;
        md.real = isreal;
        md.pole_ct = m.domain == Domain::DT ? std::log(md.pole) / hs : md.pole;
        md.wn = std::abs(md.pole_ct);
        md.fn = md.wn / (2.0 * M_PI);
        md.zeta = md.wn > 0 ? -md.pole_ct.real() / md.wn : 1.0;
        md.residue = (Cc * V.col(k)) * (W.row(k) * Bc) * xscale;
        if (isreal) md.residue = md.residue.real().cast<cd>();
        out.push_back(md);
    }
    std::stable_sort(out.begin(), out.end(), [](const Mode &a, const Mode &b) {
        return a.wn != b.wn ? a.wn < b.wn : a.pole.imag() < b.pole.imag();
    });
    return out;
}

// Quantities of a mode for the delta method: wn, zeta, Re R, Im R (column-major).
static VecR mode_vec(const Mode &md)
{
    const Eigen::Index g = md.residue.size();
    VecR q(2 + 2 * g);
    q(0) = md.wn;
    q(1) = md.zeta;
    for (Eigen::Index i = 0; i < g; ++i) {
        q(2 + i) = md.residue.data()[i].real();
        q(2 + g + i) = md.residue.data()[i].imag();
    }
    return q;
}

static const Mode &nearest(const std::vector<Mode> &ms, const Mode &ref)
{
    size_t best = 0;
    double d = 1e300;
    for (size_t j = 0; j < ms.size(); ++j) {
        const double dj = std::abs(ms[j].pole - ref.pole);
        if (dj < d) { d = dj; best = j; }
    }
    return ms[best];
}

std::vector<Mode> modes_with_sd(const std::function<SSModel(const VecR &)> &realise, const VecR &theta,
                                const MatR &cov, double h, double xscale)
{
    std::vector<Mode> nom = modes_of(realise(theta), h, xscale);
    if (nom.empty() || cov.rows() != theta.size()) return nom;
    const Eigen::Index np = theta.size();
    std::vector<MatR> J(nom.size());
    for (size_t k = 0; k < nom.size(); ++k) J[k] = MatR::Zero(mode_vec(nom[k]).size(), np);
    for (Eigen::Index i = 0; i < np; ++i) {
        const double sd = std::sqrt(std::max(0.0, cov(i, i)));
        if (!(sd > 0) || !std::isfinite(sd)) continue;
        // step: small against sd (linearisation error O(step^2)) but large against the rounding
        // error of the eigenvalues of a companion realisation (condition numbers of 1e6 and more)
        const double st = 1e-2 * sd;
        VecR tp = theta, tm = theta;
        tp(i) += st;
        tm(i) -= st;
        const std::vector<Mode> mp = modes_of(realise(tp), h, xscale), mm = modes_of(realise(tm), h, xscale);
        if (mp.empty() || mm.empty()) continue;
        for (size_t k = 0; k < nom.size(); ++k)
            J[k].col(i) = (mode_vec(nearest(mp, nom[k])) - mode_vec(nearest(mm, nom[k]))) / (2.0 * st);
    }
    for (size_t k = 0; k < nom.size(); ++k) {
        const VecR var = (J[k] * cov * J[k].transpose()).diagonal().cwiseMax(0.0);
        Mode &md = nom[k];
        md.sd_wn = std::sqrt(var(0));
        md.sd_fn = md.sd_wn / (2.0 * M_PI);
        md.sd_zeta = std::sqrt(var(1));
        const Eigen::Index g = md.residue.size(), ny = md.residue.rows(), nu = md.residue.cols();
        md.sd_residue_re = Eigen::Map<const VecR>(var.data() + 2, g).cwiseSqrt().reshaped(ny, nu);
        md.sd_residue_im = Eigen::Map<const VecR>(var.data() + 2 + g, g).cwiseSqrt().reshaped(ny, nu);
    }
    return nom;
}

}  // namespace msidfit
