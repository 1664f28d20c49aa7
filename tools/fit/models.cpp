#include "models.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace msidfit {

MatC ss_eval(const SSModel &m, cd x)
{
    const Eigen::Index n = m.A.rows();
    if (n == 0) return m.D.cast<cd>();
    MatC M = -m.A.cast<cd>();
    M.diagonal().array() += x;
    return m.C.cast<cd>() * M.partialPivLu().solve(m.B.cast<cd>()) + m.D.cast<cd>();
}

cd lmfd_var(Domain d, cd x) { return d == Domain::CT ? x : 1.0 / x; }

MatC lmfd_eval(const LmfdModel &m, cd x)
{
    const cd p = lmfd_var(m.domain, x);
    const Eigen::Index ny = (Eigen::Index)m.ny();
    MatC Dp = MatC::Identity(ny, ny), Np = MatC::Zero(ny, (Eigen::Index)m.nu());
    cd pk = 1.0;
    for (int j = 0; j <= m.nN || j <= m.nD; ++j) {
        if (j >= 1 && j <= m.nD) Dp += pk * m.Dm[(size_t)j - 1].cast<cd>();
        if (j <= m.nN) Np += pk * m.Nm[(size_t)j].cast<cd>();
        pk *= p;
    }
    return Dp.partialPivLu().solve(Np);
}

bool ss_to_lmfd_dt(const SSModel &m, int nD, LmfdModel &out)
{
    const Eigen::Index n = (Eigen::Index)m.n(), ny = m.C.rows(), nu = m.B.cols();
    if (m.domain != Domain::DT || nD < 1 || n != ny * nD) return false;
    MatR O(n, n);
    MatR CA = m.C;
    for (int i = 0; i < nD; ++i) { O.middleRows(i * ny, ny) = CA; CA = CA * m.A; }
    // [D_nD .. D_1] = -C A^nD O^-1 (solved as O^T X^T = -(C A^nD)^T)
    Eigen::FullPivLU<MatR> lu(O.transpose());
    if (lu.rank() < n) return false;
    const MatR X = lu.solve(MatR(-CA.transpose())).transpose();
    if (!X.allFinite()) return false;
    out = LmfdModel();
    out.domain = Domain::DT;
    out.h = m.h;
    out.nD = nD;
    out.nN = nD;
    for (int i = 1; i <= nD; ++i) out.Dm.push_back(X.middleCols((nD - i) * ny, ny));
    std::vector<MatR> h((size_t)nD + 1);   // Markov parameters h_0 = D, h_k = C A^(k-1) B
    h[0] = m.D;
    MatR AkB = m.B;
    for (int k = 1; k <= nD; ++k) { h[(size_t)k] = m.C * AkB; AkB = m.A * AkB; }
    for (int j = 0; j <= nD; ++j) {
        MatR Nj = h[(size_t)j];
        for (int i = 1; i <= j; ++i) Nj += out.Dm[(size_t)i - 1] * h[(size_t)(j - i)];
        out.Nm.push_back(Nj);
    }
    (void)nu;
    return true;
}

