// `msid fit --method subspace|lmfd|ml` at one order: the weights, the method's fit, the model's
// cost and document. docs/fitting.md describes the methods; the order scan is fit_scan.cpp.
#include "fit_job_detail.hpp"
#include "validation_stat.hpp"

#include "lmfd_fit.hpp"
#include "stats.hpp"
#include "subspace.hpp"

#include "msid_cancel.hpp"

#include <cmath>

namespace msidfitjob {

void add_note(FitOutcome &out, const Report &report, const std::string &note)
{
    out.notes.push_back(note);
    if (report) report(note);
}

namespace {

const std::vector<std::string> WEIGHT_NAMES = {"cov", "known-input", "none"};
const Weight WEIGHTS[] = {Weight::Cov, Weight::KnownInput, Weight::None};

double min_dof(const std::vector<WeightedLine> &w)
{
    double n = 1e300;
    for (const auto &l : w) n = std::min(n, l.dof);
    return n;
}

// Weighted cost (40) of model FRFs Gm at the lines.
double cost_at(const std::vector<WeightedLine> &w, const std::vector<MatC> &Gm)
{
    double V = 0;
    for (size_t l = 0; l < w.size(); ++l) {
        const MatC E = w[l].G - Gm[l];
        V += (w[l].real ? 0.5 : 1.0) * (w[l].Linv * Eigen::Map<const VecC>(E.data(), E.size())).squaredNorm();
    }
    return V;
}

Json feedthrough_json(Feedthrough ft, bool included, double p)
{
    Json j;
    j["mode"] = ft == Feedthrough::Auto ? "auto" : ft == Feedthrough::Yes ? "yes" : "no";
    j["included"] = included;
    if (p >= 0) j["lr_p_value"] = p; else j["lr_p_value"] = nullptr;
    return j;
}

// Everything one fit carries from step to step, in the order the document is built.
struct Fit {
    const FrfData &f;
    const FitRequest &rq;
    const Report &report;
    FitOutcome out;
    Domain d = Domain::DT;
    Weight wt = Weight::Cov;
    bool known = false, weighted = true, smoothed = false, pool = false;
    bool no_cov = false;   // the FRF has no covariance: unit weights by default, no noise scale
    std::vector<WeightedLine> w, w_line, w_pool;   // the fit's weights, each line's own, pooled (subspace)
    PoolStats pstats;
    Feedthrough ft = Feedthrough::Auto;
    bool allow_unstable = false, enforced_stable = true;
    Json doc, settings, extra;
    SSModel ss;
    int nparams = 0;
    std::vector<MatC> Gm, Gc;
    bool have_cov = false;
    double V = 0, neq = 0;
    bool converged = true;
    double grad_norm = 0.0;
    int iterations = 0;
    Fit(const FrfData &f_, const FitRequest &rq_, const Report &r_) : f(f_), rq(rq_), report(r_) {}

