#include "subspace.hpp"

#include <algorithm>
#include <cmath>

namespace msidfit {

double real_equations(const std::vector<WeightedLine> &w)
{
    double n = 0;
    for (const auto &l : w) n += l.real ? 1 : 2;
    return n;
}

static MatC vec(const MatC &M) { return Eigen::Map<const MatC>(M.data(), M.size(), 1); }

double weighted_cost_ss(const SSModel &m, const std::vector<WeightedLine> &w)
{
    double V = 0.0;
    for (const auto &l : w) {
        const MatC e = l.Linv * vec(l.G - ss_eval(m, l.x));
        V += (l.real ? 0.5 : 1.0) * e.squaredNorm();
    }
    return V;
}

void fit_BD(SSModel &m, const std::vector<WeightedLine> &w, bool estimate_D)
{
    const Eigen::Index n = m.A.rows(), ny = m.C.rows(), nu = m.B.cols() ? m.B.cols() : (Eigen::Index)(w[0].G.cols());
    const Eigen::Index g = ny * nu, nb = n * nu, nd = estimate_D ? g : 0, np = nb + nd;
    // rows: per line g complex equations -> 2g real (real lines: g)
    Eigen::Index rows = 0;
    for (const auto &l : w) rows += l.real ? g : 2 * g;
    MatR X(rows, np);
    VecR y(rows);
    Eigen::Index r0 = 0;
    const MatC Cc = m.C.cast<cd>(), Ac = m.A.cast<cd>();
    for (const auto &l : w) {
        MatC Mx = -Ac;
        Mx.diagonal().array() += l.x;
        const MatC K = n ? MatC(Cc * Mx.partialPivLu().inverse()) : MatC(ny, 0);   // ny x n
        MatC Phi(g, np);
        // vec(K B) = (I_nu kron K) vec(B); vec(D) = I_g vec(D)
        Phi.setZero();
        for (Eigen::Index j = 0; j < nu; ++j) Phi.block(j * ny, j * n, ny, n) = K;
        if (estimate_D) Phi.rightCols(g) = MatC::Identity(g, g);
        const MatC Wp = l.Linv * Phi;
        const MatC Wy = l.Linv * vec(l.G);
        const double s = l.real ? std::sqrt(0.5) : 1.0;
        X.block(r0, 0, g, np) = s * Wp.real();
        y.segment(r0, g) = s * Wy.real();
        r0 += g;
        if (!l.real) {
            X.block(r0, 0, g, np) = Wp.imag();
            y.segment(r0, g) = Wy.imag();
            r0 += g;
        }
    }
    const VecR th = X.colPivHouseholderQr().solve(y);
    m.B = Eigen::Map<const MatR>(th.data(), n, nu);
    m.D = estimate_D ? MatR(Eigen::Map<const MatR>(th.data() + nb, ny, nu)) : MatR::Zero(ny, nu);
}

// W_r(x) = [1, x, ..., x^{r-1}]
static VecC powers(cd x, int r)
{
    VecC v(r);
    cd p = 1.0;
    for (int k = 0; k < r; ++k) { v(k) = p; p *= x; }
    return v;
}

struct Shared {
    std::vector<cd> xi;   // transformed variable per line
    double wscale = 0.0;
};

// A and C from block-row count r (steps 1-2 of Algorithm 1). Returns the singular values.
static void estimate_AC(const std::vector<WeightedLine> &w, const Shared &sh, int r, int n, bool weighted,
                        MatR &A, MatR &C, std::vector<double> &sv)
{
    const Eigen::Index nu = w[0].G.cols(), ny = w[0].G.rows();
    const Eigen::Index F = (Eigen::Index)w.size();
    const Eigen::Index rows = r * (nu + ny), cols = 2 * F * nu;
    MatR ZT(cols, rows);   // Z^T: one row per real column of Z
    MatR CY = MatR::Zero(r * ny, r * ny);
    for (Eigen::Index l = 0; l < F; ++l) {
        const VecC W = powers(sh.xi[(size_t)l], r);
        for (Eigen::Index j = 0; j < nu; ++j) {
            VecC z(rows);
            for (int k = 0; k < r; ++k) {
                z.segment(k * nu, nu).setZero();
                z(k * nu + j) = W(k);
                z.segment(r * nu + k * ny, ny) = W(k) * w[(size_t)l].G.col(j);
            }
            ZT.row(2 * (l * nu + j)) = z.real().transpose();
            ZT.row(2 * (l * nu + j) + 1) = z.imag().transpose();
        }
        // C_Y = Re sum_l (W W^H) kron S_l, S_l = sum_j cov of column j of the noise
        MatC S = MatC::Zero(ny, ny);
        if (weighted)
            for (Eigen::Index j = 0; j < nu; ++j) S += w[(size_t)l].cov.block(j * ny, j * ny, ny, ny);
        else
            S = MatC::Identity(ny, ny);
        const MatC WW = W * W.adjoint();
        for (int a = 0; a < r; ++a)
            for (int b = 0; b < r; ++b) CY.block(a * ny, b * ny, ny, ny) += (WW(a, b) * S).real();
    }
    Eigen::HouseholderQR<MatR> qr(ZT);
    const MatR R = qr.matrixQR().topRows(rows).triangularView<Eigen::Upper>();
    const MatR R22 = R.bottomRightCorner(r * ny, r * ny);
    // C_Y^{1/2} and its (pseudo-)inverse by a symmetric eigendecomposition: with many block
    // rows over a narrow band C_Y is numerically rank deficient (near-collinear powers).
    Eigen::SelfAdjointEigenSolver<MatR> es(0.5 * (CY + CY.transpose()));
    const VecR lam = es.eigenvalues();
    const double lmax = lam.maxCoeff();
    if (!(lmax > 0)) throw FitError("the noise weighting C_Y of the subspace step is zero");
    VecR sq(lam.size()), isq(lam.size());
    for (Eigen::Index k = 0; k < lam.size(); ++k) {
        const bool keep = lam(k) > 1e-13 * lmax;
        sq(k) = keep ? std::sqrt(lam(k)) : 0.0;
        isq(k) = keep ? 1.0 / std::sqrt(lam(k)) : 0.0;
    }
    const MatR Ch = es.eigenvectors() * sq.asDiagonal() * es.eigenvectors().transpose();
    const MatR Cih = es.eigenvectors() * isq.asDiagonal() * es.eigenvectors().transpose();
    const MatR Mw = Cih * R22.transpose();
    Eigen::JacobiSVD<MatR> svd(Mw, Eigen::ComputeFullU);
    sv.assign(svd.singularValues().data(), svd.singularValues().data() + svd.singularValues().size());
    const MatR O = Ch * svd.matrixU().leftCols(n);
    // shift property (12): O_[1:r-1] A = O_[2:r]
    A = O.topRows((r - 1) * ny).completeOrthogonalDecomposition().solve(O.bottomRows((r - 1) * ny));
    C = O.topRows(ny);
}

static int auto_order(const std::vector<double> &sv, int rmax_order)
{
    int best = 1;
    double gap = -1;
    for (int k = 1; k <= rmax_order && k < (int)sv.size(); ++k) {
        if (!(sv[(size_t)k] > 0)) return k;
        const double gk = std::log(sv[(size_t)k - 1] / sv[(size_t)k]);
        if (gk > gap) { gap = gk; best = k; }
    }
    return best;
}

SubspaceResult fit_subspace(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted,
                            const SubspaceOptions &o)
{
    (void)f;
    if (w.empty()) throw FitError("no lines");
    const Eigen::Index nu = w[0].G.cols(), ny = w[0].G.rows();
    // Pintelon 2002 Thm 2: with sample covariances from M periods, A and C need M >= 2,
    // B and D (inverse-covariance weighted) M >= 4; dof = M - 1 per experiment.
    if (weighted) {
        double dmin = 1e300;
        for (const auto &l : w) dmin = std::min(dmin, l.dof);
        if (dmin < 1.0)
            throw FitError("the weights rest on fewer than 2 periods: the sample subspace algorithm needs M >= 2");
        if (dmin < 3.0)
            throw FitError("the weights rest on " + std::to_string((int)std::lround(dmin + 1)) +
                           " periods: B and D weighted by the inverse sample covariance need M >= 4 "
                           "(Pintelon 2002, Theorem 2); measure more periods or use --weight none");
    }
    Shared sh;
    if (d == Domain::CT) {
        double lo = 1e300, hi = 0;
        for (const auto &l : w) {
            const double om = std::abs(l.x.imag());
            if (om > 0) { lo = std::min(lo, om); hi = std::max(hi, om); }
        }
        if (!(hi > 0)) throw FitError("continuous-time subspace needs at least one line above DC");
        sh.wscale = o.wscale > 0 ? o.wscale : std::sqrt(lo * hi);
        for (const auto &l : w) {
            const cd s = l.x / sh.wscale;
            sh.xi.push_back((s - 1.0) / (s + 1.0));
        }
    } else {
        for (const auto &l : w) sh.xi.push_back(l.x);
    }
    // rank limits: Z^T has 2 F nu rows (real lines give nu zero rows) and r (nu + ny) columns
    const double eq = real_equations(w);
    const int rmax = (int)std::floor(eq * nu / (double)(nu + ny)) - 1;
    if (rmax < 2) throw FitError("too few lines for subspace identification");
    const int max_order = rmax - 1;
    if (o.order > max_order)
        throw FitError("order " + std::to_string(o.order) + " is too high for " + std::to_string(w.size()) +
                       " lines: the largest order these lines support is " + std::to_string(max_order));
    if (o.order < 0) throw FitError("the order must be positive");
    SubspaceResult res;
    res.wscale = sh.wscale;
    int n = o.order;
    if (n == 0) {
        const int r0 = o.r ? o.r : std::min(rmax, 12);
        MatR A, C;
        std::vector<double> sv;
        estimate_AC(w, sh, r0, 1, weighted, A, C, sv);
        n = auto_order(sv, std::min(r0 - 1, max_order));
    }
    int rlo = std::max(n + 1, (int)std::ceil(1.5 * n)), rhi = std::min(6 * n, rmax);
    if (o.r) {
        if (o.r <= n || o.r > rmax)
            throw FitError("block rows r = " + std::to_string(o.r) + " must lie in [" + std::to_string(n + 1) + ", " +
                           std::to_string(rmax) + "]");
        rlo = rhi = o.r;
    }
    if (rhi < rlo) rhi = rlo = std::min(std::max(n + 1, rlo), rmax);
    double best = 1e300;
    for (int r = rlo; r <= rhi; ++r) {
        SSModel m;
        m.domain = d;
        m.h = f.h;
        std::vector<double> sv;
        MatR Aw, Cw;
        estimate_AC(w, sh, r, n, weighted, Aw, Cw, sv);
        if (d == Domain::CT) {
            // w-domain (A_w, C_w) to s: A = ws (I - A_w)^{-1}(I + A_w), C = 2 C_w (I - A_w)^{-1}
            const MatR I = MatR::Identity(n, n);
            Eigen::PartialPivLU<MatR> lu(I - Aw), luT((I - Aw).transpose());
            m.A = sh.wscale * lu.solve(I + Aw);
            m.C = 2.0 * luT.solve(Cw.transpose()).transpose();   // 2 C_w (I - A_w)^{-1}
        } else {
            m.A = Aw;
            m.C = Cw;
        }
        m.B = MatR::Zero(n, nu);
        m.D = MatR::Zero(ny, nu);
        int refl = 0;
        if (o.stable) refl = ss_reflect_unstable(m);
        fit_BD(m, w, o.estimate_D);
        const double V = weighted_cost_ss(m, w);
        res.scan.emplace_back(r, V);
        if (std::isfinite(V) && V < best) {
            best = V;
            res.model = m;
            res.r = r;
            res.sv = sv;
            res.cost = V;
            res.reflected = refl;
        }
    }
    if (!(best < 1e300)) throw FitError("subspace identification failed at every block-row count");
    return res;
}

}  // namespace msidfit
