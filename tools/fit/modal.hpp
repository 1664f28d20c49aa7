// Modal parameters of a fitted model: natural frequency, damping ratio and
// residue (mode shape) of every pole pair, with standard deviations by the
// delta method from the parameter covariance the fit reports.
//
// Poles: eigenvalues lambda_k of A (CT) or mu_k (DT), mapped to CT by
// lambda_k = ln(mu_k) / h (h the sample time; rad/sample when h is unknown).
// Natural frequency w_k = |lambda_k| (rad/s), f_k = w_k / (2 pi) (Hz),
// damping ratio zeta_k = -Re(lambda_k) / |lambda_k|.
// Residues: with A = V diag(lambda) V^-1, R_k = (C v_k)(w_k^T B) (w_k^T the
// k-th row of V^-1), so G(x) = D + sum_k R_k / (x - x_k), x = s (CT) or z (DT).
// Standard deviations: sd(q) = sqrt(J Sigma_theta J^T), J = dq/dtheta by central
// differences of the eigen-decomposition with steps of 1e-2 sd(theta_i)
// (delta method, first order; Pintelon & Schoukens 2012 §7.2 on the
// variance of derived quantities).
#pragma once
#include "models.hpp"

#include <cmath>
#include <functional>

namespace msidfit {

struct Mode {
    cd pole;                 // pole in the model's own variable (s or z), Im >= 0 member of a pair
    cd pole_ct;              // CT pole (rad/s; rad/sample if the sample time is unknown)
    bool real = false;       // real pole (no pair)
    double wn = 0, fn = 0, zeta = 0;
    MatC residue;            // ny x nu, in the model's variable
    // standard deviations (NaN when no parameter covariance is available)
    double sd_wn = NAN, sd_fn = NAN, sd_zeta = NAN;
    MatR sd_residue_re, sd_residue_im;
};

// Poles and residues of a state-space model, sorted by natural frequency,
// pairs reported once (Im >= 0). h: sample time of a DT model (0: unknown).
// xscale: the model is in the scaled variable x / xscale (CT only): poles and
// residues are multiplied by xscale.
std::vector<Mode> modes_of(const SSModel &m, double h, double xscale = 1.0);

// Realisation of a CT LMFD in the scaled variable s / ws with ws = |det D_nD|^(-1/(ny nD))
// (the geometric mean of the pole magnitudes): well-conditioned companion eigenvalues.
// Returns the realisation and sets *ws (1 for DT, where z^-1 needs no scaling).
SSModel lmfd_realise_scaled(const LmfdModel &m, double *ws);

// Modes with standard deviations: `realise` maps the parameter vector to a
// state-space model, theta is the estimate, cov its covariance.
std::vector<Mode> modes_with_sd(const std::function<SSModel(const VecR &)> &realise, const VecR &theta,
                                const MatR &cov, double h, double xscale = 1.0);

}  // namespace msidfit
