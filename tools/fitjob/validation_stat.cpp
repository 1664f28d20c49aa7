#include "validation_stat.hpp"

#include "msid_host_util.hpp"
#include "json_util.hpp"
#include "stats.hpp"

#include <algorithm>
#include <cmath>

namespace msidfitjob {

using namespace msidfit;
using msidutil::UsageError;
using msidutil::fmt;

size_t lpm_line_stride(const FrfData &f, const std::string &mode)
{
    if (mode != "independent" && mode != "all")
        throw UsageError(MSID_OPT("lpm_lines") " must be independent or all (got '" + mode + "')");
    if (f.method != "lpm" || mode == "all") return 1;
    if (f.lpm_window < 1 || f.lpm_window > 1000000)
        throw FitError("'" + f.path + "' is an LPM file without a valid lpm.window: cannot tell which lines are independent");
    for (size_t l = 1; l < f.lines.size(); ++l)
        if (f.lines[l].bin != f.lines[l - 1].bin + 1)
            throw FitError("'" + f.path + "': LPM lines are not consecutive bins (bin " + std::to_string(f.lines[l].bin) +
                           " after " + std::to_string(f.lines[l - 1].bin) + "): cannot tell which lines are independent");
    return 2 * (size_t)f.lpm_window + 1;
}

ValidationStat validation_stat(const std::vector<WeightedLine> &w, const std::vector<MatC> &Gm, double n_params,
                               size_t stride, double ny, bool unit_weights)
{
    if (Gm.size() != w.size()) throw FitError("internal: model FRF at " + std::to_string(Gm.size()) + " lines, data at " +
                                              std::to_string(w.size()));
    ValidationStat s;
    s.stride = std::max<size_t>(stride, 1);
    double neq = 0, neq_all = 0, nmin = 1e300;
    for (size_t l = 0; l < w.size(); ++l) {
        const MatC E = w[l].G - Gm[l];
        const double k = (w[l].real ? 1.0 : 2.0) * (double)E.size();
        const double q = (w[l].real ? 0.5 : 1.0) * (w[l].Linv * Eigen::Map<const VecC>(E.data(), E.size())).squaredNorm();
        s.q.push_back(q);
        neq_all += k;
        if (l % s.stride) continue;
        s.cost += q;
        neq += k;
        nmin = std::min(nmin, w[l].dof);
        ++s.n_lines;
    }
    s.dof = neq - n_params * (neq_all > 0 ? neq / neq_all : 0.0);
    if (!(s.dof > 0)) return s;   // callers decide: validate refuses, fit leaves the block out
    const CostLaw law = cost_law(s.dof, unit_weights ? 1e300 : nmin, ny);
    s.expected = law.mean;
    s.p_value = cost_pvalue(law, s.cost);
    return s;
}


// The weighted fits invert sample covariances: B, D of subspace need M >= 4 periods (Pintelon 2002
// Thm 2), and an ny x ny noise covariance from M periods is singular unless M > ny. One message
// naming the periods and the outputs, for any number of outputs.
// `w` are the weights of each line's own covariance (before any pooling: the pooled weights of ml rest
// on more dof, but the cost block and msid validate use each line's own). With `validating` the message
// speaks of the cost's law: its F(2, 2n) terms have a finite mean only for n > ny and a finite variance
// only for n > 2, so with fewer periods no p-value is defined (it came out 0 or NaN for any model).
void check_weight_periods(const std::vector<WeightedLine> &w, const FrfData &f, bool validating)
{
    const size_t ny = f.ny;
    double dmin = 1e300;
    for (const auto &l : w) dmin = std::min(dmin, l.dof);
    if (dmin >= 1e8) return;
    const long M = std::lround(dmin + 1);
    const long need = std::max<long>(4, (long)ny + 2);
    if (!(dmin + 1 < (double)need - 1e-9)) return;
    std::string rule = " needs M >= 4 (Pintelon 2002, Theorem 2)" +
                       (need > 4 ? " and, with " + std::to_string(ny) + " outputs, M >= " + std::to_string(need) +
                                       " for a finite sample-ML covariance"
                                 : std::string());
    const bool periodic = f.method == "periodic" && f.realisations < 2;
    std::string what =
        periodic ? "the weights rest on " + std::to_string(M) + " periods per experiment"
                 : fmt("the covariance of '%s' has %g complex degrees of freedom per line (M = dof + 1 = %ld)",
                       f.path.c_str(), dmin, M);
    if (f.realisations >= 2) {
        // a robust-BLA cov is one sample covariance of the ny nu vector with R - 1 dof, weighed with
        // n = (R - 1) / nu in the laws written for ny outputs (weigh()): n >= need - 1 means
        // R >= nu (need - 1) + 1 (4 for SISO, 7 for 2x2); the old message said "4 periods ... needs M >= 4"
        const long Rneed = (long)f.nu * (need - 1) + 1;
        what = fmt("the total covariance of '%s' rests on %u realisations", f.path.c_str(), f.realisations);
        rule = fmt(" needs R >= %ld realisations with %u input(s) and %u output(s) (Pintelon 2002, Theorem 2, on its "
                   "R - 1 dof)", Rneed, f.nu, f.ny);
    }
    const std::string more = f.realisations >= 2 ? "measure more realisations" : "measure more periods";
    if (validating)
        throw FitError(what + ": the cost's law (F(2, 2n) terms with n = M - 1 dof) has no finite mean and variance "
                       "there, so no p-value; validating with the inverse sample covariance" + rule + "; " + more);
    throw FitError(what + ": weighting by the inverse sample covariance" + rule + "; " + more + " or use --weight none");
}

}  // namespace msidfitjob