SSModel lmfd_to_ss(const LmfdModel &m)
{
    const Eigen::Index ny = (Eigen::Index)m.ny(), nu = (Eigen::Index)m.nu();
    const int nD = m.nD;
    if (m.nN > nD) throw FitError("an LMFD with numerator degree above the denominator degree has no proper realisation");
    SSModel s;
    s.domain = m.domain;
    s.h = m.h;
    if (nD == 0) {
        s.A = MatR(0, 0); s.B = MatR(0, nu); s.C = MatR(ny, 0); s.D = m.Nm[0];
        return s;
    }
    const Eigen::Index n = ny * nD;
    s.A = MatR::Zero(n, n);
    s.B = MatR::Zero(n, nu);
    s.C = MatR::Zero(ny, n);
    s.C.leftCols(ny) = MatR::Identity(ny, ny);
    auto N = [&](int j) { return j <= m.nN ? m.Nm[(size_t)j] : MatR::Zero(ny, nu); };
    if (m.domain == Domain::DT) {
        // y = -sum D_i z^-i y + sum N_j z^-j u  (observer form in z^-1)
        s.D = N(0);
        for (int i = 1; i <= nD; ++i) {
            s.A.block((i - 1) * ny, 0, ny, ny) = -m.Dm[(size_t)i - 1];
            if (i < nD) s.A.block((i - 1) * ny, i * ny, ny, ny) = MatR::Identity(ny, ny);
            s.B.block((i - 1) * ny, 0, ny, nu) = N(i) - m.Dm[(size_t)i - 1] * N(0);
        }
    } else {
        // monic in the highest power: Dt = D_nD^{-1} D(s), Nt = D_nD^{-1} N(s)
        Eigen::PartialPivLU<MatR> lu(m.Dm[(size_t)nD - 1]);
        if (std::abs(m.Dm[(size_t)nD - 1].determinant()) < 1e-300)
            throw FitError("the leading denominator coefficient D_nD is singular: no realisation of this order");
        std::vector<MatR> Dt(nD + 1), Nt(nD + 1);
        for (int i = 0; i <= nD; ++i) {
            const MatR Di = i == 0 ? MatR::Identity(ny, ny) : m.Dm[(size_t)i - 1];
            Dt[(size_t)i] = lu.solve(Di);
            Nt[(size_t)i] = lu.solve(N(i));
        }
        // s^nD y = -sum_{i<nD} Dt_i s^i y + sum_j Nt_j s^j u
        s.D = Nt[(size_t)nD];
        for (int k = 0; k < nD; ++k) {
            const int i = nD - 1 - k;   // block row k holds coefficient of s^i
            s.A.block(k * ny, 0, ny, ny) = -Dt[(size_t)i];
            if (k + 1 < nD) s.A.block(k * ny, (k + 1) * ny, ny, ny) = MatR::Identity(ny, ny);
            s.B.block(k * ny, 0, ny, nu) = Nt[(size_t)i] - Dt[(size_t)i] * Nt[(size_t)nD];
        }
    }
    return s;
}

VecC ss_eigenvalues(const MatR &A0)
{
    if (A0.rows() == 0) return VecC();   // order 0 (Eigen's solver crashes on an empty matrix)
    MatR A = A0;
    const Eigen::Index n = A.rows();
    const double radix = 2.0, sqrdx = radix * radix;
    for (int sweep = 0; sweep < 100; ++sweep) {
        bool done = true;
        for (Eigen::Index i = 0; i < n; ++i) {
            double c = 0, r = 0;
            for (Eigen::Index j = 0; j < n; ++j)
                if (j != i) { c += std::abs(A(j, i)); r += std::abs(A(i, j)); }
            if (!(c > 0) || !(r > 0) || !std::isfinite(c + r)) continue;
            double g = r / radix, f = 1.0;
            const double s = c + r;
            while (c < g) { f *= radix; c *= sqrdx; }
            g = r * radix;
            while (c > g) { f /= radix; c /= sqrdx; }
            if ((c + r) / f < 0.95 * s) {
                done = false;
                A.row(i) /= f;
                A.col(i) *= f;
            }
        }
        if (done) break;
    }
    Eigen::EigenSolver<MatR> es(A, false);
    return es.eigenvalues();
}

bool ss_stable(const SSModel &m)
{
    if (m.A.rows() == 0) return true;
    const VecC ev = ss_eigenvalues(m.A);
    for (Eigen::Index k = 0; k < m.A.rows(); ++k) {
        const cd l = ev(k);
        if (m.domain == Domain::DT ? std::abs(l) >= 1.0 : l.real() >= 0.0) return false;
    }
    return true;
}

int ss_reflect_unstable(SSModel &m)
{
    if (m.A.rows() == 0) return 0;
    Eigen::EigenSolver<MatR> es(m.A, true);
    VecC lam = es.eigenvalues();
    MatC V = es.eigenvectors();
    int k = 0;
    for (Eigen::Index i = 0; i < lam.size(); ++i) {
        cd &l = lam(i);
        if (m.domain == Domain::DT && std::abs(l) >= 1.0) { l = 1.0 / std::conj(l); ++k; }
        if (m.domain == Domain::CT && l.real() >= 0.0) { l = cd(-std::abs(l.real()) - 1e-12, l.imag()); ++k; }
    }
    if (k) m.A = (V * lam.asDiagonal() * V.inverse()).real();
    return k;
}

// Discrete Lyapunov P = A P A^T + Q by Smith doubling (A stable).
static MatR dlyap(const MatR &A, const MatR &Q)
{
    MatR P = Q, Ak = A;
    for (int it = 0; it < 64; ++it) {
        const MatR dP = Ak * P * Ak.transpose();
        P += dP;
        Ak = Ak * Ak;
        if (dP.norm() <= 1e-16 * P.norm() || Ak.norm() < 1e-300) break;
    }
    return P;
}

