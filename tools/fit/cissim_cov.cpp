// Discrete-cISSIM noise covariance (You et al. 2023 section 4.3): residual
// correlations (Alg. 6, eq. 32-33), Xi_zz by autocovariance least squares (35)
// under the PSD constraints of (36) with a small ADMM solver, covariances (Alg. 7).
#include "cissim.hpp"
#include "real_dft.hpp"
#include "msid_cancel.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace msidfit {

// Residuals of the full frequency set: every sample minus the mean of its phase over the K
// periods used (the LS fit of all T periodic components, Assumption 6). Column-major N x C.
static MatR residuals(const double *rows, size_t n_rows, uint32_t C, uint32_t T, uint32_t skip, uint64_t &K)
{
    const uint64_t total = n_rows / T;
    if (total < skip + 2)
        throw FitError("the noise covariance needs at least 2 whole periods after the skipped ones (the record has " +
                       std::to_string(total) + " of " + std::to_string(T) + " samples)");
    K = total - skip;
    const size_t N = (size_t)K * T, TC = (size_t)T * C;
    const double *base = rows + (size_t)skip * TC;
    // the phase means, row-major like the record (period by period, no index division)
    std::vector<double> mean(TC, 0.0);
    for (uint64_t p = 0; p < K; ++p) {
        const double *x = base + p * TC;
        for (size_t i = 0; i < TC; ++i) mean[i] += x[i];
    }
    for (double &v : mean) v /= (double)K;
    MatR r(N, C);
    for (uint64_t p = 0; p < K; ++p) {
        const double *x = base + p * TC;
        for (uint32_t j = 0; j < C; ++j) {
            double *out = r.col(j).data() + p * T;
            for (size_t n = 0; n < T; ++n) out[n] = x[n * C + j] - mean[n * C + j];
        }
    }
    return r;
}

// The padded length of the correlations: the power of two at or above n (records of similar length
// share one DFT length, planned once for the process).
static size_t fast_len(size_t n)
{
    size_t L = 1;
    while (L < n) L <<= 1;
    return L;
}

bool cissim_correlations_direct(int M, uint32_t nu, uint32_t ny, uint64_t N)
{
    // products per sample: M ny^2 by the definitions; about 2.5 log2 L per transform of the padded
    // residuals (C forward, ny (ny + 1) / 2 inverse)
    const double L = (double)fast_len((size_t)N + (size_t)M);
    return (double)M * ny * ny <= 2.5 * std::log2(L) * (nu + ny + ny * (ny + 1) / 2.0);
}

