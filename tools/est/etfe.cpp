#include "etfe.hpp"
#include "msid_cancel.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>

namespace msidest {

using MatC = Eigen::Matrix<cd, Eigen::Dynamic, Eigen::Dynamic>;

double max_input_norm(const std::vector<RecordView> &recs, unsigned nu)
{
    double d = 0;
    for (const auto &r : recs)
        for (size_t t = 0; t < r.n; ++t) {
            double s = 0;
            for (unsigned j = 0; j < nu; ++j) s += r.rows[t * r.stride + j] * r.rows[t * r.stride + j];
            d = std::max(d, std::sqrt(s));
        }
    return d;
}

void check_periodic_input(const std::vector<RecordView> &recs, unsigned nu, size_t M)
{
    char b[400];
    for (size_t e = 0; e < recs.size(); ++e) {
        const RecordView &r = recs[e];
        if (M < 2 || r.n % M != 0 || r.n / M < 2) {
            std::snprintf(b, sizeof b,
                          "experiment %zu has %zu samples: the ETFE needs a whole number Np >= 2 of input periods "
                          "of M = %zu samples (Tsiamis Assumption 3)",
                          e + 1, r.n, M);
            throw EstError(b);
        }
        double amp = 0;
        for (size_t t = 0; t < r.n; ++t)
            for (unsigned j = 0; j < nu; ++j) amp = std::max(amp, std::fabs(r.rows[t * r.stride + j]));
        for (size_t t = M; t < r.n; ++t)
            for (unsigned j = 0; j < nu; ++j) {
                const double dlt = std::fabs(r.rows[t * r.stride + j] - r.rows[(t - M) * r.stride + j]);
                if (dlt > 1e-9 * amp) {
                    std::snprintf(b, sizeof b,
                                  "experiment %zu: input u%u is not periodic with period %zu (sample %zu differs from "
                                  "sample %zu by %.3g); --method etfe needs a period-M input, use --method lpm for "
                                  "arbitrary inputs",
                                  e + 1, j + 1, M, t, t - M, dlt);
                    throw EstError(b);
                }
            }
    }
}

EtfeResult etfe(const Spectra &s, const EtfeConfig &c)
{
    const unsigned nu = s.nu, ny = s.ny, m = s.m;
    if (m < nu) {
        char b[200];
        std::snprintf(b, sizeof b, "%u input(s) need at least %u experiments for the ETFE (got %u)", nu, nu, m);
        throw EstError(b);
    }
    if (c.M < 2 || s.N % c.M || s.N / c.M < 2)
        throw EstError("the ETFE needs N = Np M samples with Np >= 2 whole input periods");
    EtfeResult r;
    r.N = s.N;
    r.M = c.M;
    r.Np = s.N / c.M;
    r.nu = nu;
    r.ny = ny;
    r.m = m;
    r.dof = m * (unsigned)(r.Np - 1);
    const size_t l_hi = c.l_hi ? c.l_hi : (c.M - 1) / 2;
    if (c.l_lo > l_hi || l_hi > (c.M - 1) / 2) throw EstError("ETFE lines outside 0..(M-1)/2");
    // T Theorem 1 proof (App. D with Lemma 4 / eq. (24)): P(||V|| > sqrt(tr Phi) + 2 s sqrt(tr Phi)) <=
    // 2 9^(2m) exp(-c s^2 tr Phi / ||Phi||), c = 1/144, K = sigma_e (Gaussian); union bound over M lines.
    r.log_term = std::log(2.0 * (double)c.M / c.delta) + m * std::log(81.0);
    const double noise_factor = std::sqrt((double)ny) + 24.0 * std::sqrt(r.log_term);
    const size_t Np = r.Np;
    for (size_t l = c.l_lo; l <= l_hi; ++l) {
        msidutil::checkpoint(msidutil::Step::lines, 1, "the ETFE");
        const size_t k = l * Np;
        MatC U(nu, m), Y(ny, m), Phi = MatC::Zero(ny, ny);
        for (unsigned e = 0; e < m; ++e) {
            for (unsigned j = 0; j < nu; ++j) U(j, e) = s.U(e, j)[k];
            for (unsigned i = 0; i < ny; ++i) Y(i, e) = s.Y(e, i)[k];
            // the Np - 1 non-excited bins nearest to k (mirrored at DC / Nyquist)
            for (size_t d = 1; d < Np; ++d) {
                long kk = (long)k + (l == 0 ? (long)d : (long)d - (long)(Np / 2));
                if (kk <= (long)k && l > 0) --kk;   // skip k itself
                if (kk < 0) kk = -kk;
                if (kk > (long)(s.N / 2)) kk = (long)s.N - kk;
                Eigen::Matrix<cd, Eigen::Dynamic, 1> y(ny);
                for (unsigned i = 0; i < ny; ++i) y(i) = s.Y(e, i)[kk];
                Phi += y * y.adjoint();
            }
        }
        Phi /= (double)r.dof;
        Eigen::JacobiSVD<MatC> svd(U);
        const double smin = svd.singularValues()(nu - 1);
        if (!(smin > 1e-12 * svd.singularValues()(0))) {
            char b[200];
            std::snprintf(b, sizeof b, "the inputs do not excite line %zu (bin %zu): U U^H is singular", l, k);
            throw EstError(b);
        }
        const MatC Minv = (U * U.adjoint()).inverse();
        const MatC G = Y * U.adjoint() * Minv;
        r.lines.push_back(l);
        r.bins.push_back(k);
        for (unsigned i = 0; i < ny; ++i)
            for (unsigned j = 0; j < nu; ++j) r.G.push_back(G(i, j));
        for (unsigned j = 0; j < nu; ++j)
            for (unsigned i = 0; i < ny; ++i)
                for (unsigned j2 = 0; j2 < nu; ++j2)
                    for (unsigned i2 = 0; i2 < ny; ++i2) r.cov.push_back(Phi(i, i2) * Minv(j2, j));
        for (unsigned i = 0; i < ny; ++i)
            for (unsigned i2 = 0; i2 < ny; ++i2) r.noise.push_back(Phi(i, i2));
        const double phi_op = Eigen::SelfAdjointEigenSolver<MatC>(Phi, Eigen::EigenvaluesOnly).eigenvalues().maxCoeff();
        // eq. (12) with the unscaled DFT: ||U^+|| (||V|| + ||T||), ||V|| <= sqrt(||Phi||) noise_factor (eq. 25),
        // ||T|| <= sqrt(m) 2 ||G||_* D_u (Lemma 2 per experiment, times sqrt(m) for the stacked columns)
        const double bn = std::sqrt(std::max(phi_op, 0.0)) * noise_factor / smin;
        const double bt = 2.0 * std::sqrt((double)m) * c.gstar * c.du_max / smin;
        r.bound_noise.push_back(bn);
        r.bound_transient.push_back(bt);
        r.bound.push_back(bn + bt);
    }
    return r;
}

}  // namespace msidest
