#include "order_select.hpp"
#include "text_scan.hpp"

#include <algorithm>
#include <cmath>

namespace msidfit {

std::vector<int> parse_order_range(const std::string &s, int step, int max_order, bool *is_auto)
{
    std::vector<int> out;
    step = std::max(step, 1);
    if (is_auto) *is_auto = s == "auto";
    if (s == "auto") {
        for (int n = step; n <= max_order; n += step) out.push_back(n);
        if (out.empty()) throw FitError("--order auto: the lines support no order (at most " + std::to_string(max_order) + ")");
        return out;
    }
    // ^(\d+):(?:(\d+):)?(\d+)$
    size_t i = 0;
    const std::string first = scan_digits(s, i);
    std::string mid, last;
    bool ok = !first.empty() && scan_char(s, i, ':');
    if (ok) last = scan_digits(s, i);
    if (ok && !last.empty() && scan_char(s, i, ':')) {   // a:step:b
        mid = last;
        last = scan_digits(s, i);
    }
    ok = ok && !last.empty() && i == s.size();
    if (!ok) throw FitError("--order '" + s + "': expected a positive integer, auto, a:b or a:step:b");
    const int a = std::stoi(first), b = std::stoi(last);
    const int st = !mid.empty() ? std::stoi(mid) : step;
    if (a < 1 || b < a || st < 1 || b > 400) throw FitError("--order '" + s + "': need 1 <= a <= b <= 400 and step >= 1");
    for (int n = a; n <= b; n += st)
        if (n % step == 0) out.push_back(n);
    if (out.empty()) throw FitError("--order '" + s + "': no order in the range is a multiple of " + std::to_string(step) +
                                    " (the number of outputs, for an LMFD)");
    return out;
}

static void mark_stability(OrderRow &cur, const OrderRow *prev, const StabTol &t)
{
    cur.n_stable = 0;
    for (StabPole &p : cur.poles) {
        if (!prev || prev->poles.empty()) continue;
        const Mode &m = p.mode;
        const StabPole *best = nullptr;
        double d = 1e300;
        for (const StabPole &q : prev->poles) {
            const double dq = std::abs(q.mode.pole_ct - m.pole_ct);
            if (dq < d) { d = dq; best = &q; }
        }
        const Mode &o = best->mode;
        p.freq = std::abs(m.wn - o.wn) <= t.freq * o.wn;
        p.damping = o.zeta < 2e-3 ? std::abs(m.zeta - o.zeta) <= 1e-4 : std::abs(m.zeta - o.zeta) <= t.damping * o.zeta;
        const double rn = o.residue.norm();
        p.residue = m.residue.rows() == o.residue.rows() && (m.residue - o.residue).norm() <= t.residue * rn;
        cur.n_stable += p.stable();
    }
}

OrderSelection select_order(const std::vector<int> &orders, const std::function<OrderFit(int)> &fit, double h,
                            double alpha, const StabTol &tol, bool stop_early)
{
    OrderSelection s;
    s.alpha = alpha;
    s.tol = tol;
    int passed_at = -1;
    for (size_t i = 0; i < orders.size(); ++i) {
        OrderRow row;
        row.order = orders[i];
        try {
            row.fit = fit(orders[i]);
        } catch (const std::exception &e) {
            row.fit.ok = false;
            row.fit.error = e.what();
        }
        if (row.fit.ok)
            for (const Mode &m : modes_of(row.fit.model, h)) row.poles.push_back(StabPole{m});
        const OrderRow *prev = nullptr;
        for (auto it = s.rows.rbegin(); it != s.rows.rend(); ++it)
            if (it->fit.ok) { prev = &*it; break; }
        mark_stability(row, prev, tol);
        if (row.fit.ok && passed_at < 0 && row.fit.p_value >= alpha) passed_at = (int)i;
        s.rows.push_back(std::move(row));
        if (stop_early && passed_at >= 0 && (int)i >= passed_at + 2) break;
    }
    if (passed_at >= 0) {
        s.chosen = s.rows[(size_t)passed_at].order;
        s.rule = "p-value";
        return s;
    }
    // elbow of the cost ratio
    double rmin = 1e300, rfirst = NAN;
    for (const auto &r : s.rows) {
        if (!r.fit.ok || !(r.fit.expected > 0)) continue;
        const double q = r.fit.cost / r.fit.expected;
        if (std::isnan(rfirst)) rfirst = q;
        rmin = std::min(rmin, q);
    }
    if (std::isnan(rfirst)) return s;
    for (const auto &r : s.rows) {
        if (!r.fit.ok || !(r.fit.expected > 0)) continue;
        if (r.fit.cost / r.fit.expected - rmin <= 0.1 * (rfirst - rmin)) {
            s.chosen = r.order;
            s.rule = "elbow";
            break;
        }
    }
    return s;
}

Json order_selection_json(const OrderSelection &s)
{
    Json o;
    o["chosen"] = s.chosen >= 0 ? Json(s.chosen) : Json(nullptr);
    o["rule"] = s.rule.empty() ? Json(nullptr) : Json(s.rule);
    o["rule_text"] = "smallest order with cost p-value >= alpha; if none, the smallest order whose cost ratio V/E is "
                     "within 10% of the way from the best ratio to the first order's";
    o["alpha"] = s.alpha;
    o["line_stride"] = s.line_stride;
    o["lines_in_statistic"] = s.line_stride > 1 ? "every " + std::to_string(s.line_stride) +
                                                      "-th line (2W+1, independent LPM lines, as msid validate)"
                                                : std::string("all");
    o["tolerances"] = {{"freq_rel", s.tol.freq}, {"damping_rel", s.tol.damping}, {"damping_abs_below_0.002", 1e-4},
                       {"residue_rel", s.tol.residue}};
    Json rows = Json::array();
    for (const auto &r : s.rows) {
        Json e;
        e["order"] = r.order;
        e["ok"] = r.fit.ok;
        if (!r.fit.ok) {
            e["error"] = r.fit.error;
            rows.push_back(e);
            continue;
        }
        e["converged"] = r.fit.converged;
        e["cost"] = r.fit.cost;
        e["expected"] = r.fit.expected;
        e["dof"] = r.fit.dof;
        e["p_value"] = std::isfinite(r.fit.p_value) ? Json(r.fit.p_value) : Json(nullptr);
        e["stable_model"] = ss_stable(r.fit.model);
        e["n_stable_poles"] = r.n_stable;
        e["modes_not_identified"] = r.fit.not_identified >= 0 ? Json(r.fit.not_identified) : Json(nullptr);
        Json poles = Json::array();
        for (const auto &p : r.poles) {
            std::string flag = p.stable() ? "s" : p.freq && p.damping ? "d" : p.freq ? "f" : "o";
            poles.push_back({{"fn", p.mode.fn}, {"zeta", p.mode.zeta}, {"real_pole", p.mode.real}, {"flag", flag}});
        }
        e["poles"] = poles;
        rows.push_back(e);
    }
    o["orders"] = rows;
    o["flags"] = "s: frequency, damping and residue settled; d: frequency and damping; f: frequency; o: new/unsettled";
    return o;
}

}  // namespace msidfit