Correlations cissim_correlations(const double *rows, size_t n_rows, uint32_t nu, uint32_t ny, uint32_t T,
                                 uint32_t skip, int M, CorrMethod method)
{
    const uint32_t C = nu + ny;
    Correlations c;
    const MatR r = residuals(rows, n_rows, C, T, skip, c.periods);
    const size_t N = (size_t)r.rows();
    c.n = N;
    if (M < 1 || (size_t)M >= N) throw FitError("the number of correlation lags must be in [1, N)");
    const bool direct = method == CorrMethod::Direct || (method == CorrMethod::Auto && cissim_correlations_direct(M, nu, ny, N));
    if (direct) {
        // (32)-(33) as written: one dot product of two residual columns per lag and pair
        c.Xi_rr.assign((size_t)M, MatR::Zero(ny, ny));
        for (int l = 0; l < M; ++l) {
            const Eigen::Index len = (Eigen::Index)(N - (size_t)l);
            for (uint32_t i = 0; i < ny; ++i)
                for (uint32_t j = 0; j < ny; ++j)
                    c.Xi_rr[(size_t)l](i, j) = r.col(nu + i).segment(l, len).dot(r.col(nu + j).head(len)) / (double)len;
        }
        c.Xi_tt = MatR(nu, nu);
        for (uint32_t i = 0; i < nu; ++i)
            for (uint32_t j = 0; j < nu; ++j) c.Xi_tt(i, j) = r.col(i).dot(r.col(j)) / (double)N;
        return c;
    }
    // Alg. 6: spectra of the residuals (zero padded to L >= N + M so that the products give the
    // linear correlations of (32), not circular ones), cross-spectra, inverse transforms
    const size_t L = fast_len(N + (size_t)M), H = L / 2 + 1;
    RealDft fft(L);
    std::vector<std::vector<cd>> X(C, std::vector<cd>(H));
    std::vector<double> x(L, 0.0);
    for (uint32_t j = 0; j < C; ++j) {
        for (size_t k = 0; k < N; ++k) x[k] = r(k, j);
        fft.forward(x.data(), X[j].data());
    }
    c.Xi_rr.assign((size_t)M, MatR::Zero(ny, ny));
    std::vector<cd> S(H);
    std::vector<double> s(L);
    for (uint32_t i = 0; i < ny; ++i)
        for (uint32_t j = i; j < ny; ++j) {
            const auto &a = X[nu + i], &b = X[nu + j];
            for (size_t f = 0; f < H; ++f) S[f] = a[f] * std::conj(b[f]);
            fft.inverse(S.data(), s.data());   // L s[l] = sum_k r_i(k + l) r_j(k); L s[L - l] = sum_k r_j(k + l) r_i(k)
            for (int l = 0; l < M; ++l) {
                c.Xi_rr[(size_t)l](i, j) = s[(size_t)l] / (double)L / (double)(N - (size_t)l);
                c.Xi_rr[(size_t)l](j, i) = s[(L - (size_t)l) % L] / (double)L / (double)(N - (size_t)l);
            }
        }
    // eq. (33) by Parseval: sum_k tau_i tau_j = (1/L) sum_f T_i conj(T_j), the real parts of the bins
    // above L/2 mirror those below (a real signal's spectrum is Hermitian)
    c.Xi_tt = MatR(nu, nu);
    for (uint32_t i = 0; i < nu; ++i)
        for (uint32_t j = 0; j < nu; ++j) {
            double acc = 0;
            for (size_t f = 0; f < H; ++f) {
                const double w = (f == 0 || 2 * f == L) ? 1.0 : 2.0;
                acc += w * (X[i][f] * std::conj(X[j][f])).real();
            }
            c.Xi_tt(i, j) = acc / (double)L / (double)N;
        }
    return c;
}

Correlations cissim_correlations_time(const double *rows, size_t n_rows, uint32_t nu, uint32_t ny, uint32_t T,
                                      uint32_t skip, int M)
{
    const uint32_t C = nu + ny;
    Correlations c;
    const MatR r = residuals(rows, n_rows, C, T, skip, c.periods);
    const size_t N = (size_t)r.rows();
    c.n = N;
    if (M < 1 || (size_t)M >= N) throw FitError("the number of correlation lags must be in [1, N)");
    c.Xi_rr.assign((size_t)M, MatR::Zero(ny, ny));
    for (int l = 0; l < M; ++l) {
        MatR acc = MatR::Zero(ny, ny);
        for (size_t k = 0; k + (size_t)l < N; ++k)
            acc += r.row(k + (size_t)l).tail(ny).transpose() * r.row(k).tail(ny);   // (32)
        c.Xi_rr[(size_t)l] = acc / (double)(N - (size_t)l);
    }
    c.Xi_tt = r.leftCols(nu).transpose() * r.leftCols(nu) / (double)N;   // (33)
    return c;
}

static MatR psd_part(const MatR &X)
{
    const MatR S = 0.5 * (X + X.transpose());
    Eigen::SelfAdjointEigenSolver<MatR> es(S);
    return es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).asDiagonal() * es.eigenvectors().transpose();
}

