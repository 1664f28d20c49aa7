// Pole-residue models and their weighted maximum likelihood (González et al. 2025
// eq. 40 in a pole-residue parametrisation), started from vector fitting
// (Gustavsen & Semlyen 1999 pole relocation) and from subspace models at several
// block-row counts, refined by a scaled Levenberg-Marquardt (trust-region) with
// the residues re-solved by weighted least squares after every step (variable
// projection). Numerically sound to order 40+ where monomial LMFD coefficients
// are not: the basis 1/(x - p_k) is as well conditioned as the poles are apart.
#pragma once
#include "frf_data.hpp"
#include "models.hpp"

namespace msidfit {

// G(x) = sum_k R_k / (x - p_k) [+ conj pair] + D, x = s (CT) or z (DT).
// poles[k] with Im > 0 stands for the pair (p, conj p) with residues (R, conj R);
// Im == 0 is a real pole with a real residue.
struct PoleResidueModel {
    Domain domain = Domain::CT;
    double h = 0.0;
    std::vector<cd> poles;
    std::vector<MatC> R;      // ny x nu each
    MatR D;                   // ny x nu (zero when there is no feedthrough)
    bool feedthrough = true;
    int order() const;        // number of poles counting pairs twice
};

// The model and its realisations: poleres_model.cpp; the ML fit below: poleres.cpp.
MatC pr_eval(const PoleResidueModel &m, cd x);
// Real realisation (A block-diagonal: p I_nu, or [[s, w], [-w, s]] kron I_nu), order order() * nu.
SSModel pr_to_ss(const PoleResidueModel &m);
// Pole list from the eigenvalues of a real matrix: one entry per real pole (|Im| <= 1e-10 |p|, stored with
// Im = 0) or conjugate pair (its Im > 0 member), sorted by |p|, then by Re p.
std::vector<cd> pole_list(const VecC &ev);
// Poles of a state-space model as pole-residue pole list (pairs by their Im > 0 member), sorted by |p|.
std::vector<cd> ss_poles(const SSModel &m);

enum class Feedthrough { Auto, Yes, No };

struct PrOptions {
    int order = 0;                 // number of poles (pairs count twice)
    Feedthrough feedthrough = Feedthrough::Auto;
    bool stable = true;            // constrained ML (msid fit's default): starts reflected, steps projected onto the
                                   // stability bound, poles the data push out held on it (stab_bound.hpp)
    int max_iter = 200;            // LM iterations of the final refinement
    double tol = 1e-10;            // relative cost decrease for convergence
    int vf_iter = 15;              // vector-fitting relocations of the VF start (log-spaced poles)
    int rvf_iter = 100;            // relaxed vector-fitting relocations (linear spacing; 0: no such start)
    int start_iter = 15;           // LM iterations from each start before the best continues
    double auto_alpha = 0.01;      // level of the likelihood-ratio test for the feedthrough (auto)
    double wscale = 0.0;           // CT frequency scaling (0: geometric mean of the line frequencies)
    bool known_noise = false;
    std::vector<SSModel> subspace_starts;   // extra starts (subspace at several r), any order
    // pr_ml_fit: the weights of the subspace r scan (msid fit: each line's own covariance when ml
    // minimises pooled weights); null: the fit's own weights
    const std::vector<WeightedLine> *subspace_scan_w = nullptr;
    bool refined_subspace_start = false;     // the last subspace start is the refined model (named so)
    // starts given by their poles (msid fit --start MODEL: a previous fit, another tool's model), each
    // {name, poles as pole_list stores them}; the residues follow by weighted least squares. When given,
    // they replace the vector-fitting and subspace starts (the model is refined, as MATLAB's ssest(data, sys))
    std::vector<std::pair<std::string, std::vector<cd>>> pole_starts;
};

struct PrStart {
    std::string name;
    double cost = 0.0;             // after start_iter LM iterations
};

struct PrResult {
    PoleResidueModel model;
    std::vector<std::string> names;
    VecR theta;                    // unscaled: pole (re[, im]) per pole, then residues (re[, im]), then D
    MatR cov;                      // (pseudo-)inverse Fisher information, sample-ML corrected
    int cov_rank = 0;              // rank of the Fisher information (== theta.size() when identifiable)
    double cov_factor = 1.0;
    double cost = 0.0;             // eq. (40)
    double grad_norm = 0.0;        // |D^-1 J^T r| with D^2 = diag(J^T J): scale free
    bool converged = false;
    int iterations = 0;
    int reflected = 0;             // poles reflected into the stable region (stable option)
    // per pole of model.poles: held on the stability bound (stab_bound.hpp) at the end, the data pushing it
    // out; its damping (CT Re p, DT |p|) is the constraint's, not an estimate, and has no variance in cov
    std::vector<char> at_bound;
    std::vector<PrStart> starts;
    std::string best_start;
    double feedthrough_lr_p = -1;  // p-value of the likelihood-ratio test D = 0 (auto), -1 if not run
    std::vector<MatC> G, Gcov;     // model FRF at the lines and its covariance
};

// Vector fitting (weighted by the diagonal of the line covariances): the relocated poles.
std::vector<cd> vector_fit_poles(const std::vector<WeightedLine> &w, Domain d, int order, bool feedthrough, int iters,
                                 double wscale, bool relaxed = false);

// Weighted ML in pole-residue form. Never throws for non-convergence: the best
// iterate comes back with converged = false. Throws FitError for impossible
// orders (more parameters than data) naming the limit.
PrResult pr_ml(const std::vector<WeightedLine> &w, Domain d, double h, const PrOptions &o);

// pr_ml with the subspace starts added, as `msid fit --method ml` runs it (skipped when subspace cannot
// fit this order; weighted when `weighted`): the best models of the block-row scan at the same order and
// the model `msid fit --method subspace` writes (refined on the weights ml minimises, stable when
// o.stable), so ml never ends above that model's cost.
PrResult pr_ml_fit(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted, PrOptions o);

}  // namespace msidfit
