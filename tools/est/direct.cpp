#include "direct.hpp"

#include <cmath>

namespace msidest {

DirectResult direct_frf(const msid_design &d, const msid_twiddle &tw, const std::vector<DirectRecord> &recs, size_t ny)
{
    const uint32_t P = d.period, L = d.n_lines, nu = d.n_inputs;
    if (recs.size() != d.n_experiments) throw EstError("one record per design experiment is needed");
    // parameter columns: per line and input, (Re G, Im G); DC lines only Re G
    std::vector<Eigen::Index> col0(L);
    Eigen::Index p = 0;
    for (uint32_t l = 0; l < L; ++l) { col0[l] = p; p += (d.bins[l] == 0 ? 1 : 2) * nu; }
    Eigen::Index N = 0;
    DirectResult res;
    for (const auto &r : recs) { N += (Eigen::Index)r.n; if (r.n % P) res.whole_periods = false; }
    if (N <= p)
        throw EstError("the direct LS FRF needs more samples (" + std::to_string(N) + ") than regressors (" + std::to_string(p) + ")");
    MatR X(N, p), Y(N, (Eigen::Index)ny);
    Eigen::Index row = 0;
    for (uint32_t e = 0; e < recs.size(); ++e) {
        const auto &r = recs[e];
        for (size_t k = 0; k < r.n; ++k, ++row) {
            for (size_t i = 0; i < ny; ++i) Y(row, (Eigen::Index)i) = r.rows[k * r.stride + r.y_col + i];
            for (uint32_t l = 0; l < L; ++l) {
                const uint32_t b = d.bins[l];
                const msid_cplx w = tw.w[(uint64_t)b * (k % P) % P];   // exp(-j 2 pi b k / P)
                for (uint32_t j = 0; j < nu; ++j) {
                    const msid_cplx c = msid_design_coef(&d, e, j, l);
                    // c e^{+j theta}: e^{+j theta} = conj(w)
                    const double re = c.re * w.re + c.im * w.im, im = c.im * w.re - c.re * w.im;
                    if (b == 0) {
                        X(row, col0[l] + j) = c.re;
                    } else {
                        X(row, col0[l] + 2 * j) = re;       // multiplies Re G
                        X(row, col0[l] + 2 * j + 1) = -im;  // multiplies Im G
                    }
                }
            }
        }
    }
    Eigen::ColPivHouseholderQR<MatR> qr(X);
    const MatR Rm = qr.matrixR().topLeftCorner(p, p).triangularView<Eigen::Upper>();
    const double dmax = Rm.diagonal().cwiseAbs().maxCoeff(), dmin = Rm.diagonal().cwiseAbs().minCoeff();
    res.cond = dmin > 0 ? dmax / dmin : INFINITY;
    if (qr.rank() < p || !(dmin > 1e-11 * dmax)) {
        // name a line whose columns are dependent
        const auto perm = qr.colsPermutation().indices();
        const Eigen::Index bad = perm(std::max<Eigen::Index>(qr.rank(), 0) < p ? qr.rank() : p - 1);
        uint32_t lb = 0;
        for (uint32_t l = 0; l < L; ++l) if (col0[l] <= bad) lb = l;
        throw EstError("the direct regression is singular at line " + std::to_string(lb + 1) + " (bin " +
                       std::to_string(d.bins[lb]) + "): the record does not separate it from the other lines");
    }
    const MatR beta = qr.solve(Y);                   // p x ny
    const MatR Rres = Y - X * beta;
    res.dof_real = (double)(N - p);
    res.sigma = Rres.transpose() * Rres / res.dof_real;
    // (X^T X)^{-1} from R: P^T X^T X P = R^T R
    const MatR Rinv = Rm.triangularView<Eigen::Upper>().solve(MatR::Identity(p, p));
    MatR XtXi_perm = Rinv * Rinv.transpose();
    MatR XtXi(p, p);
    const auto perm = qr.colsPermutation().indices();
    for (Eigen::Index a = 0; a < p; ++a)
        for (Eigen::Index b = 0; b < p; ++b) XtXi(perm(a), perm(b)) = XtXi_perm(a, b);
    // per line: complex G and its covariance / pseudo-covariance from the real ones:
    // Cov(beta[:, i], beta[:, i']) = sigma(i, i') XtXi (Theorem 2: Sigma kron Z^{-1})
    const size_t g = ny * nu;
    res.lines.resize(L);
    for (uint32_t l = 0; l < L; ++l) {
        DirectLine &dl = res.lines[l];
        dl.G = MatC::Zero((Eigen::Index)ny, nu);
        dl.cov = MatC::Zero((Eigen::Index)g, (Eigen::Index)g);
        dl.pcov = MatC::Zero((Eigen::Index)g, (Eigen::Index)g);
        const bool dc = d.bins[l] == 0;
        auto ca = [&](uint32_t j) { return col0[l] + (dc ? j : 2 * j); };
        auto cb = [&](uint32_t j) { return dc ? (Eigen::Index)-1 : col0[l] + 2 * j + 1; };
        for (size_t i = 0; i < ny; ++i)
            for (uint32_t j = 0; j < nu; ++j)
                dl.G((Eigen::Index)i, j) = cd(beta(ca(j), (Eigen::Index)i), dc ? 0.0 : beta(cb(j), (Eigen::Index)i));
        for (size_t i = 0; i < ny; ++i)
            for (uint32_t j = 0; j < nu; ++j)
                for (size_t i2 = 0; i2 < ny; ++i2)
                    for (uint32_t j2 = 0; j2 < nu; ++j2) {
                        const double s = res.sigma((Eigen::Index)i, (Eigen::Index)i2);
                        auto C = [&](Eigen::Index x, Eigen::Index y) { return (x < 0 || y < 0) ? 0.0 : s * XtXi(x, y); };
                        const Eigen::Index a1 = ca(j), b1 = cb(j), a2 = ca(j2), b2 = cb(j2);
                        const size_t v1 = i + ny * j, v2 = i2 + ny * j2;
                        // x = a + j b: E[dx1 conj dx2], E[dx1 dx2]
                        dl.cov((Eigen::Index)v1, (Eigen::Index)v2) = cd(C(a1, a2) + C(b1, b2), C(b1, a2) - C(a1, b2));
                        dl.pcov((Eigen::Index)v1, (Eigen::Index)v2) = cd(C(a1, a2) - C(b1, b2), C(b1, a2) + C(a1, b2));
                    }
        if (d.is_ct && d.folded[l]) {   // the DT bin carries G(-j w) = conj(G(j w))
            dl.G = dl.G.conjugate();
            dl.cov = dl.cov.conjugate();
            dl.pcov = dl.pcov.conjugate();
        }
    }
    return res;
}

}  // namespace msidest
