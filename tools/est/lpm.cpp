#include "lpm.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <thread>

namespace msidest {

long lpm_dof(unsigned W, unsigned R, unsigned nu, unsigned m, bool transient)
{
    return (long)m * (2L * W + 1) - (long)(R + 1) * (nu + (transient ? m : 0));
}

unsigned lpm_default_window(unsigned R, unsigned nu, unsigned ny, unsigned m)
{
    unsigned W = 1;
    while (lpm_dof(W, R, nu, m) < (long)ny + 4) ++W;
    return W;
}

namespace {

// The fixed part of the local design for one window position: the window covers
// bins k+o .. k+o+2W. With rho_t = (o+t)/W the T polynomial spans {rho^s}, s <= R;
// Qp (n x Le, orthonormal columns) spans its orthogonal complement (Part I: the
// transient is eliminated by projecting the window onto that complement, which
// leaves the G-coefficient estimates and the residuals of the full LS unchanged).
// Bt[t][s*Le + c] = Qp(t, c) rho_t^s: the projected regressor of r^s U(k+r).
struct WindowOp {
    unsigned Le = 0;            // projected rows per experiment
    std::vector<double> Bt;     // n x ((R+1) Le), row t contiguous
};

WindowOp window_op(int o, unsigned W, unsigned R, bool transient)
{
    const unsigned n = 2 * W + 1;
    WindowOp op;
    Eigen::MatrixXd Qp;
    std::vector<double> rho(n);
    for (unsigned t = 0; t < n; ++t) rho[t] = (double)(o + (int)t) / (double)W;
    if (transient) {
        Eigen::MatrixXd P(n, R + 1);
        for (unsigned t = 0; t < n; ++t)
            for (unsigned s = 0; s <= R; ++s) P(t, s) = std::pow(rho[t], (double)s);
        Eigen::HouseholderQR<Eigen::MatrixXd> qr(P);
        Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(n, n);
        Qp = Q.rightCols(n - (R + 1));
    } else {
        Qp = Eigen::MatrixXd::Identity(n, n);
    }
    op.Le = (unsigned)Qp.cols();
    const unsigned cols = (R + 1) * op.Le;
    op.Bt.assign((size_t)n * cols, 0.0);
    for (unsigned t = 0; t < n; ++t)
        for (unsigned s = 0; s <= R; ++s)
            for (unsigned c = 0; c < op.Le; ++c)
                op.Bt[(size_t)t * cols + s * op.Le + c] = Qp(t, c) * std::pow(rho[t], (double)s);
    return op;
}

struct Worker {
    const Spectra &S;
    const LpmConfig &cfg;
    const std::vector<WindowOp> &ops;
    LpmResult &res;
    size_t Kmax;
    std::vector<double> pfloor;  // per input: 1e-12 x (window rows) x its mean |U|^2 over the record
    size_t bad_bin = 0;          // first singular bin in this worker's range (0: none)

