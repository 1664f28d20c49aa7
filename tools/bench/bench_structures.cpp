// msid bench fit, part 3: the simulated structures (accelerances, rigid-body and lightly damped
// elastic modes) fitted by ml and subspace against scikit-rf vector fitting at the same order, and
// the Monte Carlo over noise seeds of ml against vector fitting (docs/benchmarks.md).
#include "bench_fit_parts.hpp"

#include "model_io.hpp"
#include "msid_json_file.hpp"
#include "poleres.hpp"
#include "subspace.hpp"

#include <cmath>

namespace msidbench {

using namespace msidfit;
using msidfmt::Json;
using msidfmt::read_json_file;

namespace {

// |G - G0| / |G0| over the lines, G0 as the peer writes it (re/im per line, vec order).
double rel_error_to(const std::vector<MatC> &G, const Json &G0, Eigen::Index g)
{
    double num = 0, den = 0;
    for (size_t l = 0; l < G.size(); ++l)
        for (Eigen::Index ij = 0; ij < g; ++ij) {
            const cd g0(G0["re"][l][(size_t)ij].get<double>(), G0["im"][l][(size_t)ij].get<double>());
            num += std::norm(G[l].data()[ij] - g0);
            den += std::norm(g0);
        }
    return std::sqrt(num / den);
}

// |G - G_measured| / |G_measured| over the lines: the relative fit error vector fitting reports.
double fit_error_to(const std::vector<MatC> &G, const std::vector<WeightedLine> &w)
{
    double num = 0, den = 0;
    for (size_t l = 0; l < w.size(); ++l) {
        num += (G[l] - w[l].G).squaredNorm();
        den += w[l].G.squaredNorm();
    }
    return std::sqrt(num / den);
}

// Eq. (40) of model FRFs G on the per-line weights w (the file's covariance).
double cost_on(const std::vector<WeightedLine> &w, const std::vector<MatC> &G)
{
    double V = 0;
    for (size_t l = 0; l < w.size(); ++l)
        V += (w[l].real ? 0.5 : 1.0) * (w[l].Linv * Eigen::Map<const VecC>(MatC(w[l].G - G[l]).data(), w[l].G.size())).squaredNorm();
    return V;
}

double median_of(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double mean_of(const std::vector<double> &v)
{
    double m = 0;
    for (double x : v) m += x / (double)v.size();
    return m;
}

long count_above_one(const std::vector<double> &v)
{
    return std::count_if(v.begin(), v.end(), [](double x) { return x > 1.0; });
}

// "<kind> <modes> modes" of a case the peer wrote.
std::string case_name(const Json &c)
{
    return c["kind"].get<std::string>() + " " + std::to_string(c["modes"].get<int>()) + " modes";
}

// One case of the Monte Carlo, over its runs: ml's ratios to vector fitting's.
struct McCase {
    std::vector<double> er, fe, cr, cp;   // error against the truth, fit error, cost, pooled cost
    int stable = 0, better = 0;
    double tvf = 0;                       // vector fitting's time, summed [s]
};

McCase mc_case(const Json &c)
{
    McCase a;
    for (const Json &run : c["runs"]) {
        const FrfData f = read_frf(run["file"].get<std::string>());
        const auto w = weigh(f, Domain::CT, Weight::Cov);
        auto wp = w;
        smooth_weights(wp, ML_WEIGHT_SMOOTH);
        PrOptions po;
        po.order = c["order"].get<int>();
        const PrResult r = pr_ml_fit(f, Domain::CT, wp, true, po);
        const double e = rel_error_to(r.G, run["G0"], (Eigen::Index)f.g());
        a.er.push_back(e / run["vf_rel_error"].get<double>());
        a.fe.push_back(fit_error_to(r.G, w) / run["vf_fit_error"].get<double>());
        a.cr.push_back(cost_on(w, r.G) / run["vf_cost"].get<double>());
        a.cp.push_back(r.cost / run["vf_cost_pooled"].get<double>());   // the cost ml minimises, on both
        a.stable += ss_stable(pr_to_ss(r.model));
        a.better += a.er.back() <= 1.0;
        a.tvf += run["vf_seconds"].get<double>();
    }
    return a;
}

// The Monte Carlo over noise seeds (--runs N): ml as `msid fit` runs it against vector fitting at
// the same order, per case the mean and median of ml's error against the truth over vector
// fitting's, its standard error, the mean cost ratio and the stable fraction (docs/benchmarks.md).
void structures_mc(Writer &w, const Json &mc)
{
    if (mc.empty()) return;
    w.print("  Monte Carlo over noise seeds 0..%zu (ml error against the truth / vector fitting's, same file, same order):\n",
            mc[0]["runs"].size() - 1);
    w.print("  %-14s %5s %4s | %-28s | %-9s | %-19s | %-19s | %-19s | %-12s | %s\n", "case", "order", "runs",
            "err ratio mean (se), median", "ml <= VF", "fit err ml/VF (n > 1)", "cost ml/VF (n > 1)",
            "pooled ml/VF (n > 1)", "ml stable", "VF time");
    for (const Json &c : mc) {
        const McCase a = mc_case(c);
        const double n = (double)a.er.size();
        const double m = mean_of(a.er);
        double v = 0;
        for (double x : a.er) v += (x - m) * (x - m) / std::max(n - 1, 1.0);
        const int order = c["order"].get<int>(), nominal = c["nominal_order"].get<int>();
        w.print("  %-14s %5d %4.0f | %6.4f (%6.4f), %6.4f        | %4d/%-4.0f | %8.4f (%3ld)      | %8.4f (%3ld)      | %8.4f (%3ld)      | %4d/%-4.0f   | %.2f s/fit%s\n",
                case_name(c).c_str(), order, n, m, std::sqrt(v / n), median_of(a.er), a.better, n, mean_of(a.fe),
                count_above_one(a.fe), mean_of(a.cr), count_above_one(a.cr), mean_of(a.cp), count_above_one(a.cp),
                a.stable, n, a.tvf / n, order < nominal ? "  (one mode below the noise left out)" : "");
    }
    w.print("  (err ratio: against the true FRF; fit err: |G_model - G_measured| / |G_measured|, vector fitting's own "
            "measure)\n");
    w.print("  (the SISO structures hold a mode whose peak is 0.1 (10 modes) / 0.2 (12) times the noise sd: at the "
            "nominal order its pole pair is free and ml, which\n"
            "   minimises the cost, spends it on the noise: lower cost, higher error; at the order the data identify "
            "ml and vector fitting agree. docs/benchmarks.md)\n\n");
}

// One structure: ml (pooled weights, and each line's own covariance), subspace, beside vector fitting.
void structure_row(Writer &w, const Json &c, double min_s)
{
    const FrfData f = read_frf(c["file"].get<std::string>());
    const auto wl = weigh(f, Domain::CT, Weight::Cov);
    auto wp = wl;   // ml as `msid fit` runs it: pooled weights (--weight-smooth 4)
    smooth_weights(wp, ML_WEIGHT_SMOOTH);
    const int n = c["order"].get<int>();
    PrOptions po;
    po.order = n;
    PrResult r, r0;
    const double t_ml = best_time([&] { r = pr_ml_fit(f, Domain::CT, wp, true, po); }, c["modes"].get<int>() == 10 ? min_s : 0.0);
    r0 = pr_ml_fit(f, Domain::CT, wl, true, po);
    auto rel_err = [&](const std::vector<MatC> &G) { return rel_error_to(G, c["G0"], (Eigen::Index)f.g()); };
    const double V = cost_on(wl, r.G);   // eq. (40) on the file's (per-line) covariance, as vector fitting's cost
    SubspaceOptions so;   // as `msid fit --method subspace` runs it: refined, stable unless the data need not
    so.order = n;
    so.stable_auto = true;
    so.refine_iter = 30;
    so.refine_w = &wp;   // the refinement on the pooled weights, as msid fit (the cost on the file's)
    SubspaceResult sr;
    const double t_sub = best_time([&] { sr = fit_subspace(f, Domain::CT, wl, true, so); }, 0.0);
    const double vfe = c["vf_rel_error"].get<double>(), e_ml = rel_err(r.G), e_ml0 = rel_err(r0.G);
    w.print("  %-14s %5d %4.0fdB | %9.5g %9.3g %8.3f s | %9.5g %9.3g %8.3f s | %9.3g (%.3fx) | %9.5g (%.2fx) %s %5.1f ms\n",
            case_name(c).c_str(), n, c["dynamic_range_db"].get<double>(), c["vf_cost"].get<double>(), vfe,
            c["vf_seconds"].get<double>(), V, e_ml, t_ml, e_ml0, e_ml0 / vfe, sr.cost, sr.cost / c["vf_cost"].get<double>(),
            ss_stable(sr.model) ? "stable" : "UNSTABLE", t_sub * 1e3);
}

}  // namespace

void fit_structures(Writer &w, const std::string &dir, double min_s, uint32_t runs)
{
    w.print("structures: accelerances, rigid-body + elastic modes with 0.5-2%% damping, 267 lines, "
            "0.2%% noise, 16 periods; peer: scikit-rf VectorFitting at the same order\n");
    std::string outp;
    const std::string js = dir + "/vf.json";
    const int rc = capture("cd '" + dir + "' && PYTHONPATH='" + peers_dir() + "' python3 -m msid_peers.bench_vf_peer '" + dir +
                               "' '" + js + "' --runs " + std::to_string(runs) + " 2>&1",
                           outp);
    if (rc != 0) {
        w.print("  peer unavailable (scripts/deps.sh installs scikit-rf): %s\n\n", outp.substr(0, 300).c_str());
        return;
    }
    const Json pj = read_json_file(js);
    w.print("  %-14s %5s %6s | %-30s | %-30s | %-16s | %-26s\n", "case", "order", "range", "vector fitting: cost, rel.err, time",
            "msid ml: cost, rel.err, time", "ml H=0: rel.err", "msid subspace: cost (x VF)");
    for (const Json &c : pj["cases"]) structure_row(w, c, min_s);
    w.print("  (scikit-rf %s; rel.err = |G_model - G_true| / |G_true| over the lines; cost = eq. (40) on the file's "
            "covariance; ml: pooled weights, --weight-smooth 4 (the default); ml H=0: each line's own covariance as weight;\n"
            "   ml time: best of runs for the 10-mode SISO, one run otherwise)\n",
            pj["skrf"].get<std::string>().c_str());
    structures_mc(w, pj.value("monte_carlo", Json::array()));
    w.print("\n");
}

}  // namespace msidbench
