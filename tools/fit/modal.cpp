#include "modal.hpp"
#include "stats.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
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

// Quantities of a mode for the delta method: wn, zeta, then v = (Re p, Im p, Re R, Im R) with p the pole
// in the model's variable and R column-major (v: the contribution tests).
static VecR mode_vec(const Mode &md)
{
    const Eigen::Index g = md.residue.size();
    VecR q(4 + 2 * g);
    q(0) = md.wn;
    q(1) = md.zeta;
    q(2) = md.pole.real();
    q(3) = md.pole.imag();
    for (Eigen::Index i = 0; i < g; ++i) {
        q(4 + i) = md.residue.data()[i].real();
        q(4 + g + i) = md.residue.data()[i].imag();
    }
    return q;
}

// The contribution of a mode at the lines, c = R/(x - p) (+ conj(R)/(x - conj p) for a pair), stacked
// [Re; Im] per line and entry (2 L g), and its Jacobian with respect to v = (Re p, Im p, Re R, Im R).
static void contribution(const Mode &md, const std::vector<cd> &xs, VecR &c, MatR &B)
{
    const Eigen::Index g = md.residue.size(), L = (Eigen::Index)xs.size();
    c.setZero(2 * L * g);
    B.setZero(2 * L * g, 2 + 2 * g);
    const cd p = md.pole, pc = std::conj(md.pole), I(0.0, 1.0);
    for (Eigen::Index l = 0; l < L; ++l) {
        const cd a = 1.0 / (xs[(size_t)l] - p), b = md.real ? 0.0 : 1.0 / (xs[(size_t)l] - pc);
        for (Eigen::Index e = 0; e < g; ++e) {
            const cd R = md.residue.data()[e];
            const cd v = R * a + std::conj(R) * b;
            const cd dre = R * a * a + std::conj(R) * b * b, dim = I * (R * a * a - std::conj(R) * b * b);
            const cd drr = a + b, dri = I * (a - b);
            const Eigen::Index row = 2 * (l * g + e);
            c(row) = v.real();
            c(row + 1) = v.imag();
            const cd d[4] = {dre, dim, drr, dri};
            const Eigen::Index col[4] = {0, 1, 2 + e, 2 + g + e};
            for (int k = 0; k < 4; ++k) {
                B(row, col[k]) = d[k].real();
                B(row + 1, col[k]) = d[k].imag();
            }
        }
    }
}

// W = c^T (B S B^T)^+ c with S = Jv cov Jv^T: through the SVD of B S^{1/2} (2 L g x dim v), its singular
// values above 1e-9 of the largest; returns dof (0: no test).
static int contrib_wald(const VecR &c, const MatR &B, const MatR &Jv, const MatR &cov, double *w)
{
    const Eigen::SelfAdjointEigenSolver<MatR> es(Jv * cov * Jv.transpose());
    const VecR ev = es.eigenvalues().cwiseMax(0.0);
    const MatR M = B * es.eigenvectors() * ev.cwiseSqrt().asDiagonal();
    const Eigen::JacobiSVD<MatR> svd(M, Eigen::ComputeThinU);
    const VecR &sv = svd.singularValues();
    if (!(sv.size() > 0 && sv(0) > 0) || !std::isfinite(sv(0))) return 0;
    const VecR uc = svd.matrixU().transpose() * c;
    int dof = 0;
    *w = 0;
    for (Eigen::Index i = 0; i < sv.size(); ++i) {
        if (!(sv(i) > 1e-9 * sv(0))) break;
        *w += (uc(i) / sv(i)) * (uc(i) / sv(i));
        ++dof;
    }
    return dof;
}

// The contribution tests of every mode (and of neighbouring real poles together); J[k]: d mode_vec / d theta.
static void contribution_tests(std::vector<Mode> &ms, const std::vector<MatR> &J, const MatR &cov,
                               const std::vector<cd> &xs)
{
    const size_t K = ms.size();
    std::vector<VecR> c(K);
    std::vector<MatR> B(K), Jv(K);
    for (size_t k = 0; k < K; ++k) {
        contribution(ms[k], xs, c[k], B[k]);
        Jv[k] = J[k].bottomRows(J[k].rows() - 2);
        double w = 0;
        const int dof = contrib_wald(c[k], B[k], Jv[k], cov, &w);
        if (dof == 0) continue;
        ms[k].contrib_chi2 = w;
        ms[k].contrib_dof = dof;
        ms[k].contrib_p = chi2_sf(dof, w);
    }
    for (size_t k = 0; k < K; ++k) {   // neighbouring real poles (in frequency order) together
        if (!ms[k].real) continue;
        size_t m = k + 1;
        while (m < K && !ms[m].real) ++m;
        if (m >= K) break;
        MatR Bj(B[k].rows(), B[k].cols() + B[m].cols()), Jj(Jv[k].rows() + Jv[m].rows(), Jv[k].cols());
        Bj << B[k], B[m];
        Jj << Jv[k], Jv[m];
        double w = 0;
        const int dof = contrib_wald(c[k] + c[m], Bj, Jj, cov, &w);
        if (dof == 0) continue;
        const double p = chi2_sf(dof, w);
        for (size_t t : {k, m}) {
            if (ms[t].contrib_p >= p) continue;   // its own test (or a joint one) is already the weaker
            ms[t].contrib_chi2 = w;
            ms[t].contrib_dof = dof;
            ms[t].contrib_p = p;
            ms[t].contrib_with = (int)(t == k ? m : k);
        }
    }
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
                                const MatR &cov, double h, double xscale, const std::vector<cd> &xs)
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
        md.sd_residue_re = Eigen::Map<const VecR>(var.data() + 4, g).cwiseSqrt().reshaped(ny, nu);
        md.sd_residue_im = Eigen::Map<const VecR>(var.data() + 4 + g, g).cwiseSqrt().reshaped(ny, nu);
    }
    if (!xs.empty()) contribution_tests(nom, J, cov, xs);
    return nom;
}

}  // namespace msidfit