VecR lmi_least_squares(const LmiLs &p, int &iterations, double &primal_residual, int max_iter, double tol)
{
    // rho from the scales of the two parts (the data are often ~1e-3 and the constraints ~1)
    double gsc = 0;
    for (const auto &G : p.G) gsc += G.squaredNorm();
    const double rho = std::max(p.F.squaredNorm(), 1e-300) / std::max(gsc, 1e-300);
    MatR Q = 2.0 * p.F.transpose() * p.F;
    for (const auto &G : p.G) Q += rho * G.transpose() * G;
    const Eigen::LDLT<MatR> ldlt(Q);
    const VecR Ftg = 2.0 * p.F.transpose() * p.g;
    const size_t k = p.G.size();
    std::vector<VecR> Z(k), U(k);
    VecR x = ldlt.solve(Ftg);
    for (size_t i = 0; i < k; ++i) {
        Z[i] = p.G[i] * x + p.h[i];
        U[i] = VecR::Zero(Z[i].size());
    }
    double scale = 0;
    for (size_t i = 0; i < k; ++i) scale = std::max(scale, (p.G[i] * x + p.h[i]).norm());
    scale = std::max(scale, 1e-300);
    iterations = 0;
    primal_residual = 0;
    for (int it = 0; it < max_iter; ++it) {
        msidutil::checkpoint(msidutil::Step::iterations, 1, "the cissim covariance");
        VecR rhs = Ftg;
        for (size_t i = 0; i < k; ++i) rhs += rho * p.G[i].transpose() * (Z[i] - p.h[i] - U[i]);
        x = ldlt.solve(rhs);
        double pr = 0, du = 0;
        for (size_t i = 0; i < k; ++i) {
            const VecR v = p.G[i] * x + p.h[i];
            const Eigen::Index d = (Eigen::Index)std::lround(std::sqrt((double)v.size()));
            const VecR zo = Z[i];
            const MatR P = psd_part(Eigen::Map<const MatR>(VecR(v + U[i]).data(), d, d));
            Z[i] = Eigen::Map<const VecR>(P.data(), P.size());
            U[i] += v - Z[i];
            pr = std::max(pr, (v - Z[i]).norm());
            du = std::max(du, (Z[i] - zo).norm());
        }
        iterations = it + 1;
        primal_residual = pr;
        if (pr < tol * scale && du < tol * scale) break;
    }
    return x;
}

// The side of a square matrix stored as a column of d^2 entries.
static Eigen::Index side(Eigen::Index d2) { return (Eigen::Index)std::lround(std::sqrt((double)d2)); }

// log det of every mat(G_i x + h_i) and their inverses; false when one is not positive definite.
static bool barrier_terms(const LmiLs &p, const VecR &x, double &logdet, std::vector<MatR> *inv)
{
    logdet = 0;
    for (size_t i = 0; i < p.G.size(); ++i) {
        const VecR v = p.G[i] * x + p.h[i];
        const Eigen::Index d = side(v.size());
        const MatR X = Eigen::Map<const MatR>(v.data(), d, d);
        const Eigen::LLT<MatR> llt(0.5 * (X + X.transpose()));
        if (llt.info() != Eigen::Success) return false;
        for (Eigen::Index k = 0; k < d; ++k) {
            const double l = llt.matrixLLT()(k, k);
            if (!(l > 0) || !std::isfinite(l)) return false;
            logdet += 2.0 * std::log(l);
        }
        if (inv) (*inv)[i] = llt.solve(MatR::Identity(d, d));
    }
    return true;
}

