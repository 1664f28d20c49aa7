// The direct time-domain least-squares FRF (González et al. 2025 eqs. 19-23,
// Theorem 2) for multisine records that are not whole periods (leakage) and
// for continuous-time multisines sampled slower than Nyquist.
#pragma once
#include "spectra.hpp"

#include <Eigen/Dense>

extern "C" {
#include "msid/msid.h"
}

namespace msidest {

using MatC = Eigen::MatrixXcd;
using MatR = Eigen::MatrixXd;

struct DirectRecord {
    const double *rows = nullptr;   // n x stride, outputs at columns y_col .. y_col+ny-1
    size_t n = 0;                   // samples; sample k is at period phase k mod P
    size_t stride = 0;
    size_t y_col = 0;
};

struct DirectLine {
    MatC G;           // ny x nu at +omega (conjugated back for folded CT lines)
    MatC cov;         // Cov vec(G) (Hermitian), exact finite-sample with Sigma replaced by its estimate
    MatC pcov;        // pseudo-covariance E[dv dv^T] (zero when records are whole periods)
};

struct DirectResult {
    std::vector<DirectLine> lines;
    MatR sigma;               // residual noise covariance per sample (ny x ny)
    double dof_real = 0.0;    // real residual dof: samples - regressors
    bool whole_periods = true;
    double cond = 0.0;        // condition number of the regressor matrix
};

// y_e(k) = sum_l Re{ G(l) c_{e,l} e^{j 2 pi b_l k / P} } + v(k): the input is the design's
// exact multisine (known input), one regressor pair (Re G, Im G) per line and input.
// Throws EstError for too few samples or a singular regression (naming the line).
DirectResult direct_frf(const msid_design &d, const msid_twiddle &tw, const std::vector<DirectRecord> &recs, size_t ny);

}  // namespace msidest
