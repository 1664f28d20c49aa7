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

// A mode is "identified" when the Wald test of its contribution to the FRF over the fitted lines rejects
// "no contribution" at this level (docs/fitting.md, "Modes the data do not identify"). Small, because a
// pole pair spent on noise sits where the noise helps most: the maximum over pole positions inflates W
// over its chi2 law under "no mode" (Davies' problem), so the nominal level is not the false-alarm rate.
constexpr double MODE_IDENTIFIED_P = 1e-3;

struct Mode {
    cd pole;                 // pole in the model's own variable (s or z), Im >= 0 member of a pair
    cd pole_ct;              // CT pole (rad/s; rad/sample if the sample time is unknown)
    bool real = false;       // real pole (no pair)
    double wn = 0, fn = 0, zeta = 0;
    MatC residue;            // ny x nu, in the model's variable
    // standard deviations (NaN when no parameter covariance is available)
    double sd_wn = NAN, sd_fn = NAN, sd_zeta = NAN;
    MatR sd_residue_re, sd_residue_im;
    // Wald test of "the mode contributes nothing to the FRF at the fitted lines": c the contribution
    // R/(x - p) (+ conj for a pair) at every line, stacked [Re; Im]; W = c^T S_c^+ c, S_c its
    // delta-method covariance, dof = rank S_c, p = P(chi2(dof) > W). For two neighbouring real poles
    // also their sum (a pair split into two real poles whose residues cancel): `with` is the index of
    // the neighbour whose joint test is the weaker, -1 if none. NaN without covariance or lines.
    double contrib_chi2 = NAN, contrib_p = NAN;
    int contrib_dof = 0, contrib_with = -1;
    // the pole lies on the stability bound of a constrained fit (stab_bound.hpp): its damping is the
    // constraint's, not an estimate, so sd_zeta is NaN (the delta method has no law at a bound)
    bool at_bound = false;
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
// xs: the fitted lines in the model's variable (s = j w, z = e^{j w h}) for the contribution tests
// (empty: none).
std::vector<Mode> modes_with_sd(const std::function<SSModel(const VecR &)> &realise, const VecR &theta,
                                const MatR &cov, double h, double xscale = 1.0, const std::vector<cd> &xs = {});

}  // namespace msidfit
