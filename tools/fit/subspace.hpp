// Frequency-domain subspace identification from FRF data with covariance
// weighting (McKelvey-Akcay-Ljung 1996; Pintelon 2002 Algorithm 1, and
// Algorithm 2.1 for continuous time through the bilinear map).
#pragma once
#include "frf_data.hpp"
#include "models.hpp"

namespace msidfit {

struct SubspaceOptions {
    int order = 0;             // n; 0: choose from the singular values
    int r = 0;                 // block rows; 0: scan [1.5n, 6n] for the smallest cost (35)
    bool stable = false;       // reflect unstable poles, then re-estimate B, D (and refine constrained)
    // Stable by default (msid fit): when the r scan leaves unstable poles, the refinement is constrained
    // to stable poles from two starts (the reflected r-scan model, the reflected unconstrained
    // refinement) and the better is kept; the likelihood-ratio p-value of the unconstrained model is
    // reported (stable_lr_p) but does not decide.
    bool stable_auto = false;
    int refine_iter = 0;       // LM steps of refine_subspace after the r scan (msid fit: 30; 0: none)
    bool estimate_D = true;    // false: D = 0 (strictly proper)
    bool feedthrough_auto = false;   // with estimate_D: keep D only if a likelihood-ratio test at 1% needs it
    double wscale = 0.0;       // CT bilinear frequency scaling (0: geometric mean of the line frequencies)
    // Weights of the refinement and of its stability test (msid fit: the covariances pooled over
    // neighbouring lines, as ml's, when the file is dense enough); null: the weights of the r scan.
    // The reported cost is always on the r scan's weights.
    const std::vector<WeightedLine> *refine_w = nullptr;
};

struct SubspaceResult {
    SSModel model;
    int r = 0;
    std::vector<double> sv;                       // singular values at the chosen r
    std::vector<std::pair<int, double>> scan;     // (r, cost) tried
    double cost = 0.0;                            // weighted cost (35)
    double wscale = 0.0;
    int reflected = 0;
    bool feedthrough = true;                      // D estimated
    double feedthrough_p = -1;                    // p-value of the LR test of D = 0 (auto), -1 if not run
    // refinement and stability (refine_iter > 0 or stable_auto)
    int refine_steps = 0;
    double cost_unrefined = -1;                   // cost of the best r-scan model before refinement
    double cost_unconstrained = -1;               // stable_auto with unstable poles: the refined unconstrained cost
    double stable_lr_p = -1;                      // LR p-value of the unconstrained model (diagnostic), -1 if not run
    std::vector<SSModel> candidates;              // the best models of the r scan, best first (up to 3): ml starts
};

// Lines of a weighted data set that carry information (complex lines count 2, real 1).
double real_equations(const std::vector<WeightedLine> &w);

// Fit. Throws FitError for orders too high for the lines (naming the limit) or
// too few periods behind the weights (Pintelon 2002 Thm 2: M >= 2 for A, C and M >= 4 for B, D).
SubspaceResult fit_subspace(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted,
                            const SubspaceOptions &o);

// Weighted LS for B and D given A and C (Pintelon 2002 eq. 17, MIMO form), in place.
// Returns the weighted cost (35) of the result.
double fit_BD(SSModel &m, const std::vector<WeightedLine> &w, bool estimate_D);

// Refinement of a model at its order: Levenberg-Marquardt on the weighted cost (35) in the real
// modal realisation (subspace_refine.cpp). Never raises the cost; with `stable` every pole stays
// stable. B, D finally by fit_BD. Leaves m unchanged if A is (nearly) defective.
struct SubspaceRefine {
    bool refined = false;
    int iterations = 0;      // accepted steps
    double cost_start = 0, cost = 0;
    std::string note;
};
SubspaceRefine refine_subspace(SSModel &m, const std::vector<WeightedLine> &w, bool estimate_D, bool stable, int max_iter);

// Weighted cost sum_l |Linv vec(G_l - G(x_l))|^2 (complex lines) + 1/2 |.|^2 (real lines):
// the negative log-likelihood of eq. (40) up to a constant.
double weighted_cost_ss(const SSModel &m, const std::vector<WeightedLine> &w);

}  // namespace msidfit
