// The test statistic of `msid validate`, shared by validate, by `msid fit`'s
// independent-line cost of LPM files and by order selection (`msid fit --order
// auto|a:b`), so that all three sum the same lines with the same law
// (docs/fitting.md, "Validation"; docs/statistics.md, LPM).
#pragma once
#include "frf_data.hpp"

#include <string>
#include <vector>

namespace msidfitjob {

// Lines in the statistic: every line (stride 1), or for an LPM file (`"method": "lpm"`; neighbouring
// lines share 2W of their 2W+1 window bins) every (2W+1)-th line, which are independent.
// mode: "independent" (default) or "all" (`--lpm-lines all`: stride 1, an optimistic p-value).
// Throws UsageError for another mode, FitError for an LPM file without a valid lpm.window (1..10^6)
// or with non-consecutive bins.
size_t lpm_line_stride(const msidfit::FrfData &f, const std::string &mode = "independent");

// Eq. (40) of the model FRFs Gm (one ny x nu matrix per line of w) summed over lines 0, stride,
// 2 stride, ...; dof = (real equations of those lines) - n_params x (their share of all lines: a
// model fitted to every line spends its parameters on all of them); the law cost_law(dof, nmin, ny)
// with nmin the least weight dof of the summed lines (unit_weights: known weights, no inverse-moment
// inflation). q: every line's own term (real lines half-weighted), for per-line residuals.
struct ValidationStat {
    size_t stride = 1, n_lines = 0;   // lines in the statistic
    double cost = 0, dof = 0, expected = 0, p_value = 0;
    std::vector<double> q;
};
ValidationStat validation_stat(const std::vector<msidfit::WeightedLine> &w, const std::vector<msidfit::MatC> &Gm,
                               double n_params, size_t stride, double ny, bool unit_weights);

// The weighted fits invert sample covariances: refused, with the periods (or realisations) the
// data would need, when the covariance of `w` (each line's own) rests on too few for the weights
// (or, `validating`, for the cost's law). Throws FitError.
void check_weight_periods(const std::vector<msidfit::WeightedLine> &w, const msidfit::FrfData &f, bool validating);

}  // namespace msidfitjob
