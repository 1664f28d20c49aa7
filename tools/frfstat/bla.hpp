// Best linear approximation and nonlinear distortion from several realisations
// of a random-phase multisine: the robust method of Pintelon & Schoukens,
// System Identification: A Frequency Domain Approach, 2nd ed. (2012), §4.3.1,
// also Schoukens, Vaes & Pintelon, IEEE Control Systems 36(3), 2016, "Linear
// system identification in a nonlinear setting", sidebar on the robust method.
//
// R realisations (experiments that differ only in the random phases), each
// with several periods, give FRFs G^[r] and their period-to-period (noise)
// covariances C^[r] (complex dof n_r). Per line, with g^[r] = vec G^[r]:
//   G_BLA            = 1/R sum_r G^[r]                                   (BLA, mean over realisations)
//   C_BLA  (total)   = 1/(R(R-1)) sum_r (g^[r] - g_BLA)(g^[r] - g_BLA)^H  (noise + stochastic NL; dof R - 1)
//   C_BLA,n (noise)  = 1/R^2 sum_r C^[r]                                 (noise only; dof sum_r n_r)
//   var_BLA,NL       = diag(C_BLA - C_BLA,n)                              (NL distortion variance of G_BLA)
//   var_s            = R var_BLA,NL                                       (of one realisation's FRF: sigma^2_Gs)
// Under "no nonlinear distortion" (and Gaussian noise of equal level in every
// realisation) each diagonal entry of C_BLA / C_BLA,n is F(2(R-1), 2 sum n_r)
// distributed (independent numerator and denominator); its tail is the
// per-entry p-value. Over all lines and entries the p-values combine by
// Fisher's method, -2 sum ln p ~ chi2(2N) without distortion: the global p-value.
#pragma once
#include <Eigen/Dense>

#include <cmath>
#include <complex>
#include <vector>

namespace msidstat {

using MatC = Eigen::MatrixXcd;
using VecR = Eigen::VectorXd;

struct BlaLine {
    MatC G;                 // ny x nu
    MatC cov;               // total covariance of vec G_BLA (g x g)
    double dof = 0;         // R - 1
    MatC cov_noise;         // noise covariance of vec G_BLA
    double dof_noise = 0;   // sum_r n_r
    VecR var_nl;            // diag(cov - cov_noise): may be negative (unbiased, not clipped)
    VecR var_s;             // R var_nl: one realisation's stochastic NL variance
    VecR p_value;           // per entry, F test of "no distortion"
};

// G_BLA, C_BLA (total) and dof = R - 1 of one line from the realisations' FRFs G[r] (ny x nu) alone,
// R >= 2: all that one period per realisation allows (no noise part: cov_noise, var_nl, var_s and
// p_value are left empty). Without the periods' noise the realisation FRFs are still independent
// with one covariance (noise + stochastic distortion), so C_BLA is unbiased for cov(vec G_BLA) and,
// for circular complex Gaussian G^[r], |G_BLA,ij - G_BLA,ij^true|^2 / C_BLA,ii ~ F(2, 2(R - 1)).
BlaLine bla_total(const std::vector<MatC> &G);

// G[r] (ny x nu), cov[r] (g x g) and dof[r] of one line over R >= 2 realisations.
BlaLine bla_line(const std::vector<MatC> &G, const std::vector<MatC> &cov, const std::vector<double> &dof);

// Level of the global test: 0.1%. The per-entry laws are exact for SISO with exact
// inputs; with MIMO (Satterthwaite dof) and noisy inputs they are approximate, and
// Fisher's combination over many entries turns a small miscalibration into false
// alarms at 1% (seen on 2x2 benches), so the decision is conservative.
constexpr double BLA_DETECT_ALPHA = 1e-3;

struct BlaSummary {
    int entries = 0, significant = 0;     // line entries tested, and those with p < 1%
    double p_value = 1.0;                 // Fisher's combination of the entries' p-values
    bool detected = false;                // p_value < BLA_DETECT_ALPHA
    double nl_to_noise_db = NAN;          // 10 log10(sum var_nl / sum diag cov_noise), NaN if sum var_nl <= 0
};
// Fisher's combination P(chi2(2N) > -2 sum ln p_i) of the finite p-values
// (N of them, `significant` below 1%).
double fisher_combined(const std::vector<double> &p, int *n = nullptr, int *significant = nullptr);
BlaSummary bla_summary(const std::vector<BlaLine> &lines);

}  // namespace msidstat
