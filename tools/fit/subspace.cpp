#include "subspace.hpp"
#include "stats.hpp"

#include "msid_cancel.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>

namespace msidfit {

double real_equations(const std::vector<WeightedLine> &w)
{
    double n = 0;
    for (const auto &l : w) n += l.real ? 1 : 2;
    return n;
}

// C = A B for small dynamic matrices (plain loops: Eigen's general product has a
// large fixed cost at these sizes, and these run once per line per block-row count).
static inline void small_mul(const MatC &A, const MatC &B, MatC &C)
{
    const Eigen::Index r = A.rows(), k = A.cols(), c = B.cols();
    for (Eigen::Index j = 0; j < c; ++j)
        for (Eigen::Index i = 0; i < r; ++i) {
            cd s = 0.0;
            for (Eigen::Index t = 0; t < k; ++t) s += A(i, t) * B(t, j);
            C(i, j) = s;
        }
}
static inline void small_mulv(const MatC &A, const cd *x, cd *y)
{
    const Eigen::Index r = A.rows(), k = A.cols();
    for (Eigen::Index i = 0; i < r; ++i) {
        cd s = 0.0;
        for (Eigen::Index t = 0; t < k; ++t) s += A(i, t) * x[t];
        y[i] = s;
    }
}

// Fast evaluation of C (x I - A)^{-1} at many points: A = V diag(lambda) V^{-1}
// once, then C V diag(1/(x - lambda)) V^{-1} per point; falls back to an LU per
// point when A is (nearly) defective.
// The size from which a dense step of the subspace fit (an eigendecomposition, an SVD, a QR: O(k^3),
// over a second from k = 1000, and the SVD of the resolvent's eigenvectors from order 200) runs as one
// abandonable step (msid_cancel.hpp), so that a stop lands at once. Below, a step takes milliseconds,
// less than starting its thread.
static constexpr Eigen::Index ABANDONABLE_SIZE = 48;

// `work` (holding its inputs by value) as one abandonable step when `size` reaches ABANDONABLE_SIZE,
// else a plain call.
template <class R, class F> static R dense_step(Eigen::Index size, F work)
{
    if (size < ABANDONABLE_SIZE) return work();
    return msidutil::abandonable<R>(std::function<R()>(std::move(work)), msidutil::Step::solves, "the subspace fit");
}

struct Resolvent {
    bool diag = false;
    MatC CV, Vi, A;
    VecC lam;
    MatC C;
    Resolvent() = default;
    Resolvent(const MatR &Am, const MatR &Cm)
    {
        const Eigen::Index n = Am.rows();
        C = Cm.cast<cd>();
        A = Am.cast<cd>();
        if (n == 0) return;
        *this = dense_step<Resolvent>(n, [A = A, C = C] { return decompose(A, C); });
    }
    // The diagonal form, when A's eigenvectors are well conditioned.
    static Resolvent decompose(const MatC &A, const MatC &C)
    {
        Resolvent r;
        r.A = A;
        r.C = C;
        const Eigen::Index n = A.rows();
        Eigen::ComplexEigenSolver<MatC> es(A);
        if (es.info() != Eigen::Success) return r;
        const MatC V = es.eigenvectors();
        Eigen::JacobiSVD<MatC> sv(V);
        const double c = sv.singularValues()(0) / sv.singularValues()(n - 1);
        if (!(c < 1e8)) return r;
        r.lam = es.eigenvalues();
        r.Vi = V.inverse();
        r.CV = C * V;
        r.diag = true;
        return r;
    }
    // K = C (x I - A)^{-1} into preallocated K (ny x n), T scratch (ny x n)
    void at(cd x, MatC &K, MatC &T) const
    {
        const Eigen::Index n = A.rows();
        if (n == 0) return;
        if (diag) {
            for (Eigen::Index k = 0; k < n; ++k) {
                const cd d = 1.0 / (x - lam(k));
                for (Eigen::Index i = 0; i < CV.rows(); ++i) T(i, k) = CV(i, k) * d;
            }
            small_mul(T, Vi, K);
            return;
        }
        MatC M = -A;
        M.diagonal().array() += x;
        K.noalias() = C * M.partialPivLu().inverse();
    }
};

double weighted_cost_ss(const SSModel &m, const std::vector<WeightedLine> &w)
{
    const Resolvent res(m.A, m.C);
    const MatC B = m.B.cast<cd>(), D = m.D.cast<cd>();
    const Eigen::Index n = m.A.rows(), ny = m.C.rows(), nu = B.cols(), g = ny * nu;
    MatC K(ny, n), T(ny, n), E(ny, nu);
    VecC e(g);
    double V = 0.0;
    for (const auto &l : w) {
        if (n) {
            res.at(l.x, K, T);
            small_mul(K, B, E);
            E = l.G - D - E;
        } else {
            E = l.G - D;
        }
        small_mulv(l.Linv, E.data(), e.data());
        V += (l.real ? 0.5 : 1.0) * e.squaredNorm();
    }
    return V;
}

double fit_BD(SSModel &m, const std::vector<WeightedLine> &w, bool estimate_D)
{
    const Eigen::Index n = m.A.rows(), ny = m.C.rows(), nu = m.B.cols() ? m.B.cols() : (Eigen::Index)(w[0].G.cols());
    const Eigen::Index g = ny * nu, nb = n * nu, nd = estimate_D ? g : 0, np = nb + nd;
    // The whitened rows [X y] (per line g complex equations -> 2g real, real lines g) are reduced to
    // the R factor of [X y] a chunk of lines at a time (a QR of the running R stacked on the chunk's
    // rows: the buffer stays in cache and no 2Lg x np matrix is formed); then, with
    // R [X y] = [[R_X, z], [0, rho]], the LS solution solves R_X th = z (column pivoting: rank
    // deficient X gives the basic solution, as a pivoted QR of X would) and the weighted cost is
    // |R [th; -1]|^2 = |y - X th|^2.
    const Eigen::Index nc = np + 1, CH = 64 * 2 * g;
    MatR S(nc + CH, nc);      // rows 0..have-1: the running R; then the chunk's rows
    Eigen::Index have = 0, rows = 0;
    auto reduce = [&]() {
        if (!rows) return;
        const Eigen::Index used = have + rows;
        Eigen::Ref<MatR> top = S.topRows(used);
        Eigen::HouseholderQR<Eigen::Ref<MatR>> qr(top);   // in place
        have = std::min(used, nc);
        S.topRows(have) = S.topRows(have).triangularView<Eigen::Upper>();
        rows = 0;
    };
    const Resolvent res(m.A, m.C);
    MatC K(ny, n), T(ny, n);
    for (const auto &l : w) {
        res.at(l.x, K, T);   // ny x n
        // whitened rows of [ (I_nu kron K) , I_g ] and of vec(G): row a of Linv times them
        const double s = l.real ? std::sqrt(0.5) : 1.0;
        const Eigen::Index r0 = have + rows, ri = l.real ? 0 : g;   // imaginary rows follow the real ones
        for (Eigen::Index a = 0; a < g; ++a) {
            for (Eigen::Index j = 0; j < nu; ++j)
                for (Eigen::Index k = 0; k < n; ++k) {
                    cd acc = 0.0;
                    for (Eigen::Index i = 0; i < ny; ++i) acc += l.Linv(a, i + ny * j) * K(i, k);
                    S(r0 + a, j * n + k) = s * acc.real();
                    if (!l.real) S(r0 + ri + a, j * n + k) = acc.imag();
                }
            cd gy = 0.0;
            for (Eigen::Index b = 0; b < g; ++b) {
                if (estimate_D) {
                    S(r0 + a, nb + b) = s * l.Linv(a, b).real();
                    if (!l.real) S(r0 + ri + a, nb + b) = l.Linv(a, b).imag();
                }
                gy += l.Linv(a, b) * l.G.data()[b];
            }
            S(r0 + a, np) = s * gy.real();
            if (!l.real) S(r0 + ri + a, np) = gy.imag();
        }
        rows += l.real ? g : 2 * g;
        if (rows + 2 * g > CH) {
            reduce();
            msidutil::checkpoint(msidutil::Step::solves, 0, "the subspace fit");   // a QR of 64 lines' rows
        }
    }
    reduce();
    const MatR Rf = S.topRows(have);
    // Columns scaled to unit norm before the pivoting solve: the B columns scale with the inputs'
    // units and the D columns with the outputs' over the inputs', so in units where they differ by
    // 1e9 (nm against m) the pivoting threshold (relative to the largest pivot) dropped whole B
    // columns and the fit depended on the units. With unit columns the solution is scale free.
    VecR cs(np);
    for (Eigen::Index k = 0; k < np; ++k) {
        const double c = Rf.col(k).norm();
        cs(k) = c > 0 ? 1.0 / c : 1.0;
    }
    VecR th = (Rf.leftCols(np) * cs.asDiagonal()).colPivHouseholderQr().solve(Rf.col(np));
    th = cs.asDiagonal() * th;
    m.B = Eigen::Map<const MatR>(th.data(), n, nu);
    m.D = estimate_D ? MatR(Eigen::Map<const MatR>(th.data() + nb, ny, nu)) : MatR::Zero(ny, nu);
    // weighted cost: the whitened residual (real lines already carry their 1/2)
    return (Rf.col(np) - Rf.leftCols(np) * th).squaredNorm();
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

// Everything of the subspace step that does not depend on r, computed once for the largest r of
// the scan. Z^T (2 F nu rows, columns U_0..U_{R-1}, Y_0..Y_{R-1}) is, with its rows grouped by
// input j, block structured: input j's rows are [W_j, Y_j] with W_j = [Re; Im] W_R(x_l)^T (the same
// for every j) in the columns of U_k's entry j and zeros under the other inputs' U columns. Its R
// factor therefore comes from one QR per input of the 2F x R (1 + ny) matrix Z_j = [W_j, Y_j]
// (about half the work of the QR of Z^T): Z_j = Q_j R_j. For a block-row count r <= R the columns
// of U_0..U_{r-1} of Z_j are its first r columns, whose span in R_j's coordinates is that of the
// first r unit vectors (R_j upper triangular), so the Y_0..Y_{r-1} columns with U_0..U_{r-1}
// projected out are rows r.. of R_j's Y_0..Y_{r-1} columns, and (step 1b of P Algorithm 1)
// R_22(r)^T R_22(r) = sum_j R_j[r:, Y(r)]^T R_j[r:, Y(r)]; C_Y(r) is the leading principal block.
struct Precomp {
    int R = 0;
    Eigen::Index nu = 0, ny = 0;
    std::vector<MatR> Rj;   // per input: min(2F, R (1 + ny)) x R (1 + ny), upper triangular
    MatR CY;                // R ny square
};

static Precomp precompute(const std::vector<WeightedLine> &w, const Shared &sh, int R, bool weighted)
{
    Precomp pc;
    pc.R = R;
    const Eigen::Index nu = w[0].G.cols(), ny = w[0].G.rows(), F = (Eigen::Index)w.size();
    pc.nu = nu;
    pc.ny = ny;
    const Eigen::Index cols = R * (1 + ny), rows = 2 * F;
    std::vector<MatR> Z((size_t)nu, MatR::Zero(rows, cols));
    // C_Y = Re sum_l (W W^H) kron S_l. On the unit circle (|xi| = 1: DT z, CT bilinear w)
    // (W W^H)(a, b) = xi^(a-b): accumulate the 2R-1 moments sum_l xi^k S_l once.
    std::vector<MatC> mom((size_t)(2 * R - 1), MatC::Zero(ny, ny));
    bool unit = true;
    for (Eigen::Index l = 0; l < F; ++l) {
        const cd x = sh.xi[(size_t)l];
        if (std::abs(std::abs(x) - 1.0) > 1e-12) unit = false;
        const MatC &G = w[(size_t)l].G;
        cd p = 1.0;
        for (int k = 0; k < R; ++k, p *= x) {
            for (Eigen::Index j = 0; j < nu; ++j) {
                MatR &Zj = Z[(size_t)j];
                Zj(2 * l, k) = p.real();
                Zj(2 * l + 1, k) = p.imag();
                for (Eigen::Index i = 0; i < ny; ++i) {
                    const cd v = p * G(i, j);
                    Zj(2 * l, R + k * ny + i) = v.real();
                    Zj(2 * l + 1, R + k * ny + i) = v.imag();
                }
            }
        }
        MatC S = MatC::Zero(ny, ny);
        if (weighted)
            for (Eigen::Index j = 0; j < nu; ++j) S += w[(size_t)l].cov.block(j * ny, j * ny, ny, ny);
        else
            S = MatC::Identity(ny, ny);
        if (unit) {
            // moments k = -(R-1)..(R-1) at index k + R - 1
            cd pk = 1.0;
            const cd xc = std::conj(x);
            for (int k = 0; k < R; ++k, pk *= x) mom[(size_t)(R - 1 + k)] += pk * S;
            pk = xc;
            for (int k = 1; k < R; ++k, pk *= xc) mom[(size_t)(R - 1 - k)] += pk * S;
        }
    }
    pc.CY = MatR::Zero(R * ny, R * ny);
    if (unit) {
        for (int a = 0; a < R; ++a)
            for (int b = 0; b < R; ++b) pc.CY.block(a * ny, b * ny, ny, ny) = mom[(size_t)(R - 1 + a - b)].real();
    } else {
        for (Eigen::Index l = 0; l < F; ++l) {
            const VecC W = powers(sh.xi[(size_t)l], R);
            MatC S = MatC::Zero(ny, ny);
            if (weighted)
                for (Eigen::Index j = 0; j < nu; ++j) S += w[(size_t)l].cov.block(j * ny, j * ny, ny, ny);
            else
                S = MatC::Identity(ny, ny);
            for (int a = 0; a < R; ++a)
                for (int b = 0; b < R; ++b)
                    for (Eigen::Index i = 0; i < ny; ++i)
                        for (Eigen::Index k = 0; k < ny; ++k) pc.CY(a * ny + i, b * ny + k) += (W(a) * std::conj(W(b)) * S(i, k)).real();
        }
    }
    const Eigen::Index keep = std::min(rows, cols);
    for (Eigen::Index j = 0; j < nu; ++j) {
        Eigen::HouseholderQR<Eigen::Ref<MatR>> qr(Z[(size_t)j]);   // in place
        pc.Rj.push_back(qr.matrixQR().topRows(keep).triangularView<Eigen::Upper>());
    }
    return pc;
}

// Relative eigenvalue threshold of C_Y for its pseudo-inverse square root. C_Y's moments are sums over
// the F lines (relative rounding ~F eps ~ 1e-13 for a few hundred lines) and the eigensolver adds
// ~q eps: eigenvalues near 1e-13 lmax are rounding noise, and their inverse square roots amplified it.
// With the former 1e-13 a perturbation of the FRF by 1e-13 (relative) moved the r-scan costs of the
// 12-mode SISO structure at r = 72 between 278 and 15989 and the refined model between p = 0.46 and
// p = 1e-264 (tests/integration/test_fit_acceptance.py); from 1e-11 up the costs are stable to 3-4
// digits (1e-9: 280.9 / 312.1 at r = 72 / 96 for every perturbation; 1e-7: 281.6 / 311.9).
static constexpr double CY_RANK_TOL = 1e-9;

// A and C from block-row count r (steps 1-2 of Algorithm 1). Returns the singular values.
static void estimate_AC_here(const Precomp &pc, int r, int n, MatR &A, MatR &C, std::vector<double> &sv)
{
    const Eigen::Index ny = pc.ny, R = pc.R;
    // R_22^T R_22 from the rows r.. of every input's R factor (see Precomp)
    MatR G22 = MatR::Zero(r * ny, r * ny);
    for (const MatR &Rj : pc.Rj)
        if (Rj.rows() > r) {
            const auto Yr = Rj.block(r, R, Rj.rows() - r, r * ny);
            G22.selfadjointView<Eigen::Lower>().rankUpdate(Yr.transpose());
        }
    G22.triangularView<Eigen::StrictlyUpper>() = G22.transpose();
    const MatR CY = pc.CY.topLeftCorner(r * ny, r * ny);
    // C_Y^{1/2} and its (pseudo-)inverse by a symmetric eigendecomposition: with many block
    // rows over a narrow band C_Y is numerically rank deficient (near-collinear powers).
    // MatR arguments: the one compute<MatrixXd> instance of eigen_inst_eigen.cpp, not one per expression type
    Eigen::SelfAdjointEigenSolver<MatR> es(MatR(0.5 * (CY + CY.transpose())));
    const VecR lam = es.eigenvalues();
    const double lmax = lam.maxCoeff();
    if (!(lmax > 0)) throw FitError("the noise weighting C_Y of the subspace step is zero");
    VecR sq(lam.size()), isq(lam.size());
    for (Eigen::Index k = 0; k < lam.size(); ++k) {
        const bool keep = lam(k) > CY_RANK_TOL * lmax;
        sq(k) = keep ? std::sqrt(lam(k)) : 0.0;
        isq(k) = keep ? 1.0 / std::sqrt(lam(k)) : 0.0;
    }
    const MatR Ch = es.eigenvectors() * sq.asDiagonal() * es.eigenvectors().transpose();
    const MatR Cih = es.eigenvectors() * isq.asDiagonal() * es.eigenvectors().transpose();
    // Mw = C_Y^{-1/2} R_22^T: its left singular vectors are the eigenvectors of
    // Mw Mw^T = C_Y^{-1/2} R_22^T R_22 C_Y^{-1/2} (descending), its singular values sqrt(eig)
    const MatR MMt = Cih * G22 * Cih;
    Eigen::SelfAdjointEigenSolver<MatR> eg(MatR(0.5 * (MMt + MMt.transpose())));   // a plain matrix: the shared instance
    const Eigen::Index q = MMt.rows();
    sv.resize((size_t)q);
    MatR Us(q, n);
    for (Eigen::Index k = 0; k < q; ++k) sv[(size_t)k] = std::sqrt(std::max(0.0, eg.eigenvalues()(q - 1 - k)));
    for (Eigen::Index k = 0; k < n; ++k) Us.col(k) = eg.eigenvectors().col(q - 1 - k);
    const MatR O = Ch * Us;
    // shift property (12): O_[1:r-1] A = O_[2:r]
    A = O.topRows((r - 1) * ny).completeOrthogonalDecomposition().solve(O.bottomRows((r - 1) * ny));
    C = O.topRows(ny);
}

// estimate_AC_here as one dense step (two eigendecompositions of size r ny).
static void estimate_AC(const std::shared_ptr<const Precomp> &pc, int r, int n, MatR &A, MatR &C,
                        std::vector<double> &sv)
{
    struct AC {
        MatR A, C;
        std::vector<double> sv;
    };
    AC ac = dense_step<AC>(r * pc->ny, [pc, r, n] {
        AC o;
        estimate_AC_here(*pc, r, n, o.A, o.C, o.sv);
        return o;
    });
    A = std::move(ac.A);
    C = std::move(ac.C);
    sv = std::move(ac.sv);
}

// precompute as one dense step (a QR per input of 2F x R (1 + ny)).
static std::shared_ptr<const Precomp> precompute_step(const std::vector<WeightedLine> &w, const Shared &sh, int R,
                                                      bool weighted)
{
    const Eigen::Index size = R * (1 + w[0].G.rows());
    if (size < ABANDONABLE_SIZE) return std::make_shared<const Precomp>(precompute(w, sh, R, weighted));
    return dense_step<std::shared_ptr<const Precomp>>(
        size, [w, sh, R, weighted] { return std::make_shared<const Precomp>(precompute(w, sh, R, weighted)); });
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

static SubspaceResult fit_subspace_normalised(const FrfData &f, Domain d, const std::vector<WeightedLine> &w,
                                              bool weighted, const SubspaceOptions &o);

// The subspace step is not invariant to the units of the channels: C_Y sums the noise of every input
// column and its pseudo-inverse square root drops directions below 1e-13 of its largest eigenvalue,
// and the shift equation for A is a least-squares problem over the outputs' rows. Outputs in units
// 1e12 apart (m and pm) had the small output ignored, and inputs in units 1e6 apart gave a model
// 3000 times the noise level. So the algorithm runs on the data in units where every
// output's and every input column's mean noise variance is 1: G' = diag(1/s_o) G diag(1/s_i) with
// log s_o(i)^2 + log s_i(j)^2 the two-way (row + column) mean fit of log mean_l Gamma_l(ij, ij), which
// any change of units shifts by exactly log a_i^2 - log b_j^2 (a global factor left over changes
// nothing). The model is mapped back (C = diag(s_o) C', B = B' diag(s_i), D = diag(s_o) D' diag(s_i));
// the whitened residuals, hence every cost and test, are the same in both units. Unweighted fits
// (unit covariance) are left as they are.
SubspaceResult fit_subspace(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted,
                            const SubspaceOptions &o)
{
    if (!weighted || w.empty()) return fit_subspace_normalised(f, d, w, weighted, o);
    const Eigen::Index ny = w[0].G.rows(), nu = w[0].G.cols();
    MatR lm = MatR::Zero(ny, nu);
    for (const auto &l : w)
        for (Eigen::Index j = 0; j < nu; ++j)
            for (Eigen::Index i = 0; i < ny; ++i) lm(i, j) += l.cov(i + ny * j, i + ny * j).real();
    for (Eigen::Index j = 0; j < nu; ++j)
        for (Eigen::Index i = 0; i < ny; ++i) {
            if (!(lm(i, j) > 0) || !std::isfinite(lm(i, j))) return fit_subspace_normalised(f, d, w, weighted, o);
            lm(i, j) = std::log(lm(i, j) / (double)w.size());
        }
    const double grand = lm.mean();
    VecR so(ny), si(nu);   // standard deviations: outputs, inputs
    for (Eigen::Index i = 0; i < ny; ++i) so(i) = std::exp(0.5 * lm.row(i).mean());
    for (Eigen::Index j = 0; j < nu; ++j) si(j) = std::exp(0.5 * (lm.col(j).mean() - grand));
    VecR t(ny * nu);   // vec(G') = t .* vec(G)
    for (Eigen::Index j = 0; j < nu; ++j)
        for (Eigen::Index i = 0; i < ny; ++i) t(i + ny * j) = 1.0 / (so(i) * si(j));
    auto normalise = [&](std::vector<WeightedLine> wn) {
        for (auto &l : wn) {
            l.G = so.cwiseInverse().asDiagonal() * l.G * si.cwiseInverse().asDiagonal();
            l.cov = t.asDiagonal() * l.cov * t.asDiagonal();
            l.Linv = l.Linv * t.cwiseInverse().asDiagonal();
        }
        return wn;
    };
    const std::vector<WeightedLine> wn = normalise(w);
    std::vector<WeightedLine> wrn;   // the refinement's weights in the same units
    SubspaceOptions on = o;
    if (o.refine_w) {
        wrn = normalise(*o.refine_w);
        on.refine_w = &wrn;
    }
    SubspaceResult r = fit_subspace_normalised(f, d, wn, weighted, on);
    auto back = [&](SSModel &m) {
        if (m.C.rows() == ny) m.C = so.asDiagonal() * m.C;
        if (m.B.cols() == nu) m.B = m.B * si.asDiagonal();
        if (m.D.rows() == ny && m.D.cols() == nu) m.D = so.asDiagonal() * m.D * si.asDiagonal();
    };
    back(r.model);
    for (auto &m : r.candidates) back(m);
    return r;
}

// Pintelon 2002 Thm 2: with sample covariances from M periods, A and C need M >= 2, B and D
// (inverse-covariance weighted) M >= 4; dof = M - 1 per experiment. Refused before any work.
static void check_weight_periods(const std::vector<WeightedLine> &w, bool weighted)
{
    if (!weighted) return;
    double dmin = 1e300;
    for (const auto &l : w) dmin = std::min(dmin, l.dof);
    if (dmin < 1.0) throw FitError("the weights rest on fewer than 2 periods: the sample subspace algorithm needs M >= 2");
    if (dmin < 3.0)
        throw FitError("the weights rest on " + std::to_string((int)std::lround(dmin + 1)) +
                       " periods: B and D weighted by the inverse sample covariance need M >= 4 "
                       "(Pintelon 2002, Theorem 2); measure more periods or use --weight none");
}

// The lines' points of the algorithm: the z-domain points as they are (dt), or the s-domain points
// mapped by the bilinear w = (s/ws - 1) / (s/ws + 1) onto the unit circle (ct; ws the geometric mean
// of the lines' extreme angular frequencies unless given), where the Vandermonde-like powers of the
// data stay well conditioned.
static Shared frequency_map(Domain d, const std::vector<WeightedLine> &w, const SubspaceOptions &o)
{
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
    return sh;
}

// The rank limits: Z^T has 2 F nu rows (real lines give nu zero rows) and r (nu + ny) columns, so the
// block rows are at most rmax and the order at most rmax - 1; the order asked for is checked there.
struct RankLimits {
    int rmax, max_order;
};

static RankLimits rank_limits(const std::vector<WeightedLine> &w, const SubspaceOptions &o)
{
    const Eigen::Index nu = w[0].G.cols(), ny = w[0].G.rows();
    const double eq = real_equations(w);
    const int rmax = (int)std::floor(eq * nu / (double)(nu + ny)) - 1;
    if (rmax < 2) throw FitError("too few lines for subspace identification");
    const int max_order = rmax - 1;
    if (o.order > max_order)
        throw FitError("order " + std::to_string(o.order) + " is too high for " + std::to_string(w.size()) +
                       " lines: the largest order these lines support is " + std::to_string(max_order));
    if (o.order < 0) throw FitError("the order must be positive");
    return {rmax, max_order};
}

// The order to fit: the one given, or (order 0) the largest gap of the singular values of one fit at
// r0 block rows (given, else at most 12).
static int model_order(const std::vector<WeightedLine> &w, const Shared &sh, bool weighted, const SubspaceOptions &o,
                       const RankLimits &lim)
{
    if (o.order != 0) return o.order;
    const int r0 = o.r ? o.r : std::min(lim.rmax, 12);
    MatR A, C;
    std::vector<double> sv;
    const auto pc0 = precompute_step(w, sh, r0, weighted);
    estimate_AC(pc0, r0, 1, A, C, sv);
    return auto_order(sv, std::min(r0 - 1, lim.max_order));
}

// Block-row counts tried: the one given (checked against [n + 1, rmax]), else r in {1.5n, 2n, 3n, 4n}
// within [n + 1, rmax] (a scan of every r in [1.5n, 6n] cost 30-100 fits; these four bracket the best
// r on the simulated structures), ascending.
static std::vector<int> block_row_counts(const SubspaceOptions &o, int n, int rmax)
{
    std::vector<int> rs;
    if (o.r) {
        if (o.r <= n || o.r > rmax)
            throw FitError("block rows r = " + std::to_string(o.r) + " must lie in [" + std::to_string(n + 1) + ", " +
                           std::to_string(rmax) + "]");
        rs.push_back(o.r);
        return rs;
    }
    for (int r : {(int)std::ceil(1.5 * n), 2 * n, 3 * n, 4 * n}) {
        r = std::min(std::max(r, n + 1), rmax);
        if (std::find(rs.begin(), rs.end(), r) == rs.end()) rs.push_back(r);
    }
    std::sort(rs.begin(), rs.end());
    return rs;
}

// The fit at one block-row count: its model, singular values, cost (1e300: failed, err says why) and
// the number of unstable poles reflected.
struct Trial {
    SSModel m;
    std::vector<double> sv;
    double V = 1e300;
    int refl = 0;
    std::string err;
};

// One block-row count's fit: A and C from the shared precomputation (mapped back from the w-domain
// for ct), the unstable poles reflected when asked, then B and D by weighted least squares. A failure
// is the trial's, not the fit's (the other counts may succeed); a stop (Cancelled) goes through.
static void fit_trial(Trial &t, const std::shared_ptr<const Precomp> &pc, const FrfData &f, Domain d,
                      const std::vector<WeightedLine> &w, const Shared &sh, int r, int n, const SubspaceOptions &o)
{
    const Eigen::Index nu = w[0].G.cols(), ny = w[0].G.rows();
    try {
        SSModel &m = t.m;
        m.domain = d;
        m.h = f.h;
        MatR Aw, Cw;
        estimate_AC(pc, r, n, Aw, Cw, t.sv);
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
        if (o.stable) t.refl = ss_reflect_unstable(m);
        t.V = fit_BD(m, w, o.estimate_D);
    } catch (const std::exception &e) {
        t.err = e.what();
    }
}

// work(0..nr-1), each block-row count an independent fit, on the available cores: hw - 1 threads
// beside this one, which takes its own share (one thread start saved). The caller's cancellation token
// is every thread's; this thread, the only one that can see the caller's stop, asks it while it waits
// for the others (a stop is then seen at their next checkpoint), and every thread has ended before the
// stop is thrown.
template <class Work> static void run_trials(int nr, const Work &work)
{
    const unsigned hw = std::max(1u, std::min(4u, std::thread::hardware_concurrency()));
    if (hw <= 1 || nr <= 1) {
        for (int i = 0; i < nr; ++i) work(i);
        return;
    }
    msidutil::Cancel *const cancel = msidutil::current_cancel();
    std::atomic<bool> stopped{false};
    std::mutex mu;
    std::condition_variable cv;
    unsigned busy = hw;
    auto share = [&](unsigned t) {
        msidutil::CancelScope scope(cancel);
        try {
            for (int i = (int)t; i < nr && !stopped; i += (int)hw) work(i);
        } catch (const msidutil::Cancelled &) {
            stopped = true;
        }
        std::lock_guard<std::mutex> g(mu);
        --busy;
        cv.notify_all();
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < hw; ++t) pool.emplace_back(share, t);
    share(0);
    std::unique_lock<std::mutex> g(mu);
    while (busy) {
        cv.wait_for(g, std::chrono::milliseconds(5));
        if (!busy || stopped) continue;
        g.unlock();
        try {
            msidutil::checkpoint(msidutil::Step::solves, 0, "the subspace fit");
        } catch (const msidutil::Cancelled &) {
            stopped = true;
        }
        g.lock();
    }
    g.unlock();
    for (auto &th : pool) th.join();
    if (stopped) throw msidutil::Cancelled{"the subspace fit"};
}

// The scan over the block-row counts into res (every count's cost), and the model of the lowest
// finite cost, taken in order so that ties go to the smaller r, deterministically.
static void keep_best_trial(const std::vector<int> &rs, const std::vector<Trial> &trials, SubspaceResult &res)
{
    double best = 1e300;
    for (size_t i = 0; i < rs.size(); ++i) {
        const int r = rs[i];
        const Trial &t = trials[i];
        res.scan.emplace_back(r, t.V);
        if (std::isfinite(t.V) && t.V < best) {
            best = t.V;
            res.model = t.m;
            res.r = r;
            res.sv = t.sv;
            res.cost = t.V;
            res.reflected = t.refl;
        }
    }
    if (!(best < 1e300)) throw FitError("subspace identification failed at every block-row count");
}

// With the feedthrough estimated and left to the data: the likelihood-ratio test of D = 0,
// 2 (V0 - V1) ~ chi2 with ny nu dof (cost (35) in likelihood units); D = 0 kept unless p < 0.01.
static void test_feedthrough(SubspaceResult &res, const std::vector<WeightedLine> &w, bool weighted,
                             const SubspaceOptions &o)
{
    res.feedthrough = o.estimate_D;
    if (!(o.estimate_D && o.feedthrough_auto && weighted)) return;
    const Eigen::Index nu = w[0].G.cols(), ny = w[0].G.rows();
    SSModel m0 = res.model;
    const double V0 = fit_BD(m0, w, false);
    res.feedthrough_p = chi2_sf((double)(ny * nu), std::max(0.0, 2.0 * (V0 - res.cost)));
    if (res.feedthrough_p >= 0.01) { res.model = m0; res.cost = V0; res.feedthrough = false; }
}

// The r scan left unstable poles and stability is the default: the unconstrained and the reflected
// (constrained) refinements on the refinement's weights wr, the constrained one from two starts; the
// unconstrained model is kept only if it became stable at no higher cost.
static void refine_to_stable(SubspaceResult &res, const std::vector<WeightedLine> &wr, bool weighted, int it)
{
    SSModel mu = res.model, ms = res.model;
    const SubspaceRefine ru = refine_subspace(mu, wr, res.feedthrough, false, it);
    int k = ss_reflect_unstable(ms);
    double Vs = fit_BD(ms, wr, res.feedthrough);
    SubspaceRefine rc = refine_subspace(ms, wr, res.feedthrough, true, it);
    if (rc.refined) Vs = rc.cost;
    const double Vu = ru.refined ? ru.cost : res.cost;
    if (!ss_stable(mu)) {
        // second constrained start: the refined unconstrained model with its (by now small)
        // unstable terms reflected
        SSModel m2 = mu;
        const int k2 = ss_reflect_unstable(m2);
        double V2 = fit_BD(m2, wr, res.feedthrough);
        const SubspaceRefine r2 = refine_subspace(m2, wr, res.feedthrough, true, it);
        if (r2.refined) V2 = r2.cost;
        if (V2 < Vs) { ms = m2; Vs = V2; k = k2; rc = r2; }
    }
    res.cost_unconstrained = Vu;
    if (ss_stable(mu) && Vu <= Vs) {
        res.model = mu;   // the unconstrained refinement moved the poles into the stable region
        res.cost = Vu;
        res.refine_steps = ru.iterations;
    } else {
        // stable by default: the constrained model is kept. The likelihood-ratio statistic
        // 2 (Vs - Vu) ~ chi2(k) is written as a diagnostic only: it assumes the model is right, and
        // with model error (nonlinear distortion, too low an order) unstable poles lower the cost
        // of a stable plant's fit as well (docs/fitting.md "Stable by default")
        res.stable_lr_p = weighted ? chi2_sf((double)k, std::max(0.0, 2.0 * (Vs - Vu))) : 1.0;
        res.model = ms;
        res.cost = Vs;
        res.reflected = k;
        res.refine_steps = rc.iterations;
    }
}

// The refinement of the chosen model (asked for, or needed to make it stable by default) on the
// refinement's weights (pooled: sample-ML weights from few periods cost accuracy; docs/fitting.md);
// the cost is reported on the r scan's weights.
static void refine_model(SubspaceResult &res, const std::vector<WeightedLine> &w, bool weighted, const SubspaceOptions &o)
{
    if (!(o.refine_iter > 0 || o.stable_auto)) return;
    res.cost_unrefined = res.cost;
    const int it = std::max(0, o.refine_iter);
    const std::vector<WeightedLine> &wr = o.refine_w ? *o.refine_w : w;
    if (o.refine_w) res.cost = weighted_cost_ss(res.model, wr);
    if (o.stable_auto && !o.stable && !ss_stable(res.model)) {
        refine_to_stable(res, wr, weighted, it);
    } else if (it > 0) {
        const SubspaceRefine rr = refine_subspace(res.model, wr, res.feedthrough, o.stable || o.stable_auto, it);
        if (rr.refined) { res.cost = rr.cost; res.refine_steps = rr.iterations; }
    }
    if (o.refine_w) res.cost = weighted_cost_ss(res.model, w);   // reported on the r scan's weights
}

// The three block-row counts' models of the lowest cost (ties in r's order), for the caller's choice.
static void keep_candidates(const std::vector<Trial> &trials, SubspaceResult &res)
{
    std::vector<int> order_idx;
    for (int i = 0; i < (int)trials.size(); ++i) if (std::isfinite(trials[(size_t)i].V)) order_idx.push_back(i);
    std::stable_sort(order_idx.begin(), order_idx.end(), [&](int a, int b) { return trials[(size_t)a].V < trials[(size_t)b].V; });
    for (size_t k = 0; k < order_idx.size() && k < 3; ++k) res.candidates.push_back(trials[(size_t)order_idx[k]].m);
}

static SubspaceResult fit_subspace_normalised(const FrfData &f, Domain d, const std::vector<WeightedLine> &w,
                                              bool weighted, const SubspaceOptions &o)
{
    if (w.empty()) throw FitError("no lines");
    check_weight_periods(w, weighted);
    const Shared sh = frequency_map(d, w, o);
    const RankLimits lim = rank_limits(w, o);
    SubspaceResult res;
    res.wscale = sh.wscale;
    const int n = model_order(w, sh, weighted, o, lim);
    const std::vector<int> rs = block_row_counts(o, n, lim.rmax);
    // one precomputation for the largest count serves every count
    const auto pc = precompute_step(w, sh, rs.back(), weighted);
    const int nr = (int)rs.size();
    std::vector<Trial> trials((size_t)nr);
    run_trials(nr, [&](int i) { fit_trial(trials[(size_t)i], pc, f, d, w, sh, rs[(size_t)i], n, o); });
    keep_best_trial(rs, trials, res);
    test_feedthrough(res, w, weighted, o);
    refine_model(res, w, weighted, o);
    keep_candidates(trials, res);
    return res;
}

}  // namespace msidfit
