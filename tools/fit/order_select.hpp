// Order selection: a stabilisation diagram (poles against order) and the
// validated cost per order; the chosen order by a documented rule
// (docs/fitting.md, "Order selection").
//
// Rule: the smallest order whose weighted cost is consistent with the noise
// (p-value of the cost against its law, stats.hpp, >= alpha, default 0.05).
// If no order passes, the cost elbow: the smallest order whose cost ratio
// r_n = V_n / E[V_n] is within 10% of the way from the best ratio to the
// first order's ratio, r_n - r_min <= 0.1 (r_first - r_min), among the orders
// whose model holds no pole on the stability bound (a stable fit that holds one
// is on the edge of its model class, where the estimate has no covariance and
// the pole fits what a stable model cannot: model error); all orders when every
// one holds such a pole.
//
// A pole at order n is "stable" in the diagram when a pole at the previous
// order has |f - f'| <= tol.freq f', |zeta - zeta'| <= tol.damping zeta'
// (or 1e-4 absolute for zeta' < 2e-3) and ||R - R'||_F <= tol.residue ||R'||_F
// (defaults 1%, 5%, 10%: the usual frequency/damping/mode-shape tolerances of
// stabilisation diagrams in experimental modal analysis).
#pragma once
#include "json_util.hpp"
#include "modal.hpp"

#include <functional>

namespace msidfit {

struct OrderFit {
    bool ok = false;
    std::string error;           // why the fit at this order failed
    SSModel model;
    double cost = 0, expected = 0, dof = 0, p_value = NAN;
    bool converged = true;
    int not_identified = -1;     // modes marked NOT identified (modal.hpp, the contribution test); -1: no test
    int at_bound = 0;            // poles the stable fit holds on the stability bound (stab_bound.hpp)
};

struct StabTol {
    double freq = 0.01, damping = 0.05, residue = 0.10;
};

struct StabPole {
    Mode mode;
    bool freq = false, damping = false, residue = false;   // settled against the previous order
    bool stable() const { return freq && damping && residue; }
};

struct OrderRow {
    int order = 0;
    OrderFit fit;
    std::vector<StabPole> poles;
    int n_stable = 0;
};

struct OrderSelection {
    std::vector<OrderRow> rows;
    int chosen = -1;             // the chosen order (-1: no fit succeeded)
    std::string rule;            // "p-value" or "elbow"
    double alpha = 0.05;
    StabTol tol;
    size_t line_stride = 1;      // lines of the cost/p-value: every line_stride-th (LPM: 2W+1, as msid validate)
    bool stopped_flat = false;   // stop_early ended the scan at a decided elbow with the cost flat far above its law
};

// Parse "auto", "a:b" or "a:step:b" into orders (multiples of `step` when auto
// or when no step is given); `max_order` caps auto. Throws FitError.
std::vector<int> parse_order_range(const std::string &s, int step, int max_order, bool *is_auto);

// Fit every order (in increasing order); with stop_early the scan stops two
// orders after the first order that passes the p-value rule, or, when none has,
// two orders or more after an elbow no later order can move once the cost ratio
// is at least 10 and the last two orders lowered it by less than a factor 2 each.
OrderSelection select_order(const std::vector<int> &orders, const std::function<OrderFit(int)> &fit, double h,
                            double alpha = 0.05, const StabTol &tol = {}, bool stop_early = false);

Json order_selection_json(const OrderSelection &s);

}  // namespace msidfit
