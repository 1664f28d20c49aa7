// Maximum-likelihood identification from multiple experiments with the initial
// conditions of every record eliminated analytically (variable projection),
// after Markovsky & Pintelon, "Identification of linear time-invariant systems
// from multiple experiments" (shared/papers/markovsky-pintelon-multiple-experiments.txt).
//
// Model class (discrete time, sample index t, q^-1 the delay): for every output j
// and record i of T_i samples,
//
//     y_j(t) = yhat_j(t) + v_j(t),   a(q^-1) yhat_j(t) = sum_k b_jk(q^-1) u_k(t),  t = 0..T_i-1,
//
// a(q^-1) = 1 + alpha_1 q^-1 + ... + alpha_n q^-n (the poles: roots of
// z^n + alpha_1 z^(n-1) + ... + alpha_n, shared by all outputs and records),
// b_jk(q^-1) = sum_{d=d0}^{n} beta_jkd q^-d (d0 = 0 with a direct term, else 1),
// and u_k(t < 0) = 0. The n pre-initial values yhat_j(-1..-n) of every record and
// output are free: they are the record's initial conditions. v is white Gaussian
// with variance s^2, independent across samples, outputs and records (the output
// error setup (OE) of §VI; inputs are taken as exact).
// With no inputs this is the sum-of-damped-exponentials model (SDE) of §VI:
// every channel of every record is a free combination of the same n modes z_k^t.
//
// Cost (ML', §IV): V(alpha) = sum_i || Pi_perp(alpha) y^i ||^2 after the linear
// parameters (beta, and each record's initial conditions) are eliminated by least
// squares; per record the initial conditions are projected out (cost linear in
// the number of records N), then beta by least squares on the projected data.
// alpha is found by Levenberg-Marquardt on V with Kaufman's variable-projection
// Jacobian J_m = -Pi_perp d yhat / d alpha_m (Golub & Pereyra 2003).
//
// Covariance: cov(alpha, beta) = s2 (J^T J)^-1 with J the Jacobian of the
// residual with respect to (alpha, beta) after the initial conditions are
// projected out: the inverse of the Fisher information of (alpha, beta) with the
// initial conditions as nuisance parameters (the Schur complement), s2 = V / dof,
// dof = sum_i ny T_i - N ny n - n - ny nu n_b. multi_crb() computes the same
// bound independently (finite differences of a plain simulator, full Fisher
// matrix over every parameter including all initial conditions, then inverted).
#pragma once
#include "fit_types.hpp"

#include <string>
#include <vector>

