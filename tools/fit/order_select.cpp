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
    // digits beyond an int (std::stoi would throw out_of_range) are beyond 400 too: -1 fails the check below
    auto value = [](const std::string &d) { return d.size() > 9 ? -1 : std::stoi(d); };
    const int a = value(first), b = value(last);
    const int st = !mid.empty() ? value(mid) : step;
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

namespace {

// The elbow among the rows (the rule of order_select.hpp): the index of the chosen row, -1 if none.
// *decided: the chosen row's ratio is within 0.1 r_first of zero, so no row added later can move the
// choice (a later minimum lowers the threshold r_min + 0.1 (r_first - r_min) to no less than 0.1 r_first).
int elbow(const std::vector<OrderRow> &rows, bool *decided = nullptr)
{
    if (decided) *decided = false;
    double rmin = 1e300, rfirst = NAN;
    for (const auto &r : rows) {
        if (!r.fit.ok || !(r.fit.expected > 0)) continue;
        const double q = r.fit.cost / r.fit.expected;
        if (std::isnan(rfirst)) rfirst = q;
        rmin = std::min(rmin, q);
    }
    if (std::isnan(rfirst)) return -1;
    const bool any_interior = std::any_of(rows.begin(), rows.end(), [](const OrderRow &r) {
        return r.fit.ok && r.fit.expected > 0 && r.fit.at_bound == 0;
    });
    for (size_t i = 0; i < rows.size(); ++i) {
        const OrderRow &r = rows[i];
        if (!r.fit.ok || !(r.fit.expected > 0) || (any_interior && r.fit.at_bound > 0)) continue;
        const double q = r.fit.cost / r.fit.expected;
        if (q - rmin <= 0.1 * (rfirst - rmin)) {
            if (decided) *decided = any_interior && q <= 0.1 * rfirst;
            return (int)i;
        }
    }
    return -1;
}

// No order of the scan will pass the p-value rule, so the scan can stop once the elbow is decided: the
// cost ratio of the last order is still FLAT_RATIO times its expectation or more and the last two orders
// each lowered it by less than a factor FLAT_DROP (the model error the covariance does not hold, which
// more poles no longer remove: on the F-16 record 908, 830, 613 at orders 18, 21, 24 against 1 for a
// model the noise explains); the chosen order is two orders back or more, as after a p-value pass.
constexpr double FLAT_RATIO = 10.0, FLAT_DROP = 2.0;

bool flat_far_above(const std::vector<OrderRow> &rows)
{
    std::vector<double> q;
    for (const auto &r : rows)
        if (r.fit.ok && r.fit.expected > 0) q.push_back(r.fit.cost / r.fit.expected);
    if (q.size() < 3) return false;
    const size_t n = q.size();
    return q[n - 1] >= FLAT_RATIO && q[n - 2] < FLAT_DROP * q[n - 1] && q[n - 3] < FLAT_DROP * q[n - 2];
}

}  // namespace

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
        if (stop_early && passed_at < 0 && flat_far_above(s.rows)) {
            bool decided = false;
            const int e = elbow(s.rows, &decided);
            if (decided && e >= 0 && e + 2 <= (int)i) {
                s.stopped_flat = true;
                break;
            }
        }
    }
    if (passed_at >= 0) {
        s.chosen = s.rows[(size_t)passed_at].order;
        s.rule = "p-value";
        return s;
    }
    const int e = elbow(s.rows);
    if (e >= 0) {
        s.chosen = s.rows[(size_t)e].order;
        s.rule = "elbow";
    }
    return s;
}

Json order_selection_json(const OrderSelection &s)
{
    Json o;
    o["chosen"] = s.chosen >= 0 ? Json(s.chosen) : Json(nullptr);
    o["rule"] = s.rule.empty() ? Json(nullptr) : Json(s.rule);
    o["rule_text"] = "smallest order with cost p-value >= alpha; if none, the smallest order whose cost ratio V/E is "
                     "within 10% of the way from the best ratio to the first order's, among the orders whose model holds "
                     "no pole on the stability bound (all orders if each holds one)";
    o["alpha"] = s.alpha;
    o["stopped"] = s.stopped_flat ? Json("the elbow was decided with the cost ratio flat far above its expectation "
                                         "(no higher order would pass the p-value rule)")
                                  : Json(nullptr);
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
        e["poles_at_bound"] = r.fit.at_bound;
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
