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

// Pooled weights for ml and subspace's refinement (`--weight-smooth H`; weight_pool.cpp, docs/fitting.md
// "Pooled weights"). Each complex line's covariance is replaced by the dof-weighted mean of its own and
// those of its neighbours within a window of 2 half + 1 complex lines (shifted at the band edges), its dof
// by their sum, where pooling can pay and the covariances agree:
// - only a line whose own weights are imprecise: the sample-ML variance factor n/(n - ny - 1) of its
//   n dof above 1 + POOL_MIN_INFLATION (with more dof per-line weights are as good as exact, and pooling
//   could only add the bias of a covariance that changes over the window);
// - only the neighbours whose whole covariance matrix equals the line's by a likelihood-ratio test of two
//   complex Wishart matrices (Bartlett-corrected, chi2 with one dof per free real entry, at 5%): a change
//   of level or of shape (correlations) leaves the neighbour out. `block` is the dimension of the Wishart
//   blocks of the covariance (ny for the nonparametric covariance of several experiments, whose blocks
//   are one experiment's ny x ny noise covariance; 0: the whole g x g matrix).
// Real lines and half = 0: unchanged. Returns how many lines were pooled and neighbours left out.
struct PoolStats {
    size_t lines = 0;          // complex lines
    size_t pooled = 0;         // lines whose weight pools at least one neighbour
    size_t precise = 0;        // lines left alone: their own dof make pooling pointless
    size_t left_out = 0;       // neighbours refused by the equality test (over all lines)
};
PoolStats smooth_weights(std::vector<WeightedLine> &w, int half, size_t block = 0);
// The dimension of the Wishart blocks of a file's covariance for `smooth_weights` (ny for the
// nonparametric covariance of several experiments and for known-input weights, else 0: whole matrix).
size_t pool_block(const FrfData &f, Weight w);
// ml's default half-width H (`msid fit --weight-smooth`).
constexpr int ML_WEIGHT_SMOOTH = 4;
// Without --weight-smooth, ml pools only when the file has at least this many windows of 2H+1 lines.
constexpr int ML_WEIGHT_SMOOTH_MIN_WINDOWS = 4;
// A line pools only when its own weights inflate the estimate's variance by more than this
// (sample-ML factor n/(n - ny - 1) - 1; 2%: fewer than 51 (ny + 1) dof).
constexpr double POOL_MIN_INFLATION = 0.02;
// Level of the equality test of two lines' covariance matrices (g > 1). 5%, not 1%: on covariances whose
// shape changes from line to line (2x2, 8 dof) the neighbours a 1% test let through made the pooled
// estimate 1% worse than per-line weights (mean error ratio 1.011 over 6 noise sets; 5%: 1.000), while
// on smooth covariances the gain stays (0.755 against 0.741).
constexpr double POOL_TEST_LEVEL = 0.05;

}  // namespace msidfit