bool lmi_least_squares_barrier(const LmiLs &p, VecR &x, int &steps, double &gap, double tol)
{
    steps = 0;
    gap = 0;
    const Eigen::Index nx = p.F.cols();
    double m = 0, logdet = 0;
    for (const auto &G : p.G) m += (double)side(G.rows());
    std::vector<MatR> W(p.G.size());
    if (x.size() != nx || !barrier_terms(p, x, logdet, nullptr)) return false;
    // the cost from its residual (not from the normal equations: a fit that is nearly exact keeps its
    // digits)
    const MatR Hf = 2.0 * p.F.transpose() * p.F;
    const VecR bf = 2.0 * p.F.transpose() * p.g;
    const double S = std::max(p.g.squaredNorm(), 1e-300);
    VecR res(p.F.rows());
    auto f = [&](const VecR &y) {
        res.noalias() = p.F * y;
        res -= p.g;
        return res.squaredNorm();
    };
    VecR grad(nx), dx(nx), xn(nx);
    MatR H(nx, nx);
    // the central path from t0, where the fit and the barrier weigh alike, by factors of 10 (a
    // handful of Newton steps each) to the bound m / t <= tol ||g||^2
    double t = m / std::max(f(x), 1e-12 * S);
    for (int outer = 0; outer < 100; ++outer) {
        for (int inner = 0; inner < 50; ++inner) {
            msidutil::checkpoint(msidutil::Step::iterations, 1, "the cissim covariance");
            if (!barrier_terms(p, x, logdet, &W)) return false;
            grad.noalias() = t * (Hf * x - bf);
            H = t * Hf;
            for (size_t i = 0; i < p.G.size(); ++i) {
                // one constraint's share of the Hessian: O(nx^2 d^2), a large part of a second at order 40
                msidutil::checkpoint(msidutil::Step::solves, 0, "the cissim covariance");
                const Eigen::Index d = W[i].rows();
                grad.noalias() -= p.G[i].transpose() * Eigen::Map<const VecR>(W[i].data(), d * d);
                // d^2 log det / dx_a dx_b = -tr(W E_a W E_b), E_a = mat(G_i e_a): (W kron W) G_i
                MatR WEW(d * d, nx);
                for (Eigen::Index a = 0; a < nx; ++a) {
                    Eigen::Map<MatR> Y(WEW.col(a).data(), d, d);
                    Y.noalias() = W[i] * Eigen::Map<const MatR>(p.G[i].col(a).data(), d, d) * W[i];
                }
                H.noalias() += p.G[i].transpose() * WEW;
            }
            const Eigen::LLT<MatR> hl(0.5 * (H + H.transpose()));
            if (hl.info() != Eigen::Success) return false;
            dx = -hl.solve(grad);
            const double lam2 = -grad.dot(dx);   // Newton decrement squared
            if (!std::isfinite(lam2)) return false;
            if (lam2 <= 1e-8) break;             // centred: the barrier value within 5e-9 of its minimum
            // backtracking (Armijo) inside the domain
            const double phi0 = t * f(x) - logdet;
            double step = 1.0;
            bool moved = false;
            for (int ls = 0; ls < 60; ++ls, step *= 0.5) {
                xn = x + step * dx;
                double ldn = 0;
                if (!barrier_terms(p, xn, ldn, nullptr)) continue;
                if (t * f(xn) - ldn <= phi0 - 0.25 * step * lam2) {
                    x = xn;
                    moved = true;
                    break;
                }
            }
            ++steps;
            // no full step left near the centre: the rounding of the barrier's value, not the path
            if (!moved || (step < 1.0 && lam2 < 1e-4)) break;
        }
        gap = m / t;
        if (gap <= tol * S) return true;
        t *= 10.0;
    }
    return true;
}

