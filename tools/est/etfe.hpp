// The empirical transfer function estimate (ETFE) for period-M inputs with the
// finite-sample error bound of Tsiamis, Abdalmoaty, Hjalmarsson, Pappas,
// "Finite-sample analysis of the empirical transfer function estimate" (2024):
// T eq. (5) for the estimate, Theorem 1 / eq. (12) for the bound, with the
// explicit constants of its proof (Hanson-Wright with c = 1/144, a 1/4-net of
// 9^(2m) points, union bound over the M lines; Appendix B and D).
//
// Record: m >= nu experiments of N = Np M samples whose inputs repeat with period
// M (T Assumption 3). At k = l Np the DFTs give Ghat = Y U^H (U U^H)^-1 (= Y U^-1
// for m = nu). Between the lines the input DFT is zero (T Lemma 3), so the
// Np - 1 bins around each line hold only noise (and transient): they give the
// noise spectrum Phihat (m (Np - 1) complex dof) used both for the usual
// covariance M^T kron Phihat and, plugged in for Phi_v,N, in the bound.
#pragma once
#include "spectra.hpp"

namespace msidest {

struct EtfeConfig {
    size_t M = 0;              // input period (samples); N must be a multiple, Np = N/M >= 2
    double delta = 0.05;       // failure probability of the bound, jointly over all M lines
    double gstar = 0.0;        // ||G||_* = sum_t t ||g_t|| (T eq. 7); 0: transient term left out
    double du_max = 0.0;       // D_u = max_t ||u_t||_2 (T Assumption 2); see max_input_norm()
    size_t l_lo = 1, l_hi = 0; // lines l (frequency l/M) to estimate; l_hi = 0: floor((M-1)/2)
};

struct EtfeResult {
    size_t N = 0, M = 0, Np = 0;
    unsigned nu = 0, ny = 0, m = 0, dof = 0;   // dof = m (Np - 1)
    std::vector<size_t> lines, bins;           // l and k = l Np
    std::vector<cd> G, cov, noise;             // as LpmResult (noise: Phihat, unscaled DFT)
    std::vector<double> bound;                 // eq. (12): bound on ||Ghat - G||_op (2-norm)
    std::vector<double> bound_noise, bound_transient;   // its two terms
    double log_term = 0;                       // log(2 * 81^m * M / delta)
};

// Max over samples and experiments of the input 2-norm ||u_t||_2.
double max_input_norm(const std::vector<RecordView> &recs, unsigned nu);
// Throws EstError unless every input repeats with period M (tolerance 1e-9 max|u|) and M divides N.
void check_periodic_input(const std::vector<RecordView> &recs, unsigned nu, size_t M);

EtfeResult etfe(const Spectra &s, const EtfeConfig &c);

}  // namespace msidest
