// Discrete-cISSIM: combined invariant-subspace and frequency-domain subspace
// identification of DT state-space models from periodic time records
// (You, Huang, Zhang 2023, "discrete-cISSIM"; equation and algorithm numbers
// below are the paper's). docs/fitting.md, section "cissim".
//
// Data flow: whole periods of [u; y] samples -> invariant-subspace regression
// (ISP, Alg. 1 / 3) -> phasors Y^i, U^i at the chosen lines -> A, C, n by
// QR + SVD (Alg. 4) -> B, D by the Sylvester regression (Alg. 5). With the full
// frequency set the residuals give the noise correlations (Alg. 6) and the
// covariances Sigma_ww, Sigma_vv, Sigma_tt (ALS with the PSD constraints of
// (36), Alg. 7; cissim_cov.cpp).
#pragma once
#include "models.hpp"

#include <cstdint>
#include <string>
#include <vector>

namespace msidfit {

// How the ISP regression (25) is evaluated.
enum class IspMethod {
    Auto,     // Direct for few lines, FFT for many (cissim_isp_auto_direct)
    Direct,   // Alg. 1: sum of the periods, then one multiplication per line, O(N + q T)
    Fft       // Alg. 3: sum of the periods, then one FFT of length T, O(N + T log T)
};

// One experiment's ISP estimate R^i (eq. 25) at the lines, as complex phasors:
// P_r = (2 / (K T)) sum_k z_k exp(-j theta_r k), theta_r = 2 pi bin_r / T, so that
// the paper's sine / cosine coefficients are a_r = -Im P_r, b_r = Re P_r
// (v_k = [1/sqrt 2, sin(k theta), cos(k theta), ...], eq. 7 with phi = 0) and the
// DC coefficient is P_0 / sqrt 2. Time index k = 0 at the first sample used.
struct IspResult {
    uint32_t period = 0;
    std::vector<uint32_t> bins;   // the lines F^i, bins in [0, T/2)
    MatC Y, U;                    // ny x q and nu x q phasors
    uint64_t periods = 0;         // K whole periods used
    bool used_fft = false;
    MatR noise;                   // ny x ny output noise covariance per sample (period-to-period
                                  // variation, K >= 2; empty otherwise): the weighting of Alg. 4
    // With line_cov (cissim_isp(.., line_cov = true), K >= 2): per line the (nu + ny) x (nu + ny)
    // sample covariance of the mean phasor [U; Y] over the K periods, S_l / K with
    // S_l = sum_p (P_p - P)(P_p - P)^H / (K - 1) (the FRF step's estimate, K - 1 complex dof).
    std::vector<MatC> line_cov;
};

// rows: n_rows x (nu + ny), row-major [u_1..u_nu, y_1..y_ny] (the msid record layout).
// Uses periods skip .. floor(n_rows / T) - 1. Throws FitError when fewer than
// one whole period remains or a bin is out of [0, T/2).
// cov_bins (with line_cov): only these of `bins` get a line_cov entry (the others stay empty, 0 x 0),
// as the ML refinement uses the excited lines alone of a full-set regression.
IspResult cissim_isp(const double *rows, size_t n_rows, uint32_t nu, uint32_t ny, uint32_t period,
                     const std::vector<uint32_t> &bins, uint32_t skip_periods, IspMethod method = IspMethod::Auto,
                     bool line_cov = false, const std::vector<uint32_t> *cov_bins = nullptr);
// The Auto rule: direct multiplication when q (nu + ny) T < 4 T log2 T (nu + ny), i.e. q < 4 log2 T.
bool cissim_isp_auto_direct(size_t q, uint32_t period);
// The paper's real ISP matrix R^i (s x (nu + ny), columns in record order [u, y], rows [dc/sqrt2 |
// sin | cos ...] per line, eq. 25) from the phasors: the layout of the online Algorithm 2 (lib/msid_cissim).
MatR cissim_isp_real(const IspResult &r);

struct CissimOptions {
    int order = 0;        // n; 0: estimate from the singular values of R22 (Alg. 4 step 5, Remark 3)
    int block_rows = 0;   // nbar (Assumption 3); 0: 2n with --order (at least n + 1 for one output), else max_order + 1
    int max_order = 10;   // upper bound when the order is estimated
    bool estimate_D = true;
    // Whiten R22 by the covariance of the output-noise phasors in the stacked block rows,
    // sum_r Re(v_r v_r^H) kron Sigma_v with v_r = [1, z_r, .., z_r^(nbar-1)] (McKelvey et al. 1996).
    // The published Alg. 4 (false) takes it as a multiple of I, true for the full set of lines but
    // not for a reduced set in a band, where it biases A and C for a finite record.
    bool weighted = true;
    // Assumption 1 (A Schur): reflect poles of A-hat outside the unit circle into it (1/conj p) before
    // Alg. 5, as `subspace --stable`. A spurious unstable pole outside the band is otherwise possible.
    bool stable = true;
};

struct CissimResult {
    SSModel model;
    int order = 0, block_rows = 0;
    bool order_estimated = false;
    std::vector<double> sv;       // singular values of R22 (Alg. 4 step 4)
    size_t lines = 0;             // q per experiment
    size_t real_columns = 0;      // columns of the stacked real ISP matrices (all experiments)
    int reflected = 0;            // poles reflected into the unit circle (options.stable)
};

// Alg. 4 + 5 on the ISP results of one or more experiments (same period and lines).
// Throws FitError when the lines do not identify the order (eq. 31: q >= nu (n + nbar)
// summed over the experiments, and a full-rank input block) or the order is too high.
CissimResult cissim_fit(const std::vector<IspResult> &isp, const CissimOptions &o);

// Alg. 5 alone: B and D from A, C and the phasors (real least squares).
void cissim_BD(SSModel &m, const std::vector<IspResult> &isp, bool estimate_D);

// ---- ML refinement and uncertainty (cissim_ml.cpp; not in the paper) ----
// Weighted output error on the ISP phasors, started from the cissim model:
//   V(theta) = sum_e sum_l e_l^H W_l^-1 e_l,  e_l = Y_l - G(z_l, theta) U_l,  G = C (zI - A)^-1 B + D,
//   W_l = [-G_l  I] S_l [-G_l  I]^H  (S_l: line_cov of the ISP, input noise included, at the start G),
// minimised by Levenberg-Marquardt over all entries of (A, B, C, D) (the similarity freedom is left to
// the damping: the FRF and its covariance do not depend on it). At the minimum V is the negative log
// likelihood of the phasors (Gaussian, weights from the periods), so the estimate is the (sample) ML one.
struct CissimMlOptions {
    int max_iter = 100;
    double tol = 1e-10;     // relative cost decrease that stops the iterations
    int reweight = 1;       // times W_l is recomputed at the refined G and the iterations rerun
};
struct CissimMlResult {
    SSModel model;
    int iterations = 0;
    bool converged = false;
    double cost_start = 0, cost = 0;   // V at the cissim start and at the end (real DC terms weighted 1/2)
    double dof = 0;                    // real residual dof: real equations - rank of the Fisher information
    MatR cov;                          // covariance of vec [A; B; C; D] entries (pseudo-inverse: n^2 gauge directions)
    int cov_rank = 0;
    double cov_factor = 1;             // sample-ML factor n / (n - ny - 1) for weights with n = K - 1 dof;
                                       // infinite when K - 1 <= ny + 1: cov, Gcov are then not an uncertainty
    std::vector<uint32_t> bins;        // lines of G, Gcov
    std::vector<MatC> G;               // model FRF at the lines
    std::vector<MatR> Gcov;            // 2 ny nu x 2 ny nu real covariance of [Re vec G; Im vec G] per line
};
// G(z) = C (z I - A)^-1 B + D by a small LU: ss_eval's value to rounding, for the hundreds of lines of
// a cissim fit (ss_eval keeps Eigen's LU: other methods' model files are compared bit for bit).
MatC cissim_eval(const SSModel &m, cd z);
// Throws FitError when an experiment has no line_cov (K < 2 or cissim_isp(.., line_cov = false)).
CissimMlResult cissim_refine(const SSModel &start, const std::vector<IspResult> &isp, const CissimMlOptions &o = {});
// The FRF covariance (2 ny nu x 2 ny nu, [Re vec G; Im vec G]) at z of a model whose entries
// vec [A; B; C; D] (column-major per matrix, in that order) have covariance `cov`.
MatR cissim_frf_cov(const SSModel &m, const MatR &cov, cd z);

// ---- noise covariance (section 4.3, cissim_cov.cpp) ----

// Residual correlations Xi_rr^l (l = 0..M-1, ny x ny) and Xi_tt (nu x nu) of the residuals of
// the full frequency set (Assumption 6): r_k = y_k - (periodic part), tau_k = u_k - (periodic part).
struct Correlations {
    std::vector<MatR> Xi_rr;   // Xi_rr[l], eq. (32)
    MatR Xi_tt;                // eq. (33)
    uint64_t n = 0;            // samples N = K T used
    uint64_t periods = 0;
};

// How the correlations are computed: Alg. 6 in the frequency domain (the periodic part is the DFT
// bins at multiples of K; correlations by FFTs of length >= N + M, zero padded, so that they equal
// (32)-(33) exactly, not only asymptotically as with the paper's length-N circular correlation), or
// (32)-(33) directly (M ny^2 dot products of length ~N). Both give the same numbers to rounding;
// Auto takes the one with fewer operations (cissim_correlations_direct): direct for a few lags and
// outputs (the default M <= 50), where it also spares the planning of a long transform.
enum class CorrMethod { Auto, Direct, Fft };
bool cissim_correlations_direct(int M, uint32_t nu, uint32_t ny, uint64_t N);
// The residuals are every sample minus the mean of its phase over the K periods (Assumption 6).
Correlations cissim_correlations(const double *rows, size_t n_rows, uint32_t nu, uint32_t ny, uint32_t period,
                                 uint32_t skip_periods, int M, CorrMethod method = CorrMethod::Auto);
// The same from the time-domain definitions (32)-(33), O(M N): the reference of the tests.
Correlations cissim_correlations_time(const double *rows, size_t n_rows, uint32_t nu, uint32_t ny, uint32_t period,
                                      uint32_t skip_periods, int M);

struct NoiseCov {
    MatR Sigma_ww, Sigma_vv, Sigma_tt, Xi_zz;
    int lags = 0;                // M
    bool detectable = true;      // Assumption 7 (A non-singular, C full column rank)
    std::string note;            // why the solution is nominal, when it is
    std::string solver;          // "interior point", or "ADMM" without a strictly feasible start
    int iterations = 0;          // Newton steps (interior point) or ADMM iterations
    double duality_gap = -1;     // interior point: the bound m / t on the cost above its minimum (-1: ADMM)
    double primal_residual = 0;  // max constraint violation left (Frobenius; 0 for the interior point)
    double fit_residual = 0;     // || M vec Xi_zz - p || / || p ||
};

// Algorithm 7: Xi_zz by least squares (35) under the PSD constraints of (36), solved by a primal
// log-barrier interior-point method (ADMM when no strictly feasible start exists), then Sigma_ww = Xi - A Xi A^T, Sigma_vv = Xi_rr^0 - C Xi C^T, Sigma_tt = Xi_tt.
// The residual correlations are scaled by K / (K - 1) first (the periodic-mean projection removes
// one period's worth of noise degrees of freedom; exact for white noise at lag 0).
NoiseCov cissim_noise_cov(const SSModel &m, const Correlations &c);

// ADMM for  min ||F x - g||^2  s.t.  mat(G_i x + h_i) PSD (d_i x d_i), i = 1..k, x real.
// G_i: (d_i^2 x dim x), h_i: d_i^2 (column-major vec). Returns x; iterations and the residual.
struct LmiLs {
    MatR F;
    VecR g;
    std::vector<MatR> G;
    std::vector<VecR> h;
};
VecR lmi_least_squares(const LmiLs &p, int &iterations, double &primal_residual, int max_iter = 5000, double tol = 1e-10);
// The same problem by a primal log-barrier method: Newton steps on t ||F x - g||^2 - sum_i log det
// mat(G_i x + h_i) along t = t0, 10 t0, ... until the bound m / t (m = sum d_i) on the cost above its
// minimum is below tol ||g||^2. x: a strictly feasible start on entry, the solution on return; false
// (x unusable) when the start is not strictly feasible or a Newton system fails. A few dozen Newton
// steps of a small dense system where ADMM creeps towards a minimiser on the boundary of the cone
// (no process noise: Xi_zz = 0) for thousands of iterations.
bool lmi_least_squares_barrier(const LmiLs &p, VecR &x, int &steps, double &gap, double tol = 1e-12);

// Relative H2 / Hinf errors are msidfit::ss_distance (models.hpp).

}  // namespace msidfit