NoiseCov cissim_noise_cov(const SSModel &m, const Correlations &cr)
{
    NoiseCov out;
    const Eigen::Index n = m.A.rows(), ny = m.C.rows();
    const int M = (int)cr.Xi_rr.size();
    out.lags = M;
    if (M < 2) throw FitError("the covariance needs at least 2 correlation lags");
    // dof correction of the periodic-mean projection
    const double kc = cr.periods > 1 ? (double)cr.periods / (double)(cr.periods - 1) : 1.0;
    std::vector<MatR> Xi(cr.Xi_rr);
    for (auto &X : Xi) X *= kc;
    // Assumption 7 (strong detectability)
    Eigen::FullPivLU<MatR> luA(m.A), luC(m.C);
    const bool nonsingular = luA.rank() == n;
    const bool fullcol = luC.rank() == n;
    out.detectable = nonsingular && fullcol;
    if (!out.detectable)
        out.note = std::string("strong detectability (Assumption 7) fails: ") +
                   (!fullcol ? "C has rank " + std::to_string(luC.rank()) + " < n = " + std::to_string(n) : "A is singular") +
                   "; (35) is underdetermined, Sigma_ww and Sigma_vv are a nominal solution that reproduces the output "
                   "correlations (Remark 5), not the true covariances; Sigma_tt is unaffected";
    // unknowns: vech(Xi_zz), basis E_a symmetric
    const Eigen::Index nx = n * (n + 1) / 2;
    std::vector<MatR> E;
    for (Eigen::Index j = 0; j < n; ++j)
        for (Eigen::Index i = j; i < n; ++i) {
            MatR e = MatR::Zero(n, n);
            e(i, j) = e(j, i) = 1.0;
            E.push_back(e);
        }
    LmiLs p;
    const Eigen::Index pp = ny * ny;
    p.F = MatR::Zero((M - 1) * pp, nx);
    p.g = VecR((M - 1) * pp);
    MatR CAl = m.C;
    for (int l = 1; l < M; ++l) {
        CAl = CAl * m.A;   // C A^l: eq. (34) vec(Xi_rr^l) = (C kron C A^l) vec(Xi_zz)
        for (Eigen::Index a = 0; a < nx; ++a) {
            const MatR v = CAl * E[(size_t)a] * m.C.transpose();
            p.F.block((l - 1) * pp, a, pp, 1) = Eigen::Map<const VecR>(v.data(), pp);
        }
        p.g.segment((l - 1) * pp, pp) = Eigen::Map<const VecR>(Xi[(size_t)l].data(), pp);
    }
    // (36): Xi >= 0, Xi - A Xi A^T >= 0, Xi_rr^0 - C Xi C^T >= 0
    MatR G1(n * n, nx), G2(n * n, nx), G3(pp, nx);
    for (Eigen::Index a = 0; a < nx; ++a) {
        const MatR &e = E[(size_t)a];
        const MatR e2 = e - m.A * e * m.A.transpose(), e3 = -(m.C * e * m.C.transpose());
        G1.col(a) = Eigen::Map<const VecR>(e.data(), n * n);
        G2.col(a) = Eigen::Map<const VecR>(e2.data(), n * n);
        G3.col(a) = Eigen::Map<const VecR>(e3.data(), pp);
    }
    const MatR X0 = 0.5 * (Xi[0] + Xi[0].transpose());
    p.G = {G1, G2, G3};
    p.h = {VecR::Zero(n * n), VecR::Zero(n * n), Eigen::Map<const VecR>(X0.data(), pp)};
    // A strictly feasible start for the interior-point solver: Xi = eps P with P - A P A^T = I
    // (A Schur), so that Xi and Xi - A Xi A^T = eps I are positive definite, eps small enough that
    // Xi_rr^0 - C Xi C^T is too. Without one (A not Schur, Xi_rr^0 singular): ADMM.
    VecR x;
    bool done = false;
    const Eigen::LLT<MatR> l0(X0);
    if (ss_stable(m) && l0.info() == Eigen::Success) {
        const MatR Inn = MatR::Identity(n, n);
        MatR Kr = MatR::Identity(n * n, n * n);   // I - A kron A: vec(A P A^T) = (A kron A) vec P
        for (Eigen::Index l = 0; l < n; ++l)
            for (Eigen::Index k = 0; k < n; ++k)
                for (Eigen::Index j = 0; j < n; ++j)
                    for (Eigen::Index i = 0; i < n; ++i) Kr(i + n * j, k + n * l) -= m.A(i, k) * m.A(j, l);
        // an LU of n^2 x n^2 (seconds from order 40), abandoned on a stop
        const VecR pv = msidutil::abandonable<VecR>(
            [Kr = std::move(Kr), Inn] { return VecR(Kr.partialPivLu().solve(Eigen::Map<const VecR>(Inn.data(), Inn.size()))); },
            msidutil::Step::solves, "the cissim covariance");
        const MatR Pl = Eigen::Map<const MatR>(pv.data(), n, n);
        const MatR Q = l0.matrixL().solve(MatR(m.C * Pl * m.C.transpose()));
        const MatR Qs = l0.matrixL().solve(Q.transpose());
        const double lmax = Eigen::SelfAdjointEigenSolver<MatR>(0.5 * (Qs + Qs.transpose()), Eigen::EigenvaluesOnly)
                                .eigenvalues()
                                .maxCoeff();
        const double eps = lmax > 0 ? 0.5 / lmax : 1.0;
        x.resize(nx);
        for (Eigen::Index a = 0, j = 0; j < n; ++j)
            for (Eigen::Index i = j; i < n; ++i) x(a++) = eps * 0.5 * (Pl(i, j) + Pl(j, i));
        double gap = 0;
        done = lmi_least_squares_barrier(p, x, out.iterations, gap, 1e-12);
        out.solver = "interior point";
        out.duality_gap = gap;
    }
    if (!done) {
        x = lmi_least_squares(p, out.iterations, out.primal_residual);
        out.solver = "ADMM";
        out.duality_gap = -1;
    }
    MatR Xz = MatR::Zero(n, n);
    for (Eigen::Index a = 0; a < nx; ++a) Xz += x(a) * E[(size_t)a];
    out.Xi_zz = Xz;
    out.fit_residual = p.g.norm() > 0 ? (p.F * x - p.g).norm() / p.g.norm() : 0.0;
    out.Sigma_ww = Xz - m.A * Xz * m.A.transpose();
    out.Sigma_vv = X0 - m.C * Xz * m.C.transpose();
    out.Sigma_tt = cr.Xi_tt * kc;
    return out;
}

}  // namespace msidfit