static double h2norm(const SSModel &m)
{
    const Eigen::Index n = m.A.rows();
    if (m.domain == Domain::DT) {
        double d2 = m.D.squaredNorm();
        if (n == 0) return std::sqrt(d2);
        const MatR P = dlyap(m.A, m.B * m.B.transpose());
        return std::sqrt(std::max(0.0, (m.C * P * m.C.transpose()).trace() + d2));
    }
    if (m.D.norm() > 0) throw FitError("H2 of a continuous-time difference with a direct term is infinite");
    if (n == 0) return 0.0;
    // CT: A P + P A^T + B B^T = 0 via the Cayley map Ad = (I - A)^{-1}(I + A),
    // P = Ad P Ad^T + 2 (I - A)^{-1} B B^T (I - A)^{-T}
    const MatR I = MatR::Identity(n, n);
    Eigen::PartialPivLU<MatR> lu(I - m.A);
    const MatR Ad = lu.solve(I + m.A), Bd = lu.solve(m.B);
    const MatR P = dlyap(Ad, 2.0 * Bd * Bd.transpose());
    return std::sqrt(std::max(0.0, (m.C * P * m.C.transpose()).trace()));
}

static double smax(const MatC &G)
{
    Eigen::JacobiSVD<MatC> svd(G);
    return svd.singularValues()(0);
}

// Peak of sigma_max over a grid with golden-section refinement around the best points.
static double hinf(const SSModel &m, double wlo, double whi)
{
    const int N = 4000;
    auto point = [&](double w) { return m.domain == Domain::DT ? std::polar(1.0, w) : cd(0.0, w); };
    auto f = [&](double w) { return smax(ss_eval(m, point(w))); };
    std::vector<double> ws(N), vs(N);
    for (int k = 0; k < N; ++k) {
        ws[k] = m.domain == Domain::DT ? M_PI * k / (N - 1) : wlo * std::pow(whi / wlo, (double)k / (N - 1));
        vs[k] = f(ws[k]);
    }
    double best = *std::max_element(vs.begin(), vs.end());
    for (int k = 1; k + 1 < N; ++k) {
        if (vs[k] < vs[k - 1] || vs[k] < vs[k + 1] || vs[k] < 0.5 * best) continue;
        double a = ws[k - 1], b = ws[k + 1];
        const double gr = 0.6180339887498949;
        double c = b - gr * (b - a), d = a + gr * (b - a), fc = f(c), fd = f(d);
        for (int it = 0; it < 60; ++it) {
            if (fc > fd) { b = d; d = c; fd = fc; c = b - gr * (b - a); fc = f(c); }
            else { a = c; c = d; fc = fd; d = a + gr * (b - a); fd = f(d); }
        }
        best = std::max(best, std::max(fc, fd));
    }
    return best;
}

Distance ss_distance(const SSModel &a, const SSModel &b)
{
    if (a.domain != b.domain) throw FitError("cannot compare a discrete-time with a continuous-time model");
    if (a.B.cols() != b.B.cols() || a.C.rows() != b.C.rows())
        throw FitError("the models have different numbers of inputs or outputs");
    if (!ss_stable(a) || !ss_stable(b)) throw FitError("H2 and Hinf distances need stable models");
    SSModel d;
    d.domain = a.domain;
    d.h = a.h;
    const Eigen::Index na = a.A.rows(), nb = b.A.rows();
    d.A = MatR::Zero(na + nb, na + nb);
    d.A.topLeftCorner(na, na) = a.A;
    d.A.bottomRightCorner(nb, nb) = b.A;
    d.B = MatR(na + nb, a.B.cols());
    d.B << a.B, b.B;
    d.C = MatR(a.C.rows(), na + nb);
    d.C << a.C, -b.C;
    d.D = a.D - b.D;
    Distance r;
    r.h2_ref = h2norm(b);
    r.h2 = h2norm(d) / r.h2_ref;
    // CT grid: around the poles of both models
    double wlo = 1e-3, whi = 1e3;
    if (a.domain == Domain::CT) {
        double lo = 1e300, hi = 0;
        for (const SSModel *m : {&a, &b}) {
            if (m->A.rows() == 0) continue;
            Eigen::EigenSolver<MatR> es(m->A, false);
            for (Eigen::Index k = 0; k < m->A.rows(); ++k) {
                const double w = std::abs(es.eigenvalues()(k));
                if (w > 0) { lo = std::min(lo, w); hi = std::max(hi, w); }
            }
        }
        if (hi > 0) { wlo = lo * 1e-3; whi = hi * 1e3; }
    }
    r.hinf_ref = hinf(b, wlo, whi);
    r.hinf = hinf(d, wlo, whi) / r.hinf_ref;
    return r;
}

}  // namespace msidfit