namespace msidfit {

// One record: T samples of nu inputs (T x nu, nu may be 0) and ny outputs (T x ny).
struct MultiRecord {
    MatR u, y;
};

struct MultiOptions {
    int order = 0;              // n, number of poles (>= 1)
    bool feedthrough = false;   // b_jk has a direct term beta_jk0 (input-output case only)
    int max_iter = 200;         // Levenberg-Marquardt iterations
    double h = 0.0;             // sample time in s for the modes (0: rad/sample)
    // false: initial conditions fixed at zero instead of eliminated (a WRONG model for
    // transient records, kept as the negative control of the tests and the benchmark)
    bool eliminate_ic = true;
    // start values: "auto" (every applicable start, LM from the one of least cost),
    // "kung" (autonomous only), "prony", "sm" (Steiglitz-McBride after Prony)
    std::string start = "auto";
    // coloured output noise (multi_noise.cpp): the AR polynomial c_1..c_p of c(q^-1) v = e, known
    VecR noise_ar;
    // > 0 with noise_ar empty: estimate AR(noise_ar_order) by Yule-Walker from the residuals of the
    // unweighted fit, refit weighted, re-estimate from the new residuals and refit (two-stage GLS)
    int noise_ar_order = 0;
};

// One pole (pair) with derived modal quantities and delta-method standard deviations.
struct MultiMode {
    cd z;                       // DT pole (Im >= 0 member of a pair)
    cd s;                       // CT pole ln(z) / h (rad/s; rad/sample when h = 0)
    bool real = false;
    double wn = 0, fn = 0, zeta = 0;          // |s|, |s| / 2 pi, -Re s / |s|
    double sd_wn = NAN, sd_fn = NAN, sd_zeta = NAN, sd_z_re = NAN, sd_z_im = NAN;
};

// One start value of the search. A start whose values or cost are not finite (the response of an
// unstable 1/a(q^-1) overflows over a long record) takes no part in the choice: failed says why, cost is NaN.
struct MultiStart {
    std::string name;
    double cost = 0.0;
    std::string failed;   // empty: a valid start
};

struct MultiResult {
    int n = 0, nu = 0, ny = 0, d0 = 1, nb = 0;   // nb taps per (j, k): d = d0..n
    VecR alpha;                       // alpha_1..alpha_n
    std::vector<MatR> beta;           // beta[d - d0]: ny x nu coefficient of q^-d
    std::vector<MatR> x0;             // per record: ny x n pre-initial values yhat(-1..-n)
    VecR theta;                       // (alpha, beta) stacked: alpha, then for j, k, d
    std::vector<std::string> names;   // of theta
    MatR cov;                         // covariance of theta (s2 (J^T J)^-1)
    int cov_rank = 0;
    double cost = 0.0;                // V = sum of squared residuals
    double s2 = 0.0;                  // noise variance V / dof
    double dof = 0.0;
    size_t n_samples = 0;             // sum_i T_i ny
    int iterations = 0;
    bool converged = false;
    double grad_norm = 0.0;
    std::vector<MultiStart> starts;
    std::string best_start;
    std::vector<MultiMode> modes;     // sorted by natural frequency
    VecR noise_ar;                    // the noise AR polynomial used (empty: white); s2 is then the innovations variance
    std::string noise_source = "white";   // "white", "given", "estimated from residuals"
    double logdet = 0.0;              // ny sum_i ln det Sigma_i of the normalised noise covariance
};

// Check the records (same channel counts, finite samples, enough samples for the
// order) and fit. Throws FitError with one message naming the problem.
MultiResult multi_fit(const std::vector<MultiRecord> &recs, const MultiOptions &o);

// The cost, linear parameters and covariance at a given alpha (no iterations).
MultiResult multi_evaluate(const std::vector<MultiRecord> &recs, const VecR &alpha, const MultiOptions &o);

// Starting values of alpha (exposed for the tests and the benchmark).
VecR multi_start_kung(const std::vector<MultiRecord> &recs, int n);        // stacked block Hankel SVD
VecR multi_start_prony(const std::vector<MultiRecord> &recs, int n, int d0);  // equation error (ARX) LS
// Steiglitz-McBride from a0; every iterate's poles outside the unit circle are reflected (stable prefilter)
VecR multi_start_sm(const std::vector<MultiRecord> &recs, int n, int d0, const VecR &a0, int iters);
// alpha with the poles outside the unit circle reflected to 1 / conj(z) (count: how many; may be nullptr)
VecR multi_reflect_unstable(const VecR &alpha, int *count);

// Poles, frequencies and damping of alpha with delta-method sd from cov_alpha
// (dz/dalpha_m = -z^(n-m) / p'(z), p(z) = z^n + alpha_1 z^(n-1) + ... + alpha_n).
std::vector<MultiMode> multi_modes(const VecR &alpha, const MatR &cov_alpha, double h);

// Simulate yhat of one record (T samples) from alpha, beta (as in MultiResult),
// the inputs u (T x nu; nu may be 0, T is u.rows()) and the pre-initial values x0 (ny x n).
MatR multi_simulate(const VecR &alpha, const std::vector<MatR> &beta, int d0, const MatR &u, const MatR &x0, int ny);

// Cramer-Rao bound of theta = (alpha, beta) for records with the given inputs and
// true pre-initial values, noise variance s2: the full Fisher matrix over theta and
// every record's initial conditions from central differences of multi_simulate(),
// inverted; the theta block is returned. noise_ar: AR noise with innovations variance s2. Independent of the estimator's projections.
MatR multi_crb(const VecR &alpha, const std::vector<MatR> &beta, int d0, const std::vector<MatR> &u,
               const std::vector<MatR> &x0, int ny, double s2, const VecR &noise_ar = VecR());

// Characteristic coefficients alpha_1..alpha_n of prod_k (1 - z_k q^-1) (complex poles in conjugate pairs).
VecR multi_alpha_from_poles(const std::vector<cd> &z);

// ---------------- coloured noise (multi_noise.cpp) ----------------
// Stationary AR(p) output noise c(q^-1) v(t) = e(t), c = 1 + c_1 q^-1 + ... + c_p q^-p, e white
// with variance s^2, the same polynomial for every output and record (outputs independent).
// The ML cost with a noise covariance s^2 Sigma_i per record is sum_i || W_i (y^i - yhat^i) ||^2 with
// Sigma_i^-1 = W_i^T W_i (the weighted 2-norm of the paper's ref. [10]; with the initial conditions
// and numerator still eliminated by least squares, now in the W-weighted norm). W_i is the exact
// innovations (Cholesky) factor of the Toeplitz covariance: Levinson-Durbin predictors of order
// t < p for the first p samples, c itself after, each scaled by its prediction error variance.
struct MultiNoise {
    VecR c;                   // c_1..c_p (empty: white noise, W = I)
    std::vector<VecR> pred;   // pred[k]: order-k predictor coefficients (length k), k = 0..p
    VecR P;                   // prediction error variances P_0..P_p of the normalised process (P_p = 1)
    bool white() const { return c.size() == 0; }
    // out = W x for one channel of T samples (out != x)
    void apply(const double *x, double *out, Eigen::Index T) const;
    // log det Sigma for T samples (sum_t ln P_min(t,p))
    double logdet(Eigen::Index T) const;
};

// The whitening factor of c (throws FitError when c(z) has roots on or outside the unit circle).
MultiNoise multi_noise_from_ar(const VecR &c);
// Autocovariance r(0..L) of the normalised AR model (innovations variance 1).
VecR multi_ar_autocov(const VecR &c, int L);
// Yule-Walker AR(p) from several zero-mean sequences (columns of the matrices; pooled biased
// autocovariance, Levinson-Durbin): noise-only records, or the residuals of a fit.
VecR multi_ar_yule_walker(const std::vector<MatR> &x, int p);

// ---------------- order selection (multi_order.cpp) ----------------
// -2 log L concentrated over s^2: S ln(V / S) + ny sum_i ln det Sigma_i, S = sum_i ny T_i.
// Free parameters k = n + ny nu nb + N ny n (the initial conditions of every record are
// parameters of the likelihood: they count, although they are eliminated analytically).
// AIC = -2 log L + 2 k, MDL (= BIC) = -2 log L + k ln S.
struct MultiOrderRow {
    int order = 0;
    bool ok = false;
    std::string error;
    bool converged = false;
    double cost = 0, s2 = 0, k = 0, m2logl = 0, aic = 0, mdl = 0;
};
struct MultiOrderSelection {
    std::vector<MultiOrderRow> rows;
    int chosen = -1;
    std::string rule;         // "mdl" or "aic"
    VecR hankel_sv;           // singular values of the stacked block Hankel matrix (descending)
    int hankel_gap_order = 0; // order of the largest ratio sv_k / sv_k+1 within the range
    MultiResult best;         // the fit at the chosen order
};
// Fit every order (o.order ignored) and pick the least criterion. count_ic = false drops the
// N ny n initial conditions from k: the WRONG count, kept as the negative control of the tests.
MultiOrderSelection multi_select_order(const std::vector<MultiRecord> &recs, const MultiOptions &o,
                                       const std::vector<int> &orders, const std::string &rule = "mdl",
                                       bool count_ic = true);
// Singular values of [H_1 ... H_N] (block Hankel of every record, Lr block rows), descending.
VecR multi_hankel_sv(const std::vector<MultiRecord> &recs, int Lr);

// ---------------- noisy inputs (errors-in-variables, multi_eiv.cpp) ----------------
// One output, white noise on the inputs and the output with a known ratio lambda = sigma_u / sigma_y:
// the true inputs and every record's initial conditions are eliminated (the distance of the data to
// the model's trajectories, e^T (A D^2 A^T)^-1 e with e the equation error, see multi_eiv.cpp);
// Levenberg-Marquardt over theta = (alpha, beta) from the output-error fit, finite-difference
// Jacobian; cov = s2 (J^T J)^-1 (Gauss-Newton), s2 = cost / (sum_i (T_i - n) - q) estimates sigma_y^2.
struct MultiEivResult {
    VecR alpha, theta, oe_theta;     // oe_theta: the output-error start (biased under input noise)
    std::vector<std::string> names;
    MatR cov;
    double cost = 0, s2 = 0, dof = 0, lambda = 0;
    int iterations = 0;
    bool converged = false;
};
MultiEivResult multi_fit_eiv(const std::vector<MultiRecord> &recs, const MultiOptions &o, double lambda);
// The cost at theta (for the tests: lambda = 0 gives the output-error cost of multi_evaluate).
double multi_eiv_cost(const std::vector<MultiRecord> &recs, const VecR &theta, int n, int d0, double lambda);

// ---------------- validation on records (multi_order.cpp) ----------------
// A fixed model (alpha, beta, noise AR c) on records: each record's initial conditions are
// re-estimated (they are not part of the model), the rest is fixed. Returns the whitened
// residuals and two tests: the cost against its law under the model (V / s2_model against
// chi2(dof) / dof ... F(dof, dof_model)), and whiteness (pooled residual autocorrelation at lags
// 1..m, Ljung-Box Q against chi2(m)).
struct MultiCheck {
    double cost = 0, dof = 0, s2 = 0;       // whitened cost, S - N ny n, cost / dof
    double f_stat = NAN, p_cost = NAN;      // (s2 / s2_model) against F(dof, dof_model), upper tail
    int lags = 0;
    VecR rho;                               // residual autocorrelation at lags 1..m
    double q_lb = 0, p_white = NAN;         // Ljung-Box statistic and its p-value
    std::vector<MatR> residuals;            // per record, whitened
};
MultiCheck multi_check(const std::vector<MultiRecord> &recs, const VecR &alpha, const std::vector<MatR> &beta, int d0,
                       const VecR &noise_c, double s2_model, double dof_model, int lags);

}  // namespace msidfit