    void note(const std::string &s) { add_note(out, report, s); }
    // an ml result (either parametrisation): parameters, model FRF with covariance, convergence
    template <class R> void take(const R &r)
    {
        nparams = (int)r.theta.size();
        Gm = r.G;
        Gc = r.Gcov;
        have_cov = true;
        converged = r.converged;
        grad_norm = r.grad_norm;
        iterations = r.iterations;
    }
};

// --domain dt|ct (default: the file's domain); a CT model of a DT file needs the file's sample time
// (a CT file without one, an analogue instrument's, has its lines in rad/s).
Domain parse_domain(const FitRequest &rq, const FrfData &f)
{
    Domain d = f.domain;
    if (!rq.domain.empty()) d = msidutil::parse_enum(rq.domain, "--domain", {"dt", "ct"}) == 0 ? Domain::DT : Domain::CT;
    if (d == Domain::CT && f.h <= 0 && f.domain != Domain::CT)
        throw Error("a continuous-time model needs the sample time of the FRF file (give " MSID_OPT("fs") " to msid frf)");
    return d;
}

Feedthrough parse_feedthrough(const FitRequest &rq)
{
    if (rq.no_d) {
        if (!rq.feedthrough.empty() && rq.feedthrough != "no")
            throw UsageError(MSID_OPT("no_d") " contradicts " MSID_OPT("feedthrough") " " + rq.feedthrough);
        return Feedthrough::No;
    }
    if (rq.feedthrough.empty()) return Feedthrough::Auto;
    const Feedthrough v[] = {Feedthrough::Auto, Feedthrough::Yes, Feedthrough::No};
    return v[msidutil::parse_enum(rq.feedthrough, "--feedthrough", {"auto", "yes", "no"})];
}

// --order n of the fixed-order methods (positive).
int order_value(const FitRequest &rq)
{
    const uint32_t n = msidutil::parse_u32(rq.order, "--order");
    if (n > MAX_STATES) throw UsageError(fmt(MSID_OPT("order") " %u is too large (at most %u states)", n, MAX_STATES));
    return (int)n;
}

// Weights (--weight, --noise-var) and the pooling of neighbouring lines (--weight-smooth).
void weigh_lines(Fit &c)
{
    const FitRequest &rq = c.rq;
    const FrfData &f = c.f;
    c.d = parse_domain(rq, f);
    // An FRF without any covariance (one measured by another tool, msid import) is fitted with unit
    // weights unless a weight is asked for: said once, and the cost then has no p-value (cost_block).
    bool any_cov = false;
    for (const auto &l : f.lines) any_cov = any_cov || l.cov.size() > 0;
    c.no_cov = !any_cov && rq.weight.empty() && !rq.noise_var;
    const bool no_cov = c.no_cov;
    const std::string wname = no_cov ? "none" : rq.weight.empty() ? "cov" : rq.weight;
    c.wt = WEIGHTS[msidutil::parse_enum(wname, "--weight", WEIGHT_NAMES)];
    if (no_cov)
        c.note("note: '" + f.path + "' has no FRF covariance: an unweighted fit (unit weights); the cost has no noise "
               "scale, so no p-value and no standard deviations that mean anything");
    const double noise_var = rq.noise_var.value_or(0.0);
    if (rq.noise_var && !(noise_var > 0)) throw UsageError(MSID_OPT("noise_var") " must be positive");
    c.w = weigh(f, c.d, c.wt, noise_var);
    c.known = noise_var > 0;
    const std::string &method = rq.method;
    const int wsmooth = (int)rq.weight_smooth.value_or((uint32_t)ML_WEIGHT_SMOOTH);
    if (!rq.start.empty() && method != "ml")
        throw UsageError(MSID_OPT("start") " belongs to " MSID_OPT("method") " ml (subspace|sk for " MSID_OPT("param") " lmfd, a model file for " MSID_OPT("param") " poles)");
    if (rq.weight_smooth && ((method != "ml" && method != "subspace") || c.wt == Weight::None || c.known))
        throw UsageError(MSID_OPT("weight_smooth") " belongs to " MSID_OPT("method") " ml or subspace with estimated weights "
                         "(" MSID_OPT("weight") " cov|known-input)");
    // Pooling needs the window to be a small part of the band: by default only with at least
    // ML_WEIGHT_SMOOTH_MIN_WINDOWS windows of lines (docs/fitting.md, "Pooled weights").
    const bool dense = c.w.size() >= (size_t)ML_WEIGHT_SMOOTH_MIN_WINDOWS * (size_t)(2 * wsmooth + 1);
    c.pool = c.wt != Weight::None && !c.known && wsmooth > 0 && (rq.weight_smooth || dense);
    c.smoothed = method == "ml" && c.pool;
    const size_t pblock = pool_block(f, c.wt);
    if (c.smoothed) { c.w_line = c.w; c.pstats = smooth_weights(c.w, wsmooth, pblock); }
    // subspace: the r scan on each line's covariance, the refinement on pooled ones (docs/fitting.md)
    if (method == "subspace" && c.pool) { c.w_pool = c.w; c.pstats = smooth_weights(c.w_pool, wsmooth, pblock); }
    // no line pooled (precise own weights, or covariances that change): the per-line fit, bit for bit
    if (c.pool && c.pstats.pooled == 0) {
        c.smoothed = false;
        c.w_line.clear();
        c.w_pool.clear();
    }
    c.doc = model_head(f.path, c.d, f.h, method);
    c.settings["weight"] = wname;
    if (no_cov) c.settings["weight_reason"] = "the FRF file has no covariance: unit weights, no p-value";
    if (c.d == Domain::CT && f.h <= 0)
        c.settings["frequency_axis"] =
            "continuous time without a sample time: the lines' omega (rad/s) as the file gives them; the bilinear "
            "map of subspace and the scaling of the polynomial coefficients use the geometric mean of the band "
            "(a numerical device: the model is continuous-time, in rad/s)";
    if (c.pool && (method == "ml" || method == "subspace")) {
        c.settings["weight_smooth"] = wsmooth;
        // which lines pooled (docs/fitting.md "Pooled weights": imprecise own weights, equal covariance)
        c.settings["weight_pooling"] = Json{{"complex_lines", c.pstats.lines}, {"pooled", c.pstats.pooled},
                                            {"precise_own_weights", c.pstats.precise},
                                            {"neighbours_left_out", c.pstats.left_out}};
    }
    if (c.known) c.settings["noise_var"] = noise_var;
    for (const auto &l : c.w) c.neq += (l.real ? 1.0 : 2.0) * (double)f.g();
    c.ft = parse_feedthrough(rq);
    c.settings["feedthrough"] = rq.no_d ? "no" : rq.feedthrough.empty() ? "auto" : rq.feedthrough;
    c.weighted = c.wt != Weight::None;
    if (method != "lmfd" && c.weighted) check_weight_periods(c.smoothed ? c.w_line : c.w, f, false);
}

// Stable models by default (subspace and ml, both parametrisations): the test that kept unstable
// poles when the data "needed" them assumes the model is right, and a model whose cost is rejected
// (nonlinear distortion, an order too low) makes it meaningless. --allow-unstable is for plants
// that are unstable (measured in closed loop). settings.stability names the rule that applied.
void stability_rule(Fit &c)
{
    const FitRequest &rq = c.rq;
    if (rq.stable && rq.allow_unstable) throw UsageError(MSID_OPT("stable") " contradicts " MSID_OPT("allow_unstable"));
    c.allow_unstable = rq.allow_unstable;
    c.settings["stability"] = c.allow_unstable ? "allow-unstable" : rq.stable ? "stable" : "stable (default)";
    c.enforced_stable = !c.allow_unstable && rq.method != "lmfd";
    if (rq.method == "lmfd" && (rq.stable || c.allow_unstable))
        throw UsageError(MSID_OPT("stable") " and " MSID_OPT("allow_unstable") " belong to " MSID_OPT("method") " subspace and ml: the closed-form lmfd "
                         "interpolates the data, whatever its poles");
    if (rq.method == "lmfd") c.settings.erase("stability");
    if (rq.method != "subspace" && !rq.refine.empty()) throw UsageError(MSID_OPT("refine") " belongs to " MSID_OPT("method") " subspace");
}

void fit_by_subspace(Fit &c)
{
    const FitRequest &rq = c.rq;
    const size_t nu = c.f.nu, ny = c.f.ny;
    SubspaceOptions o;
    o.order = rq.order.empty() ? 0 : order_value(rq);
    if (!rq.order.empty() && o.order == 0) throw UsageError(MSID_OPT("order") " must be positive");
    o.r = (int)rq.r.value_or(0);
    o.stable = rq.stable;
    o.stable_auto = !c.allow_unstable;
    // --refine ml|none as for cissim (the LM steps lower the weighted cost (35), the ML cost of
    // Gaussian FRF errors); a number is the step budget (ml = 30, none = 0)
    const std::string rspec = rq.refine.empty() ? "ml" : rq.refine;
    if (rspec != "ml" && rspec != "none" && (rspec.empty() || rspec.find_first_not_of("0123456789") != std::string::npos))
        throw UsageError(MSID_OPT("refine") " must be ml, none or a number of steps (got '" + rspec + "')");
    o.refine_iter = rspec == "ml" ? 30 : rspec == "none" ? 0 : (int)msidutil::parse_u32(rspec, "--refine");
    o.estimate_D = c.ft != Feedthrough::No;
    o.feedthrough_auto = c.ft == Feedthrough::Auto;
    if (!c.w_pool.empty()) o.refine_w = &c.w_pool;
    const SubspaceResult r = fit_subspace(c.f, c.d, c.w, c.weighted, o);
    c.ss = r.model;
    c.enforced_stable = o.stable || o.stable_auto;
    c.V = r.cost;
    const int n = (int)c.ss.n();
    c.nparams = n * (int)(nu + ny) + (r.feedthrough ? (int)(nu * ny) : 0);
    c.settings["r"] = r.r;
    c.settings["stable"] = o.stable;
    c.settings["estimate_D"] = r.feedthrough;
    if (c.d == Domain::CT) c.settings["wscale"] = r.wscale;
    Json sub;
    sub["singular_values"] = r.sv;
    Json sc = Json::array();
    for (auto &x : r.scan) sc.push_back(Json::array({x.first, x.second}));
    sub["r_scan"] = sc;
    sub["reflected_poles"] = r.reflected;
    Json rf;
    rf["max_steps"] = o.refine_iter;
    rf["steps"] = r.refine_steps;
    rf["cost_before"] = r.cost_unrefined >= 0 ? Json(r.cost_unrefined) : Json(nullptr);
    sub["refine"] = rf;
    sub["stable_mode"] = o.stable ? "yes" : o.stable_auto ? "default" : "no";
    sub["unconstrained_cost"] = r.cost_unconstrained >= 0 ? Json(r.cost_unconstrained) : Json(nullptr);
    sub["stability_lr_p_value"] = r.stable_lr_p >= 0 ? Json(r.stable_lr_p) : Json(nullptr);
    c.extra["subspace"] = sub;
    if (r.stable_lr_p >= 0 && r.stable_lr_p < 0.01)
        c.note(fmt("note: the unconstrained model (unstable) has a significantly lower cost (likelihood ratio p = "
                   "%.3g); for a stable plant that is model error (nonlinear distortion, the order), for an unstable "
                   "one (measured in closed loop) refit with --allow-unstable",
                   r.stable_lr_p));
    c.extra["feedthrough"] = feedthrough_json(c.ft, r.feedthrough, r.feedthrough_p);
    // the model at every line: a solve of the model's order per line (seconds at order 200 on 1000 lines)
    for (const auto &l : c.w) {
        c.Gm.push_back(ss_eval(c.ss, l.x));
        msidutil::checkpoint(msidutil::Step::lines, 1, "the subspace fit");
    }
}

// --start MODEL.json of ml --param poles: the model's poles (its pole_residue block, else the eigenvalues
// of A) as pole_list stores them. The model must describe the fit's frequencies: the same domain and, in
// DT, the same sample time. Its inputs and outputs may differ (the poles are common to every entry).
std::vector<cd> model_start_poles(const std::string &path, Domain d, double h)
{
    if (path == "subspace" || path == "sk")
        throw UsageError(MSID_OPT("start") " " + path + " chooses the start of " MSID_OPT("param") " lmfd; " MSID_OPT("param") " poles runs every start "
                         "(vector fitting, relaxed vector fitting, subspace at several r) and keeps the best; "
                         MSID_OPT("start") " MODEL.json refines a model from its poles");
    ModelFile mf;
    try {
        mf = read_model(path);
    } catch (const msidfrf::IoError &e) {   // missing, unreadable, a directory: stays a file error
        throw msidfrf::IoError(std::string("--start: ") + e.what());
    } catch (const FitError &e) {
        throw FitError(std::string("--start: ") + e.what());
    }
    if (mf.domain != d)
        throw FitError(fmt("the start model '%s' is %s and the fit %s (--domain): its poles are in another variable",
                           path.c_str(), mf.domain == Domain::CT ? "continuous-time" : "discrete-time",
                           d == Domain::CT ? "continuous-time" : "discrete-time"));
    if (d == Domain::DT && mf.h > 0 && h > 0 && std::abs(mf.h - h) > 1e-9 * h)
        throw FitError(fmt("the start model '%s' was fitted at sample time %g s and the FRF has %g s", path.c_str(),
                           mf.h, h));
    std::vector<cd> p = mf.poles.empty() ? pole_list(ss_eigenvalues(mf.ss.A)) : mf.poles;
    if (p.empty()) throw FitError("the start model '" + path + "' has no poles (order 0)");
    // a pole repeated (to rounding) is one pole of the start: the pole-residue form gives each pole a full
    // residue matrix, and the realisation of a model with several inputs (msid's pole-residue and multi
    // models) repeats each pole once per input in A; kept twice, the start would double the order with
    // coincident poles whose residues no data separate
    std::vector<cd> u;
    for (const cd &z : p) {
        bool seen = false;
        for (const cd &q : u) seen = seen || std::abs(z - q) <= 1e-9 * std::max(std::abs(z), 1e-300);
        if (!seen) u.push_back(z);
    }
    return u;
}

// ml parametrisation: --param poles|lmfd; default poles, except the LMFD for DT with several inputs
// (full-rank residue matrices would multiply the state order by the number of inputs).
bool use_poles(const FitRequest &rq, Domain d, size_t nu)
{
    const std::string def = d == Domain::DT && nu > 1 ? "lmfd" : "poles";
    return msidutil::parse_enum(rq.param.empty() ? def : rq.param, "--param", {"poles", "lmfd"}) == 0;
}

void fit_by_ml_poles(Fit &c)
{
    const FitRequest &rq = c.rq;
    const Domain d = c.d;
    if (rq.nd || rq.nn || !rq.pins.empty())
        throw UsageError(MSID_OPT("nd") "/" MSID_OPT("nn") "/" MSID_OPT("pin") " belong to the LMFD parametrisation: add " MSID_OPT("param") " lmfd");
    PrOptions po;
    if (!rq.order.empty()) {
        po.order = order_value(rq);
        if (po.order == 0) throw UsageError(MSID_OPT("order") " must be positive");
    }
    if (!rq.start.empty()) {   // refine a model: its poles are the only start (docs/fitting.md, "Starting from a model")
        const std::string &sp = rq.start;
        po.pole_starts.push_back({"model", model_start_poles(sp, d, c.f.h)});
        int cnt = 0;
        for (const cd &p : po.pole_starts.back().second) cnt += p.imag() > 0 ? 2 : 1;
        if (rq.order.empty()) po.order = cnt;
        else if (po.order != cnt)
            throw UsageError(fmt(MSID_OPT("order") " %d and the start model '%s' has %d distinct poles (pairs count twice): "
                                 "give its order or leave " MSID_OPT("order") " out", po.order, sp.c_str(), cnt));
        c.settings["start"] = sp;
    }
    if (po.order == 0) throw UsageError("give " MSID_OPT("order"));
    // the step rules of the LMFD refinement: given here they were taken and ignored
    if (rq.delta || rq.beta)
        throw UsageError(MSID_OPT("delta") " and " MSID_OPT("beta") " are the step rules of " MSID_OPT("param") " lmfd; the pole-residue fit (" MSID_OPT("param") " poles) "
                         "takes neither");
    // --weight none: the cost has no noise scale for the likelihood-ratio test, auto keeps D (as subspace)
    po.feedthrough = c.ft == Feedthrough::Auto && !c.weighted ? Feedthrough::Yes : c.ft;
    po.stable = !c.allow_unstable;
    po.known_noise = c.known;
    po.max_iter = (int)rq.max_iter.value_or((uint32_t)po.max_iter);
    if (c.smoothed) po.subspace_scan_w = &c.w_line;   // subspace's r scan on each line's own weights, as msid fit
    const PrResult r = fit_ml_poles(c.f, d, c.w, c.weighted, po);
    c.ss = pr_to_ss(r.model);
    c.settings["param"] = "poles";
    c.settings["stable"] = po.stable;
    c.settings["max_iter"] = po.max_iter;
    c.extra["parameters"] = model_params(r.names, r.theta, r.cov, r.cov_rank, &r.cov_factor);
    // the poles held on the stability bound: their damping is the constraint's, with no variance in cov
    Json held = Json::array(), pl = Json::array(), rl = Json::array();
    for (size_t k = 0; k < r.model.poles.size(); ++k) {
        const bool b = k < r.at_bound.size() && r.at_bound[k];
        pl.push_back(Json{{"re", r.model.poles[k].real()}, {"im", r.model.poles[k].imag()}, {"at_bound", b}});
        rl.push_back(cmat_json(r.model.R[k]));
        if (b) held.push_back("p" + std::to_string(k + 1));
    }
    c.extra["parameters"]["at_bound"] = held;
    Json pj;
    pj["variable"] = d == Domain::CT ? "s" : "z";
    pj["poles"] = pl;
    pj["residues"] = rl;
    pj["D"] = rmat_json(r.model.D);
    c.extra["pole_residue"] = pj;
    Json st = Json::array();
    for (const auto &x : r.starts) st.push_back(Json{{"start", x.name}, {"cost", x.cost}});
    c.extra["starts"] = st;
    c.extra["best_start"] = r.best_start;
    c.extra["reflected_poles"] = r.reflected;
    c.extra["feedthrough"] = feedthrough_json(c.ft, r.model.feedthrough, r.feedthrough_lr_p);
    c.take(r);
    c.V = r.cost;
}

// ML of an LMFD from the subspace or the SK start. The subspace start is the model `msid fit --method
// subspace` writes at this order (r scan on `w_scan`, each line's own covariance; refined on `w`, the
// weights ml minimises; stable unless `stable` is off), in DT carried over exactly into the LMFD, so ml
// never ends above it; in CT (or when the conversion does not exist) fitted by SK to its FRF.
MlResult lmfd_ml_from(const FrfData &f, Domain d, const std::vector<WeightedLine> &w,
                      const std::vector<WeightedLine> &w_scan, bool weighted, const LmfdSpec &s,
                      const std::string &start, MlOptions mo, bool known, bool stable)
{
    const size_t ny = f.ny;
    LmfdModel st;
    mo.stable = stable;
    if (start == "subspace") {
        SubspaceOptions so;
        so.order = s.nD * (int)ny;
        so.estimate_D = !(d == Domain::CT && s.nN < s.nD);
        so.refine_iter = 30;
        so.stable_auto = stable;
        if (&w_scan != &w) so.refine_w = &w;
        const SubspaceResult sr = fit_subspace(f, d, w_scan, weighted && min_dof(w_scan) >= 3, so);
        if (!(d == Domain::DT && s.nN == s.nD && ss_to_lmfd_dt(sr.model, s.nD, st))) {
            std::vector<MatC> target;
            for (const auto &l : w) {
                target.push_back(ss_eval(sr.model, l.x));
                msidutil::checkpoint(msidutil::Step::lines, 1, "the lmfd fit");
            }
            st = lmfd_sk(w, d, f.h, s, 30, &target);
        }
    } else {
        st = lmfd_sk(w, d, f.h, s, 30);
    }
    return lmfd_ml(w, d, f.h, s, st, mo, known);
}

// The LMFD's degrees from --nd/--nn or --order and --feedthrough; `auto_nn`: ml tests nN = nD - 1.
LmfdSpec lmfd_spec(const Fit &c, bool &auto_nn)
{
    const FitRequest &rq = c.rq;
    const Domain d = c.d;
    const size_t ny = c.f.ny;
    LmfdSpec s;
    auto_nn = false;
    if (rq.nd || rq.nn) {
        if (!rq.order.empty()) throw UsageError("give " MSID_OPT("order") " or " MSID_OPT("nd") "/" MSID_OPT("nn") ", not both");
        for (auto [v, name] : {std::make_pair(rq.nd, "--nd"), std::make_pair(rq.nn, "--nn")})
            if (v && *v > MAX_STATES) throw UsageError(fmt("%s %u is too large (at most %u)", name, *v, MAX_STATES));
        s.nD = (int)rq.nd.value_or(1);
        s.nN = rq.nn ? (int)*rq.nn : (d == Domain::CT ? s.nD - 1 : s.nD);
    } else if (!rq.order.empty()) {
        const uint32_t n = msidutil::parse_u32(rq.order, "--order");
        if (n == 0 || n % ny) throw UsageError(MSID_OPT("order") " must be a positive multiple of the number of outputs for an LMFD");
        if (n > MAX_STATES) throw UsageError(fmt(MSID_OPT("order") " %u is too large (at most %u states)", n, MAX_STATES));
        s.nD = (int)(n / ny);
        // properness from --feedthrough: CT yes -> nN = nD (direct term), no -> nN = nD - 1,
        // auto -> both, kept by a likelihood-ratio test; DT: the direct term is N_0 (pinned to 0 for no)
        s.nN = d == Domain::CT && c.ft == Feedthrough::No ? s.nD - 1 : s.nD;
        if (d == Domain::DT && c.ft == Feedthrough::No) s.pins.push_back(parse_pin("N0=0"));
        // --weight none: the cost has no noise scale for the test, auto keeps D (as subspace)
        auto_nn = d == Domain::CT && c.ft == Feedthrough::Auto && rq.method == "ml" && c.weighted;
    } else {
        throw UsageError("give " MSID_OPT("order") " or " MSID_OPT("nd") "/" MSID_OPT("nn"));
    }
    if (s.nN < 0) s.nN = 0;
    for (const auto &p : rq.pins) s.pins.push_back(parse_pin(p));
    return s;
}

// The closed form (Gonzalez et al. 2025 Thm 6): minimum-norm solution, kernel basis.
LmfdModel fit_lmfd_closed(Fit &c, const LmfdSpec &s, const MlOptions &mo)
{
    const size_t ny = c.f.ny, nu = c.f.nu;
    c.settings["nD"] = s.nD;
    c.settings["nN"] = s.nN;
    const ClosedForm cf = lmfd_closed_form(c.w, c.d, c.f.h, s);
    c.extra["kernel"] = rmat_json(cf.kernel);
    Json names = Json::array();
    const auto nm = lmfd_param_names(s, ny, nu);
    for (size_t i = 0; i < (size_t)cf.unknowns; ++i)
        names.push_back(nm[i].substr(0, nm[i].find('[')) + "[k," + nm[i].substr(nm[i].find(',') + 1));
    c.extra["kernel_rows"] = names;
    c.extra["equations_per_row"] = cf.equations;
    c.extra["unknowns_per_row"] = cf.unknowns;
    c.extra["unique"] = cf.unique;
    if (cf.unique) {
        const MlResult ev = lmfd_evaluate(c.w, c.d, c.f.h, s, cf.model, mo, c.known);
        c.extra["parameters"] = model_params(ev.names, ev.theta, ev.cov, ev.cov_rank, &ev.cov_factor);
        c.nparams = (int)ev.theta.size();
    } else {
        c.nparams = (int)(cf.equations * ny);
        // more unknowns than equations: the lines are interpolated exactly by every model of a family
        // (the kernel), so the residual has no degree of freedom and the order says nothing of the plant
        c.note(fmt("the LMFD with nD = %d, nN = %d has %d unknowns per output row for %d real interpolation "
                   "equations: one of a %d-dimensional family of models that pass through every line (dof 0, the "
                   "cost tests nothing); a lower order, or --method ml, fits the plant",
                   s.nD, s.nN, cf.unknowns, cf.equations, cf.unknowns - cf.equations));
    }
    // an interpolating model reproduces the FRF: its covariance at the lines is the data's (Cor. 3)
    for (const auto &l : c.w) { c.Gm.push_back(lmfd_eval(cf.model, l.x)); c.Gc.push_back(l.cov); }
    c.have_cov = true;
    c.settings["wscale"] = s.wscale;
    return cf.model;
}

// ml of the LMFD (eq. 40) with the bounds (45)-(46); with auto_nn the direct term by a LR test.
LmfdModel fit_lmfd_ml(Fit &c, LmfdSpec s, bool auto_nn, const MlOptions &mo)
{
    const size_t ny = c.f.ny, nu = c.f.nu;
    const std::string start = c.rq.start.empty() ? "subspace" : c.rq.start;   // subspace|sk (others refused)
    c.settings["start"] = start;
    const std::vector<WeightedLine> &w_scan = c.smoothed ? c.w_line : c.w;
    MlResult r = lmfd_ml_from(c.f, c.d, c.w, w_scan, c.weighted, s, start, mo, c.known, !c.allow_unstable);
    double lr_p = -1;
    if (auto_nn) {
        LmfdSpec s0 = s;
        s0.nN = s.nD - 1;
        const MlResult r0 = lmfd_ml_from(c.f, c.d, c.w, w_scan, c.weighted, s0, start, mo, c.known, !c.allow_unstable);
        lr_p = chi2_sf((double)(ny * nu), std::max(0.0, 2.0 * (r0.cost - r.cost)));
        if (lr_p >= 0.01) { r = r0; s = s0; }
    }
    c.settings["nD"] = s.nD;
    c.settings["nN"] = s.nN;
    c.extra["feedthrough"] = feedthrough_json(c.ft, s.nN == s.nD, lr_p);
    c.extra["cost_start"] = r.cost_start;
    if (!c.allow_unstable && !r.stable_constrained) {
        // the start (SK, or an SK fit to the subspace model) has unstable poles: no stable path
        c.enforced_stable = false;
        c.settings["stability"] = "not enforced: unstable start";
        c.note("warning: the LMFD start is unstable, so ml could not keep the model stable; --param poles constrains "
               "every start");
    }
    c.extra["parameters"] = model_params(r.names, r.theta, r.cov, r.cov_rank, &r.cov_factor);
    Json b;
    b["delta"] = mo.delta;
    b["beta"] = mo.beta;
    b["frf"] = r.frf_bound;
    b["theta"] = r.theta_bound;
    b["lambda_max_cov"] = r.lambda_max_cov;
    b["sigma_min_jacobian"] = r.sigma_min_J;
    b["jacobian_rank"] = r.sigma_rank;
    b["valid_if"] = "Gonzalez et al. 2025 Theorem 5: Gaussian white noise of known covariance, whole "
                    "periods, no undermodelling; theta bound also needs the estimate inside the ball "
                    "where the Jacobian stays within (1-beta) sigma_min of its value";
    c.extra["bounds"] = b;
    c.take(r);
    c.settings["max_iter"] = mo.max_iter;
    return r.model;
}

// lmfd, and ml --param lmfd: the fraction, then its state-space realisation.
void fit_by_lmfd(Fit &c)
{
    const FitRequest &rq = c.rq;
    const size_t ny = c.f.ny, nu = c.f.nu;
    if (rq.method == "ml" && !rq.start.empty() && rq.start != "subspace" && rq.start != "sk")
        throw UsageError(MSID_OPT("start") " " + rq.start + ": " MSID_OPT("param") " lmfd starts from subspace or sk; a model file is refined "
                         "in the pole-residue form: add " MSID_OPT("param") " poles" +
                         (rq.param.empty() ? std::string(" (ml's default for discrete time with several inputs is lmfd)")
                                           : std::string()));
    bool auto_nn = false;
    const LmfdSpec s = lmfd_spec(c, auto_nn);
    Json pins = Json::array();
    for (const auto &p : rq.pins) pins.push_back(p);
    c.settings["pins"] = pins;
    if (rq.method == "ml") c.settings["param"] = "lmfd";
    MlOptions mo;
    mo.max_iter = (int)rq.max_iter.value_or((uint32_t)mo.max_iter);
    mo.delta = rq.delta.value_or(mo.delta);
    mo.beta = rq.beta.value_or(mo.beta);
    if (!(mo.delta > 0 && mo.delta <= 1) || !(mo.beta > 0 && mo.beta < 1))
        throw UsageError(MSID_OPT("delta") " must be in (0, 1] and " MSID_OPT("beta") " in (0, 1)");
    const LmfdModel lm = rq.method == "lmfd" ? fit_lmfd_closed(c, s, mo) : fit_lmfd_ml(c, s, auto_nn, mo);
    try {
        c.ss = lmfd_to_ss(lm);
    } catch (const FitError &) {
        c.ss = SSModel();   // no proper realisation (e.g. improper LMFD): LMFD only
        c.ss.domain = c.d;
        c.ss.A = MatR(0, 0); c.ss.B = MatR(0, nu); c.ss.C = MatR(ny, 0); c.ss.D = MatR::Zero(ny, nu);
        c.extra["realisation"] = "none: the LMFD is improper";
    }
    c.extra["lmfd"] = model_lmfd(lm);
    c.V = weighted_cost_lmfd(lm, c.w);
}

// LPM files: the fitted model's cost over every (2W+1)-th line (independent) with the cost law
// of those lines: validate's statistic (validation_stat.hpp); null when the file has no usable
// covariance.
Json lpm_independent_cost(const FrfData &f, Domain d, const std::vector<MatC> &Gm, int nparams)
{
    std::vector<WeightedLine> wc;
    try {
        wc = weigh(f, d, Weight::Cov);
    } catch (const FitError &) {
        return nullptr;
    }
    if (Gm.size() != wc.size()) return nullptr;
    const ValidationStat vs = validation_stat(wc, Gm, nparams, lpm_line_stride(f), (double)f.ny, false);
    if (!(vs.dof > 0)) return nullptr;
    Json c;
    c["value"] = vs.cost;
    c["expected"] = vs.expected;
    c["dof"] = vs.dof;
    if (std::isfinite(vs.p_value)) c["p_value"] = vs.p_value; else c["p_value"] = nullptr;
    c["line_stride"] = vs.stride;
    return c;
}

// The cost block always comes from the FRF covariance when the file has one, whatever weighting
// the fit used: an unweighted fit's p-value would otherwise depend on the units of the data.
Json cost_block(const Fit &c)
{
    const FrfData &f = c.f;
    const size_t ny = f.ny;
    const double dof = c.neq - c.nparams;
    Json cost = model_cost(c.V, dof, c.known || c.wt == Weight::None ? 1e300 : min_dof(c.w), (double)ny);
    cost["weight"] = c.settings["weight"];
    if (c.smoothed) {
        // the p-value from each line's own covariance (as validate computes it); the fit's own cost beside it
        cost = model_cost(cost_at(c.w_line, c.Gm), dof, min_dof(c.w_line), (double)ny);
        cost["weight"] = c.settings["weight"];
        cost["fit_cost_smoothed_weights"] = c.V;
    } else if (c.wt == Weight::None) {
        try {
            const auto wc = weigh(f, c.d, Weight::Cov);
            if (c.Gm.size() == wc.size() && min_dof(wc) <= (double)ny) {
                // a covariance from too few periods (dof <= outputs: the weighted cost has no finite
                // expectation, which is why --weight none was needed): no p-value, said so
                cost["p_value"] = nullptr;
                cost["note"] = fmt("the FRF covariance has %.3g dof at the fewest, at most the %zu outputs: the "
                                   "weighted cost has no finite expectation; unit weights, no p-value",
                                   min_dof(wc), ny);
            } else if (c.Gm.size() == wc.size()) {
                cost = model_cost(cost_at(wc, c.Gm), dof, min_dof(wc), (double)ny);
                cost["weight"] = "cov";
                cost["fit_cost_unweighted"] = c.V;
            }
        } catch (const FitError &) {
            // no usable covariance in the file: the unit-weight cost has no noise scale, so no p-value
            // (it printed "p = 1" against an expectation of half the real dof)
            cost["p_value"] = nullptr;
            cost["note"] = "no usable FRF covariance: unit weights, no p-value";
        }
    }
    if (f.method == "lpm") {   // neighbouring LPM lines are correlated: the p-value of independent lines
        const Json ic = lpm_independent_cost(f, c.d, c.Gm, c.nparams);
        if (!ic.is_null()) cost["independent_lines"] = ic;
    }
    return cost;
}

// An FRF without any covariance (another tool's): the unit-weight fit's covariances assume unit noise.
// Scaled by the residual variance per complex FRF entry, s^2 = 2 V / (neq - n_params) (unit noise gives
// E V = (neq - n_params) / 2: cost_law), as an unweighted least-squares fit estimates its noise, the
// parameters' and the model FRF's covariances, hence the modes' standard deviations, rest on the data:
// right for one noise level at every line and entry and a model that is right (the residuals are then
// noise). Returns s^2 (0: no residual dof, nothing scaled).
double scale_by_residual_variance(Fit &c)
{
    const double dof = c.neq - c.nparams;
    if (!(dof > 0) || !(c.V >= 0)) return 0.0;
    const double s2 = 2.0 * c.V / dof;
    for (MatC &g : c.Gc) g *= s2;
    if (c.extra.contains("parameters") && c.extra["parameters"].contains("cov"))
        for (Json &row : c.extra["parameters"]["cov"])
            for (Json &v : row)
                if (v.is_number()) v = v.get<double>() * s2;
    return s2;
}

// The document after the fit: the model, its stability, the method's sections, cost, FRF, modes.
void finish_document(Fit &c)
{
    const FrfData &f = c.f;
    Json &doc = c.doc;
    const double s2 = c.no_cov ? scale_by_residual_variance(c) : 0.0;
    if (s2 > 0) c.extra["residual_variance"] = s2;
    if (c.rq.method == "ml") {
        c.extra["converged"] = c.converged;
        c.extra["gradient_norm"] = c.grad_norm;
        c.extra["iterations"] = c.iterations;
    }
    model_put_ss(doc, c.ss, (int)c.ss.n(), f.nu, f.ny, c.settings);
    model_put_signals(doc, f.input_names, f.output_names, f.input_units, f.output_units);
    // balanced eigenvalues: the same poles as the modal table
    doc["stability"] = model_stability(c.ss, c.enforced_stable, c.ss.A.rows() ? ss_eigenvalues(c.ss.A) : VecC());
    doc["n_params"] = c.nparams;
    for (auto it = c.extra.begin(); it != c.extra.end(); ++it) doc[it.key()] = it.value();
    doc["cost"] = cost_block(c);
    Json fr = Json::array();
    for (size_t l = 0; l < f.lines.size(); ++l)
        fr.push_back(model_frf_line(f.lines[l].bin, f.lines[l].freq, f.lines[l].omega, c.Gm[l],
                                    c.have_cov ? &c.Gc[l] : nullptr));
    doc["frf"] = fr;
    model_put_modes(doc, &c.out.before);   // modal parameters with standard deviations
    if (c.no_cov && doc.contains("modes"))
        c.out.before += s2 > 0 ? fmt("note: the FRF has no covariance: the standard deviations above rest on the fit's "
                                     "residual variance (%.3g per FRF entry: one noise level everywhere, and the "
                                     "residuals are noise only when the model is right)\n", s2)
                               : "note: the FRF has no covariance and the fit no residual dof: the standard "
                                 "deviations above take unit noise on every line, they are not the data's "
                                 "uncertainty\n";
}

// What msid prints of the fit: "wrote PATH: ml fit, order 4, weighted cost ...".
void summarise(Fit &c)
{
    const Json &doc = c.doc;
    const size_t nu = c.f.nu;
    // ml in the pole-residue form with several inputs: --order counts poles, the realisation repeats
    // each per input (state order n nu); "order 48" alone after --order 24 read as a different model
    const bool repeated = doc.contains("pole_residue") && nu > 1;
    int npoles = 0;   // pairs are stored once (Im > 0)
    if (repeated)
        for (const auto &p : doc["pole_residue"]["poles"]) npoles += p["im"].get<double>() != 0.0 ? 2 : 1;
    const std::string order_txt = repeated ? fmt("order %d (%d poles; state order %d: each pole once per input)",
                                                 npoles, npoles, (int)c.ss.n())
                                           : fmt("order %d", (int)c.ss.n());
    // unit weights without any covariance (another tool's FRF): the cost has no noise scale, hence no
    // expectation to set it against
    const bool no_scale = c.wt == Weight::None && doc["cost"]["p_value"].is_null() && doc["cost"].contains("note");
    if (no_scale)
        c.out.tail = fmt(": %s fit, %s, unweighted cost %.6g (no covariance: no expectation, no p-value)%s\n",
                         c.rq.method.c_str(), order_txt.c_str(), doc["cost"]["value"].get<double>(),
                         doc["stable"].get<bool>() ? "" : ", UNSTABLE");
    else
        c.out.tail = fmt(": %s fit, %s, weighted cost %.6g (expected %.6g, %s)%s\n", c.rq.method.c_str(),
                         order_txt.c_str(), doc["cost"]["value"].get<double>(), doc["cost"]["expected"].get<double>(),
                         doc["cost"]["p_value"].is_null() ? "no p-value"
                                                          : fmt("p = %.3g", doc["cost"]["p_value"].get<double>()).c_str(),
                         doc["stable"].get<bool>() ? "" : ", UNSTABLE");
    if (doc["cost"].contains("independent_lines") && !doc["cost"]["independent_lines"]["p_value"].is_null())
        c.out.after = fmt("LPM file: p = %.3g on every %d-th line (independent; the p-value msid validate gives)\n",
                          doc["cost"]["independent_lines"]["p_value"].get<double>(),
                          doc["cost"]["independent_lines"]["line_stride"].get<int>());
    c.out.converged = c.converged;
    if (!c.converged)   // V is the cost the fit minimised: with pooled weights not the cost block's (per-line weights)
        c.out.not_converged = fmt("ml did not converge in %d iterations (cost %.6g%s, gradient norm %.3g): wrote the "
                                  "best iterate to ",
                                  c.iterations, c.V, c.smoothed ? " with the pooled weights it minimises" : "",
                                  c.grad_norm);
}

}  // namespace

FitOutcome fit_frf_at_order(const FrfData &f, const FitRequest &rq, const Report &report)
{
    // multi and cissim have their own entries: listed so that a wrong name shows every method
    msidutil::parse_enum(rq.method, "--method", {"subspace", "lmfd", "ml", "multi", "cissim"});
    if (rq.method == "multi" || rq.method == "cissim")
        throw UsageError(MSID_OPT("method") " " + rq.method + " fits time records, not an FRF");
    Fit c(f, rq, report);
    try {
        weigh_lines(c);
        stability_rule(c);
        if (rq.method == "subspace") fit_by_subspace(c);
        else if (rq.method == "ml" && use_poles(rq, c.d, f.nu)) fit_by_ml_poles(c);
        else fit_by_lmfd(c);
        finish_document(c);
        summarise(c);
    } catch (const msidfrf::IoError &e) {   // a file (--start) that cannot be opened
        throw msidutil::IoError(e.what());
    } catch (const FitError &e) {
        throw Error(e.what());
    }
    c.out.model = std::move(c.doc);
    return std::move(c.out);
}

bool order_is_scan(const FitRequest &rq)
{
    if (rq.order == "auto" || rq.order.find(':') != std::string::npos) return true;
    // No order: ml chooses it (auto, as msid measure --fit), unless --nd/--nn give LMFD degrees or
    // --start MODEL.json gives the model's order. subspace keeps its own default (the singular-value
    // gap: its scan's model at the chosen order 26 of the 1x3 structure moved by 1.7e-5 in cost
    // between units, where the unit-invariance test asks 1e-6); lmfd, which interpolates at every
    // order, still asks for it.
    return rq.method == "ml" && rq.order.empty() && !rq.nd && !rq.nn &&
           (rq.start.empty() || rq.start == "subspace" || rq.start == "sk");
}

FitOutcome fit_frf(const FrfData &f, const FitRequest &rq, const Report &report)
{
    if (order_is_scan(rq)) return fit_frf_scan(f, rq, report);
    return fit_frf_at_order(f, rq, report);
}

}  // namespace msidfitjob
