// Order selection of subspace and ml (`msid fit --order auto | a:b | a:step:b`): a fit at every
// order, a stabilisation diagram, one order kept. docs/fitting.md, "Order selection".
#include "fit_job_detail.hpp"
#include "msid_cancel.hpp"
#include "validation_stat.hpp"

#include "msid_json_file.hpp"
#include "modal_io.hpp"
#include "order_select.hpp"

#include <algorithm>
#include <cmath>
#include <map>

namespace msidfitjob {

namespace {

// The largest order auto tries: the largest the method fits on these lines (subspace: the
// block-row limit; ml in the pole-residue form: fewer parameters n (1 + g) + g than real
// equations), at least neq / (2 (nu + ny)), at most 40. The latter bound alone stopped at order 2
// on 5 SISO lines, where the 4th-order plant fits (p = 0.9), and the elbow rule chose order 2 at p = 0.
int largest_order(const FrfData &f, const FitRequest &rq)
{
    double neq = 0;
    for (const auto &l : f.lines) neq += (l.real ? 1.0 : 2.0) * (double)f.g();
    const double g = (double)f.g(), eq_lines = neq / g;
    int method_cap = 0;
    if (rq.method == "subspace") method_cap = (int)std::floor(eq_lines * f.nu / (double)(f.nu + f.ny)) - 2;
    const bool poles = rq.param != "lmfd" && !(f.domain == Domain::DT && f.nu > 1 && rq.domain != "ct");
    if (rq.method == "ml" && poles) method_cap = (int)std::floor((neq - g - 1.0) / (1.0 + g));
    return std::min(40, std::max((int)std::floor(neq / (2.0 * (f.nu + f.ny))), method_cap));
}

// The stabilisation diagram compares residue matrices by a relative Frobenius norm, which the
// entries in the largest units dominate: with outputs in 1e-9 and 1e3 the count of stable poles
// changed (11/12 against 8/12 at the same model). The residues are compared in units where every
// output's and input's |G| has mean square 1 (a two-way fit of log mean_l |G_l(i, j)|^2, as the
// subspace normalisation): C and B of the compared model are scaled, nothing written changes.
void unit_scales(const FrfData &f, VecR &so, VecR &si)
{
    so = VecR::Ones(f.ny);
    si = VecR::Ones(f.nu);
    MatR lm = MatR::Zero(f.ny, f.nu);
    for (const auto &l : f.lines) lm += l.G.cwiseAbs2();
    bool ok = true;
    for (Eigen::Index i = 0; i < lm.size(); ++i) {
        ok = ok && lm(i) > 0 && std::isfinite(lm(i));
        if (ok) lm(i) = std::log(lm(i) / (double)f.lines.size());
    }
    if (!ok) return;
    const double grand = lm.mean();
    for (Eigen::Index i = 0; i < (Eigen::Index)f.ny; ++i) so(i) = std::exp(0.5 * lm.row(i).mean());
    for (Eigen::Index j = 0; j < (Eigen::Index)f.nu; ++j) si(j) = std::exp(0.5 * (lm.col(j).mean() - grand));
}

// One row of the diagram from the model document of one order.
OrderFit order_row(const Json &d, const FitOutcome &o, size_t stride, const VecR &so, const VecR &si, size_t nu,
                   size_t ny)
{
    OrderFit r;
    r.ok = true;
    r.converged = o.converged && d.value("converged", true);
    // the statistic of msid validate: for an LPM file the cost over every (2W+1)-th line (independent),
    // which the fit writes as cost.independent_lines (validation_stat.hpp); every line otherwise
    const Json &c = stride > 1 ? d["cost"].value("independent_lines", Json()) : d["cost"];
    if (c.is_null()) {   // too few independent lines for this many parameters: no p-value
        r.cost = d["cost"]["value"].get<double>();
        r.expected = d["cost"]["expected"].get<double>();
        r.dof = d["cost"]["dof"].get<double>();
        r.p_value = NAN;
    } else {
        r.cost = c["value"].get<double>();
        r.expected = c["expected"].get<double>();
        r.dof = c["dof"].get<double>();
        r.p_value = c["p_value"].is_number() ? c["p_value"].get<double>() : NAN;
    }
    const Eigen::Index k = d["order"].get<Eigen::Index>();
    r.model.domain = d["domain"] == "ct" ? Domain::CT : Domain::DT;
    auto jm = [](const Json &v, Eigen::Index rr, Eigen::Index cc) {
        MatR M(rr, cc);
        for (Eigen::Index i = 0; i < rr; ++i)
            for (Eigen::Index j = 0; j < cc; ++j) M(i, j) = v.at((size_t)i).at((size_t)j).get<double>();
        return M;
    };
    r.model.A = jm(d["A"], k, k);
    r.model.B = jm(d["B"], k, (Eigen::Index)nu) * si.cwiseInverse().asDiagonal();   // unit-free residues (above)
    r.model.C = so.cwiseInverse().asDiagonal() * jm(d["C"], (Eigen::Index)ny, k);
    r.model.D = jm(d["D"], (Eigen::Index)ny, (Eigen::Index)nu);
    if (d.contains("parameters") && d["parameters"].contains("at_bound"))
        r.at_bound = (int)d["parameters"]["at_bound"].size();
    if (d.contains("modes") && d["modes"].contains("modes"))
        for (const Json &m : d["modes"]["modes"])
            if (m.contains("identified")) r.not_identified = std::max(r.not_identified, 0) + !m["identified"].get<bool>();
    return r;
}

// The table msid prints: one row per order, failures once per message.
std::string scan_table(const OrderSelection &sel, size_t stride)
{
    std::string t;
    if (stride > 1)
        t += fmt("LPM file: cost and p-value over every %zu-th line (2W+1 bins apart: independent), as msid validate\n",
                 stride);
    // "stabilised": poles that repeat from the order below (the diagram's sense, not the model's stability)
    t += "order  cost          expected      p-value     stabilised    not identified  on the bound\n";
    std::map<std::string, int> failed_first;   // error -> the first order that printed it
    for (const auto &r : sel.rows) {
        if (!r.fit.ok) {
            const auto seen = failed_first.emplace(r.fit.error, r.order);
            if (seen.second) t += fmt("%-6d failed: ", r.order) + r.fit.error + "\n";
            else t += fmt("%-6d failed: as order %d\n", r.order, seen.first->second);
            continue;
        }
        const std::string sp = std::to_string(r.n_stable) + "/" + std::to_string(r.poles.size());
        t += fmt("%-6d %-13.6g %-13.6g %-11.3g %-13s %-15s %-12d%s%s\n", r.order, r.fit.cost, r.fit.expected,
                 r.fit.p_value, sp.c_str(), r.fit.not_identified >= 0 ? std::to_string(r.fit.not_identified).c_str() : "-",
                 r.fit.at_bound, r.fit.converged ? "" : "  (not converged)", r.order == sel.chosen ? "  <- chosen" : "");
    }
    if (sel.stopped_flat)
        t += fmt("scan stopped after order %d: the elbow is decided and the cost, %.3g times its expectation, fell by "
                 "less than half at each of the last two orders (model error the covariance does not hold: no higher "
                 "order would pass the p-value rule)\n",
                 sel.rows.back().order, sel.rows.back().fit.cost / sel.rows.back().fit.expected);
    return t;
}

}  // namespace

FitOutcome fit_frf_scan(const FrfData &f, const FitRequest &rq, const Report &report)
{
    const std::string range = rq.order.empty() ? "auto" : rq.order;
    if (rq.method == "lmfd") throw UsageError(MSID_OPT("order") " auto/a:b needs " MSID_OPT("method") " subspace or ml (lmfd interpolates at every order)");
    if (!rq.start.empty() && rq.start != "subspace" && rq.start != "sk")
        throw UsageError(MSID_OPT("start") " " + rq.start + " starts one order (the model's): give one " MSID_OPT("order") " or leave it out, not " +
                         range);
    const int step = rq.method == "subspace" ? 1 : (int)f.ny;
    bool is_auto = false;
    std::vector<int> orders;
    try {
        orders = parse_order_range(range, step, largest_order(f, rq), &is_auto);
    } catch (const FitError &e) {
        throw UsageError(e.what());
    }
    FitOutcome out;
    size_t stride = 1;
    try {
        stride = lpm_line_stride(f);   // as msid validate: every (2W+1)-th line of an LPM file
    } catch (const FitError &e) {
        throw Error(e.what());
    }
    VecR so, si;
    unit_scales(f, so, si);
    std::vector<std::pair<int, FitOutcome>> fits;
    std::string usage;   // a usage error of the fit (e.g. --start sk with --param poles) holds at every order
    auto fit_at = [&](int n) {
        if (!usage.empty()) throw FitError(usage);
        FitRequest at = rq;
        at.order = std::to_string(n);
        FitOutcome o;
        try {
            // a note every order gives alike (e.g. an FRF without covariance: unweighted) is said once
            o = fit_frf_at_order(f, at, [&](const std::string &note) {
                if (std::find(out.notes.begin(), out.notes.end(), note) == out.notes.end()) add_note(out, report, note);
            });
        } catch (const msidutil::UsageError &e) {
            usage = e.what();
            throw FitError(usage);
        }
        const std::string bad = msidfmt::nonfinite_at(o.model);   // such a model is never written
        if (!bad.empty())
            throw Error("the model is not finite at " + bad +
                        " (inputs beyond double precision's range, e.g. data scaled near 1e150 or a sample rate near 0)");
        const OrderFit r = order_row(o.model, o, stride, so, si, f.nu, f.ny);
        fits.emplace_back(n, std::move(o));
        msidutil::checkpoint(msidutil::Step::orders, 1, "the order scan");
        return r;
    };
    OrderSelection sel = select_order(orders, fit_at, f.h, 0.05, StabTol{}, is_auto);
    if (!usage.empty()) throw UsageError(usage);   // one message, exit 2, not one failed row per order
    sel.line_stride = stride;
    // Every order failed for the same reason (the data's, e.g. too few periods for the weighting): that one
    // message, not one table row per order and the same again below.
    const bool same_failure = !sel.rows.empty() && std::all_of(sel.rows.begin(), sel.rows.end(), [&](const auto &r) {
        return !r.fit.ok && r.fit.error == sel.rows.front().fit.error;
    });
    if (same_failure) throw Error(sel.rows.front().fit.error);
    out.before = scan_table(sel, stride);
    if (sel.chosen < 0)
        throw Error("no order in '" + range + "' gave a model: " + sel.rows.back().fit.error, out.before);
    for (auto &x : fits)
        if (x.first == sel.chosen) out.model = std::move(x.second.model);
    out.model["order_selection"] = order_selection_json(sel);
    out.head = fmt("chosen order %d (%s rule); wrote ", sel.chosen, sel.rule.c_str());
    out.tail = "\n";
    const ModalReport mr = modal_report(out.model);
    if (!mr.modes.empty()) out.after = modal_text(mr);
    out.converged = out.model.value("converged", true);
    if (!out.converged)   // as a fit at a fixed order: the best iterate is written, exit status 3
        out.not_converged = fmt("the chosen order %d did not converge (cost %.6g, gradient norm %.3g): wrote its best "
                                "iterate to ",
                                sel.chosen,
                                out.model["cost"].value("fit_cost_smoothed_weights",
                                                        out.model["cost"]["value"].get<double>()),
                                out.model.value("gradient_norm", 0.0));
    return out;
}

}  // namespace msidfitjob
