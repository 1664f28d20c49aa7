#include "validation_stat.hpp"

#include "cli_util.hpp"
#include "json_util.hpp"
#include "stats.hpp"

#include <algorithm>
#include <cmath>

namespace msidcli {

using namespace msidfit;

size_t lpm_line_stride(const FrfData &f, const std::string &mode)
{
    if (mode != "independent" && mode != "all")
        throw UsageError("--lpm-lines must be independent or all (got '" + mode + "')");
    if (f.method != "lpm" || mode == "all") return 1;
    const Json j = read_json(f.path);
    if (!j.contains("lpm") || !j["lpm"].contains("window") || !j["lpm"]["window"].is_number_unsigned() ||
        j["lpm"]["window"].get<uint64_t>() < 1 || j["lpm"]["window"].get<uint64_t>() > 1000000)
        throw FitError("'" + f.path + "' is an LPM file without a valid lpm.window: cannot tell which lines are independent");
    for (size_t l = 1; l < f.lines.size(); ++l)
        if (f.lines[l].bin != f.lines[l - 1].bin + 1)
            throw FitError("'" + f.path + "': LPM lines are not consecutive bins (bin " + std::to_string(f.lines[l].bin) +
                           " after " + std::to_string(f.lines[l - 1].bin) + "): cannot tell which lines are independent");
    return 2 * (size_t)j["lpm"]["window"].get<uint64_t>() + 1;
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

}  // namespace msidcli