    void run(size_t i0, size_t i1)
    {
        const unsigned nu = S.nu, ny = S.ny, m = S.m, R = cfg.order, W = res.W;
        const unsigned n = 2 * W + 1, ng = nu * (R + 1), g = ny * nu;
        const unsigned Le = ops[0].Le, L = m * Le, cols = (R + 1) * Le;
        // Unknown a = (R - s) nu + j: the G(k) coefficients (s = 0) come last, so the
        // trailing nu x nu block of the Cholesky factor gives their covariance block.
        std::vector<double> xr((size_t)ng * L), xi((size_t)ng * L), yr((size_t)ny * L), yi((size_t)ny * L);
        std::vector<double> ar(cols), ai(cols);
        std::vector<cd> A((size_t)ng * ng), Lc((size_t)ng * ng), Z((size_t)ng * ny), Th((size_t)ny * ng);
        std::vector<cd> Cv((size_t)ny * ny), Li((size_t)nu * nu), M((size_t)nu * nu), Vres((size_t)ny * L);
        for (size_t bi = i0; bi < i1; ++bi) {
            const size_t k = res.bins[bi];
            const size_t w0 = std::min(std::max(k, (size_t)W + 1) - W, Kmax - 2 * W);
            const WindowOp &op = ops[(size_t)(w0 + 2 * W - k)];
            // project every regressor and output onto the complement of the T polynomials
            auto project = [&](const cd *X, unsigned ncols) {
                std::fill(ar.begin(), ar.begin() + ncols, 0.0);
                std::fill(ai.begin(), ai.begin() + ncols, 0.0);
                for (unsigned t = 0; t < n; ++t) {
                    const double ur = X[w0 + t].real(), ui = X[w0 + t].imag();
                    const double *b = &op.Bt[(size_t)t * cols];
                    for (unsigned r = 0; r < ncols; ++r) {
                        ar[r] += b[r] * ur;
                        ai[r] += b[r] * ui;
                    }
                }
            };
            for (unsigned e = 0; e < m; ++e) {
                for (unsigned j = 0; j < nu; ++j) {
                    project(S.U(e, j), cols);
                    for (unsigned s = 0; s <= R; ++s) {
                        const size_t row = (size_t)((R - s) * nu + j) * L + e * Le;
                        for (unsigned c = 0; c < Le; ++c) {
                            xr[row + c] = ar[s * Le + c];
                            xi[row + c] = ai[s * Le + c];
                        }
                    }
                }
                for (unsigned i = 0; i < ny; ++i) {
                    project(S.Y(e, i), Le);
                    for (unsigned c = 0; c < Le; ++c) {
                        yr[(size_t)i * L + e * Le + c] = ar[c];
                        yi[(size_t)i * L + e * Le + c] = ai[c];
                    }
                }
            }
            // normal matrix A = X X^H (lower triangle) and its Cholesky factor A = Lc Lc^H
            // sum_c p_c conj(q_c) over the L projected columns (split re/im rows)
            auto dotc = [L](const double *pr, const double *pi, const double *qr, const double *qi) {
                double sr = 0, si = 0;
                for (unsigned c = 0; c < L; ++c) {
                    sr += pr[c] * qr[c] + pi[c] * qi[c];
                    si += pi[c] * qr[c] - pr[c] * qi[c];
                }
                return cd(sr, si);
            };
            for (unsigned a = 0; a < ng; ++a)
                for (unsigned b = 0; b <= a; ++b)
                    A[(size_t)a * ng + b] = dotc(&xr[(size_t)a * L], &xi[(size_t)a * L], &xr[(size_t)b * L], &xi[(size_t)b * L]);
            bool singular = false;
            for (unsigned j = 0; j < ng && !singular; ++j) {
                double d = A[(size_t)j * ng + j].real();
                const double d0 = d;
                for (unsigned c = 0; c < j; ++c) d -= std::norm(Lc[(size_t)j * ng + c]);
                // a pivot below 1e-12 of its diagonal: this regressor lies in the span of the others
                // or an input with (almost) no power in this window against its level in the record
                if (!(d > 1e-12 * d0) || !(d0 > pfloor[j % nu])) { singular = true; break; }
                const double ljj = std::sqrt(d);
                Lc[(size_t)j * ng + j] = ljj;
                for (unsigned i = j + 1; i < ng; ++i) {
                    cd s = A[(size_t)i * ng + j];
                    for (unsigned c = 0; c < j; ++c) s -= Lc[(size_t)i * ng + c] * std::conj(Lc[(size_t)j * ng + c]);
                    Lc[(size_t)i * ng + j] = s / ljj;
                }
            }
            if (singular) {
                bad_bin = k;
                return;
            }
            // rhs X Y^H, forward then backward substitution: Th^H = A^-1 X Y^H
            for (unsigned i = 0; i < ny; ++i) {
                for (unsigned a = 0; a < ng; ++a) {
                    cd s = dotc(&xr[(size_t)a * L], &xi[(size_t)a * L], &yr[(size_t)i * L], &yi[(size_t)i * L]);
                    for (unsigned c = 0; c < a; ++c) s -= Lc[(size_t)a * ng + c] * Z[(size_t)c * ny + i];
                    Z[(size_t)a * ny + i] = s / Lc[(size_t)a * ng + a].real();
                }
                for (unsigned a = ng; a-- > 0;) {
                    cd s = Z[(size_t)a * ny + i];
                    for (unsigned c = a + 1; c < ng; ++c) s -= std::conj(Lc[(size_t)c * ng + a]) * Th[(size_t)i * ng + c];
                    Th[(size_t)i * ng + a] = s / Lc[(size_t)a * ng + a].real();   // still Th^H(a, i)
                }
                for (unsigned a = 0; a < ng; ++a) Th[(size_t)i * ng + a] = std::conj(Th[(size_t)i * ng + a]);
            }
            // residuals V = Y - Th X and C_v = V V^H / q
            for (unsigned i = 0; i < ny; ++i)
                for (unsigned c = 0; c < L; ++c) {
                    cd s(yr[(size_t)i * L + c], yi[(size_t)i * L + c]);
                    for (unsigned a = 0; a < ng; ++a)
                        s -= Th[(size_t)i * ng + a] * cd(xr[(size_t)a * L + c], xi[(size_t)a * L + c]);
                    Vres[(size_t)i * L + c] = s;
                }
            for (unsigned i = 0; i < ny; ++i)
                for (unsigned i2 = 0; i2 < ny; ++i2) {
                    cd s = 0;
                    for (unsigned c = 0; c < L; ++c) s += Vres[(size_t)i * L + c] * std::conj(Vres[(size_t)i2 * L + c]);
                    Cv[(size_t)i * ny + i2] = s / (double)res.q;
                }
            // M = (L22 L22^H)^-1, L22 the trailing nu x nu block: the G(k) block of A^-1
            const unsigned o = R * nu;
            std::fill(Li.begin(), Li.end(), cd(0));
            for (unsigned j = 0; j < nu; ++j) {
                Li[(size_t)j * nu + j] = 1.0 / Lc[(size_t)(o + j) * ng + o + j].real();
                for (unsigned i = j + 1; i < nu; ++i) {
                    cd s = 0;
                    for (unsigned c = j; c < i; ++c) s -= Lc[(size_t)(o + i) * ng + o + c] * Li[(size_t)c * nu + j];
                    Li[(size_t)i * nu + j] = s / Lc[(size_t)(o + i) * ng + o + i].real();
                }
            }
            for (unsigned a = 0; a < nu; ++a)
                for (unsigned b = 0; b < nu; ++b) {
                    cd s = 0;
                    for (unsigned c = 0; c < nu; ++c) s += std::conj(Li[(size_t)c * nu + a]) * Li[(size_t)c * nu + b];
                    M[(size_t)a * nu + b] = s;
                }
            cd *G = &res.G[bi * g], *C = &res.cov[bi * g * g], *N = &res.noise[bi * ny * ny];
            for (unsigned i = 0; i < ny; ++i)
                for (unsigned j = 0; j < nu; ++j) G[i * nu + j] = Th[(size_t)i * ng + o + j];
            std::copy(Cv.begin(), Cv.end(), N);
            // Cov[(i + ny j), (i2 + ny j2)] = C_v(i, i2) M(j2, j): M^T kron C_v in the column-stacked vec
            for (unsigned j = 0; j < nu; ++j)
                for (unsigned i = 0; i < ny; ++i)
                    for (unsigned j2 = 0; j2 < nu; ++j2)
                        for (unsigned i2 = 0; i2 < ny; ++i2)
                            C[(size_t)(i + ny * j) * g + i2 + ny * j2] = Cv[(size_t)i * ny + i2] * M[(size_t)j2 * nu + j];
        }
    }
};

}  // namespace

LpmResult lpm(const Spectra &s, const LpmConfig &c)
{
    const unsigned nu = s.nu, ny = s.ny, m = s.m, R = c.order;
    if (nu == 0 || ny == 0 || m == 0) throw EstError("no inputs, outputs or experiments");
    const unsigned W = c.window ? c.window : lpm_default_window(R, nu, ny, m);
    const long q = lpm_dof(W, R, nu, m, c.transient);
    if (q <= 0) {
        unsigned wmin = 1;
        while (lpm_dof(wmin, R, nu, m, c.transient) <= 0) ++wmin;
        char b[400];
        std::snprintf(b, sizeof b,
                      "window W = %u is too small for order R = %u: %u experiment(s) x (2W+1) = %u bins leave "
                      "q = %ld <= 0 noise degrees of freedom after the (R+1)(nu+m) = %u parameters; use --window %u "
                      "or more (or a lower --order)",
                      W, R, m, m * (2 * W + 1), q, (R + 1) * (nu + (c.transient ? m : 0)), wmin);
        throw EstError(b);
    }
    const size_t Kmax = s.N >= 3 ? (s.N - 1) / 2 : 0;   // last bin below Nyquist
    if (2 * (size_t)W + 1 > Kmax) {
        char b[300];
        std::snprintf(b, sizeof b,
                      "record too short for the window: %zu samples give %zu bins between DC and Nyquist, the "
                      "window needs 2W+1 = %u (W = %u); record at least %zu samples or use a smaller --window",
                      s.N, Kmax, 2 * W + 1, W, (size_t)(2 * W + 1) * 2 + 2);
        throw EstError(b);
    }
    const size_t k_lo = c.k_lo, k_hi = c.k_hi ? c.k_hi : Kmax;
    if (k_lo < 1 || k_hi > Kmax || k_lo > k_hi) {
        char b[200];
        std::snprintf(b, sizeof b, "band bins %zu..%zu outside the usable bins 1..%zu (DC and Nyquist excluded)", k_lo,
                      k_hi, Kmax);
        throw EstError(b);
    }
    LpmResult res;
    res.N = s.N;
    res.nu = nu;
    res.ny = ny;
    res.m = m;
    res.R = R;
    res.W = W;
    res.q = (unsigned)q;
    const size_t nb = k_hi - k_lo + 1, g = (size_t)ny * nu;
    res.bins.resize(nb);
    for (size_t i = 0; i < nb; ++i) res.bins[i] = k_lo + i;
    res.G.resize(nb * g);
    res.cov.resize(nb * g * g);
    res.noise.resize(nb * ny * ny);
    std::vector<WindowOp> ops;
    for (int o = -2 * (int)W; o <= 0; ++o) ops.push_back(window_op(o, W, R, c.transient));

    const unsigned T = std::max(1u, std::min<unsigned>(c.threads, (unsigned)((nb + 1023) / 1024)));
    std::vector<double> pfloor(nu, 0.0);
    for (unsigned j = 0; j < nu; ++j) {
        double p = 0;
        for (unsigned e = 0; e < m; ++e)
            for (size_t k = 1; k <= Kmax; ++k) p += std::norm(s.U(e, j)[k]);
        pfloor[j] = 1e-12 * (double)(m * ops[0].Le) * p / (double)(m * Kmax);
    }
    std::vector<Worker> wk(T, Worker{s, c, ops, res, Kmax, pfloor});
    std::vector<std::thread> th;
    for (unsigned t = 1; t < T; ++t) th.emplace_back([&, t] { wk[t].run(nb * t / T, nb * (t + 1) / T); });
    wk[0].run(0, nb / T);
    for (auto &x : th) x.join();
    for (const auto &w : wk)
        if (w.bad_bin) {
            char b[400];
            std::snprintf(b, sizeof b,
                          "the local input matrix is singular at bin %zu (%.6g cycles/sample): the inputs do not "
                          "excite the %u bins around it%s; restrict --band to where every input has power",
                          w.bad_bin, (double)w.bad_bin / s.N, 2 * W + 1,
                          nu > 1 ? " independently (inputs correlated or one missing)" : "");
            throw EstError(b);
        }
    return res;
}

}  // namespace msidest
