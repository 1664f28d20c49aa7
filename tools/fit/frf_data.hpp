// Weighting msid-frf/1 data for the fits (the file is read by tools/frffile).
#pragma once
#include "fit_types.hpp"

namespace msidfit {

// Read and validate (format, shapes, finiteness). Throws FitError naming the
// file and the offending entry. The one reader of the format.
using msidfrf::read_frf;

// Which covariance weights a fit.
enum class Weight { Cov, KnownInput, None };

struct WeightedLine {
    cd x;                     // frequency variable
    bool real;
    MatC G;                   // ny x nu
    MatC Linv;                // inverse Cholesky factor of the covariance (g x g), or identity
    MatC cov;                 // the covariance used (g x g)
    double dof;               // complex dof governing the inverse moments of the weights (1e9: known)
};

// Prepare weights: Cholesky of each line's covariance; throws FitError naming
// the line if a covariance is missing, not finite or not positive definite.
// noise_var > 0 replaces the estimated noise by a known time-domain variance
// (per output, white), keeping the design structure of cov_known_input.
std::vector<WeightedLine> weigh(const FrfData &f, Domain d, Weight w, double noise_var = 0.0);

// Weights with less variance for ml: each complex line's covariance replaced by the dof-weighted mean
// of the per-line covariances over a window of 2 half + 1 neighbouring complex lines (shifted at the
// band edges), its dof by their sum. Right when the noise covariance of the FRF is smooth over the
// window (output noise, smooth excitation amplitude); a neighbour whose covariance trace differs from
// the line's beyond the central 99% of F(2n, 2n) is left out. Real lines and half = 0: unchanged.
void smooth_weights(std::vector<WeightedLine> &w, int half);
// ml's default half-width H (`msid fit --weight-smooth`; docs/fitting.md, "Pooled weights").
constexpr int ML_WEIGHT_SMOOTH = 4;
// Without --weight-smooth, ml pools only when the file has at least this many windows of 2H+1 lines.
constexpr int ML_WEIGHT_SMOOTH_MIN_WINDOWS = 4;

}  // namespace msidfit
