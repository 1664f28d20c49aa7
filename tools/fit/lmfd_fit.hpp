// LMFD estimators: the closed-form ML of González et al. 2025 Theorem 6 (fully
// and under-constrained), Sanathanan-Koerner initialisation, and the weighted
// maximum likelihood (eq. 40) by Levenberg-Marquardt with its covariance and
// the finite-sample bounds (45)-(46) of Theorem 5.
#pragma once
#include "frf_data.hpp"
#include "models.hpp"

namespace msidfit {

// One pinned coefficient: matrix ("D" i or "N" j), entry (row, col) 0-based, value.
struct Pin {
    char mat = 'N';
    int index = 0;
    int row = -1, col = -1;   // -1: every entry of the matrix
    double value = 0.0;
};
// Parse "N0=0", "D1[1,2]=0.5" (1-based entry indices). Throws FitError.
Pin parse_pin(const std::string &s);

struct LmfdSpec {
    int nD = 1, nN = 0;
    std::vector<Pin> pins;
    double wscale = 0.0;      // CT: p = s / wscale internally (0: geometric mean of line frequencies)
};

// Parameter names in the order of the parameter vector: per output row k,
// D_1[k,:], .., D_nD[k,:], N_0[k,:], .., N_nN[k,:] (vec of González's Theta^T).
std::vector<std::string> lmfd_param_names(const LmfdSpec &s, size_t ny, size_t nu);
VecR lmfd_pack(const LmfdModel &m);
LmfdModel lmfd_unpack(const VecR &th, const LmfdSpec &s, size_t ny, size_t nu, Domain d, double h);

struct ClosedForm {
    LmfdModel model;          // the chosen solution (minimum norm, after pins)
    MatR kernel;              // q x k real basis of the kernel of J (per output row), unscaled coordinates
    int equations = 0;        // real interpolation equations per output row
    int unknowns = 0;         // unknowns per output row
    bool unique = false;
};
// Theorem 6: all ML solutions Theta = J^+ G + K L; pins fix entries of Theta.
// Throws FitError if over-constrained (use ml), or pins are inconsistent.
ClosedForm lmfd_closed_form(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s);

struct MlOptions {
    int max_iter = 200;
    double tol = 1e-12;
    int sk_iter = 30;
    double beta = 0.8;        // Theorem 5 (46)
    double delta = 0.1;       // bound probability
    bool stable = false;      // refuse steps to unstable models (when the start is stable)
};

struct MlResult {
    LmfdModel model;
    VecR theta;               // free parameters (unscaled), names in `names`
    std::vector<std::string> names;
    MatR cov;                 // parameter covariance (inverse Fisher information, sample-ML corrected)
    double cov_factor = 1.0;  // the sample-ML factor applied
    double cost = 0.0;        // eq. (40) / negative log-likelihood (real lines weighted 1/2)
    double cost_expected = 0.0;
    double dof = 0.0;         // real residual dof (N_real - n_theta)
    int iterations = 0;
    bool converged = true;    // false: the iterations ran out; this is the best iterate
    double grad_norm = 0.0;   // |D^-1 J^T r|, D^2 = diag(J^T J) (scale free)
    int cov_rank = 0;         // rank of the Fisher information (pseudo-inverse when below the parameter count)
    std::vector<MatC> G;      // model FRF at the lines
    std::vector<MatC> Gcov;   // its covariance (J Cov J^H)
    double frf_bound = 0.0, theta_bound = 0.0, sigma_min_J = 0.0, lambda_max_cov = 0.0;
    int sigma_rank = 0;      // rank of the FRF Jacobian; sigma_min_J is its smallest non-zero singular value
    bool stable_constrained = false;   // stable asked and the start stable: every iterate is stable
    double cost_start = 0.0;  // eq. (40) of the start
};

// Sanathanan-Koerner starting point (weighted Levy then iterations).
LmfdModel lmfd_sk(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s, int iters,
                  const std::vector<MatC> *Gtarget = nullptr);

// Weighted ML from a start. When the iterations run out (or no descent step exists away from a
// stationary point) the best iterate comes back with converged = false; it is never thrown away.
MlResult lmfd_ml(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s, const LmfdModel &start,
                 const MlOptions &o, bool known_noise);

// Covariance, model FRF covariance and bounds of a given LMFD (e.g. the unique
// closed-form solution), as lmfd_ml reports them at its optimum.
MlResult lmfd_evaluate(const std::vector<WeightedLine> &w, Domain d, double h, const LmfdSpec &s, const LmfdModel &m,
                       const MlOptions &o, bool known_noise);

// Parameter covariance of eq. (40) from the whitened Jacobian J: 1/2 (J^T J)^+ in unit-scaled
// columns (a singular Fisher matrix at a good estimate is a rank-deficient parametrisation: the
// pseudo-inverse, eigenvalues below 1e-12 n lambda_max dropped), and its rank.
MatR fisher_cov(const MatR &J, int &rank);
// Smallest non-zero singular value of a column-graded J (unscaled LMFD coefficients) and its rank,
// without forming J^T J.
double sigma_min_graded(const MatR &J, int &rank);
// Sample-ML factor n/(n - ny - 1) for weights estimated with n complex dof (1 for known noise).
double sample_ml_factor(const std::vector<WeightedLine> &w, size_t ny, bool known_noise);

// Cost (40) of an LMFD on the weighted lines.
double weighted_cost_lmfd(const LmfdModel &m, const std::vector<WeightedLine> &w);

}  // namespace msidfit
