// msid fit | validate | compare: parametric models from msid-frf/1 files.
#include "cli_util.hpp"
#include "commands.hpp"
#include "fit_poles.hpp"
#include "host_libs.hpp"
#include "validation_stat.hpp"

#include "lmfd_fit.hpp"
#include "poleres.hpp"
#include "model_io.hpp"
#include "stats.hpp"
#include "subspace.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <cstring>
#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace msidcli {

using namespace msidfit;

static const char *FIT_HELP =
    "Which method: ml for the model you report (weighted maximum likelihood: the best fit to the data's\n"
    "  noise, parameter standard deviations, modes with their uncertainty); subspace for a quick,\n"
    "  non-iterative model or a start; lmfd for a closed-form fit of a fraction D^-1 N (fixed entries with\n"
    "  --pin); multi for time records (ring-downs, free decays) without an FRF; cissim for periodic time\n"
    "  records in closed form. Without --order ml chooses the order (auto: stabilisation diagram, as msid\n"
    "  measure --fit does), subspace from its singular values. Check any model with msid validate.\n"
    "\n"
    "usage: msid fit --method subspace|lmfd|ml frf.json -o model.json\n"
    "                [--order n|auto|a:b | --nd K --nn J] [--domain dt|ct] [--weight cov|known-input|none]\n"
    "                [--noise-var S2] [--r R] [--stable] [--no-d] [--pin N0=0 ...] [--start subspace|sk|MODEL]\n"
    "                [--max-iter N] [--delta D] [--beta B] [--feedthrough auto|yes|no] [--param poles|lmfd]\n"
    "                [--allow-unstable] [--refine ml|none|N]\n"
    "       msid fit --method multi --experiment r1.csv ... --order n|auto -o model.json   (time records)\n"
    "\n"
    "  subspace  frequency-domain subspace (McKelvey; Pintelon 2002 Alg. 1, CT by the bilinear map,\n"
    "            Alg. 2.1) weighted by the FRF covariance; block rows r in {1.5n, 2n, 3n, 4n}, the one with the\n"
    "            smallest weighted cost (35), refined (--refine ml, the default: up to 30 Levenberg-Marquardt\n"
    "            steps; N: up to N steps; none: the bare estimate, as for cissim) on\n"
    "            that cost (never raising it); stable (constrained refinement); order from the singular values\n"
    "            when --order is omitted\n"
    "  lmfd      closed-form ML of a left matrix fraction D(p)^-1 N(p), fully or under-constrained\n"
    "            (Gonzalez et al. 2025 Thm 6): minimum-norm solution, kernel basis, --pin to fix entries\n"
    "  ml        weighted maximum likelihood (eq. 40): --param poles (default; dt with several inputs: lmfd)\n"
    "            pole-residue form from vector-fitting and subspace starts (subspace's refined model among them:\n"
    "            ml never ends above a start), scaled trust-region LM, order 40+; --param lmfd: LMFD from\n"
    "            subspace's model (default) or Sanathanan-Koerner, with bounds (45)-(46); stable models;\n"
    "            parameter covariance (pseudo-inverse Fisher information with its rank). When the iterations\n"
    "            run out the best iterate is written marked \"converged\": false and the exit status is 3\n"
    "  --start   ml --param lmfd: subspace (default) | sk; ml --param poles: MODEL.json, refine that model\n"
    "            (a previous fit, another tool's model): its poles are the only start; its order when --order\n"
    "            is left out\n"
    "  multi     time records of any lengths (ring-downs, free decays, transients), every record's initial\n"
    "            conditions eliminated (Markovsky & Pintelon): msid fit --method multi --help\n"
    "  --feedthrough auto (LR test at 1%, default) | yes | no: the direct term D (accelerations need it)\n"
    "  stable models by default (subspace, ml): a stable plant's model is stable, whatever the cost says\n"
    "  --allow-unstable  no stability constraint: for plants that are unstable (measured in closed loop)\n"
    "  --stable  the default (subspace: also reflects unstable poles in the r scan)\n"
    "  --order n     state order (ml poles: number of poles); LMFD degrees nD = n/ny, nN from --feedthrough;\n"
    "                auto (ml's default), a:b or a:step:b: order selection with a\n"
    "                stabilisation diagram (docs/fitting.md);\n"
    "                on LPM files the cost and p-value of every (2W+1)-th line, as msid validate\n"
    "  --nd, --nn    LMFD degrees (p = s for ct, p = 1/z for dt)\n"
    "  --weight      covariance for the weighting: cov (nonparametric, default), known-input, none\n"
    "  --noise-var   known white output noise variance per sample (replaces the estimated noise)\n"
    "  --weight-smooth H  ml, and subspace's refinement, with --weight cov|known-input: weights from the\n"
    "                covariance pooled over 2H+1 neighbouring lines (default H = 4 when the file has at least\n"
    "                4(2H+1) lines, else 0; 0: each line's own sample covariance); only lines whose own dof\n"
    "                are few, only neighbours whose covariance matrix equals the line's (LR test at 5%)\n"
    "  --method cissim  discrete-cISSIM (You et al. 2023) from periodic time records, no FRF file:\n"
    "                --period P --lines .. --experiment e.csv; `msid fit --method cissim --help`\n";

// No --order: ml chooses it (--order auto, as msid measure --fit), unless --nd/--nn give LMFD degrees or
// --start MODEL.json gives the model's order. subspace keeps its own default (the singular-value gap: its
// scan's model at the chosen order 26 of the 1x3 structure moved by 1.7e-5 in cost between units, where the
// unit-invariance test asks 1e-6); lmfd, which interpolates at every order, still asks for it.
static bool order_defaults_to_auto(int argc, char **argv)
{
    if (!fit_method_is(argc, argv, "ml")) return false;
    for (int i = 2; i < argc; ++i) {
        const std::string a = argv[i];
        for (const char *k : {"--order", "--nd", "--nn"})
            if (a == k || a.rfind(std::string(k) + "=", 0) == 0) return false;
        std::string start;
        if (a == "--start" && i + 1 < argc) start = argv[i + 1];
        else if (a.rfind("--start=", 0) == 0) start = a.substr(8);
        if (!start.empty() && start != "subspace" && start != "sk") return false;
    }
    return true;
}

// --domain dt|ct (default: the file's domain); a CT model needs the file's sample time.
static Domain parse_domain(const Args &a, const FrfData &f)
{
    const Domain d = a.enum_<Domain>("domain", f.domain, {{"dt", Domain::DT}, {"ct", Domain::CT}});
    if (d == Domain::CT && f.h <= 0)
        throw Error("a continuous-time model needs the sample time of the FRF file (give --fs to msid frf)");
    return d;
}

static const std::vector<std::pair<std::string, Weight>> WEIGHTS = {
    {"cov", Weight::Cov}, {"known-input", Weight::KnownInput}, {"none", Weight::None}};

static double min_dof(const std::vector<WeightedLine> &w)
{
    double n = 1e300;
    for (const auto &l : w) n = std::min(n, l.dof);
    return n;
}

static Json frf_at_lines(const FrfData &f, const std::vector<MatC> &G, const std::vector<MatC> *cov)
{
    Json a = Json::array();
    for (size_t l = 0; l < f.lines.size(); ++l) {
        Json e;
        e["bin"] = f.lines[l].bin;
        e["freq"] = f.lines[l].freq;
        e["omega"] = f.lines[l].omega;
        e["G"] = cmat_json(G[l]);
        if (cov) e["cov"] = cmat_json((*cov)[l]); else e["cov"] = nullptr;
        a.push_back(e);
    }
    return a;
}

static Json params_json(const std::vector<std::string> &names, const VecR &theta, const MatR &cov, double factor, int rank)
{
    Json pr;
    pr["names"] = names;
    pr["values"] = std::vector<double>(theta.data(), theta.data() + theta.size());
    pr["cov"] = rmat_json(cov);
    pr["cov_factor"] = factor;
    pr["cov_rank"] = rank;
    return pr;
}

static Json lmfd_json(const LmfdModel &m)
{
    Json l;
    l["nD"] = m.nD;
    l["nN"] = m.nN;
    l["variable"] = m.domain == Domain::CT ? "s" : "z^-1";
    Json D = Json::array(), N = Json::array();
    for (const auto &x : m.Dm) D.push_back(rmat_json(x));
    for (const auto &x : m.Nm) N.push_back(rmat_json(x));
    l["D"] = D;
    l["N"] = N;
    return l;
}

static Json cost_json(double V, double dof, double nmin, double p)
{
    const CostLaw law = cost_law(dof, nmin, p);
    Json c;
    c["value"] = V;
    c["expected"] = law.mean;
    c["dof"] = dof;
    const double pv = cost_pvalue(law, V);
    if (std::isfinite(pv)) c["p_value"] = pv; else c["p_value"] = nullptr;
    return c;
}


// Exit status of `msid fit` when ml ran out of iterations: the best iterate is written, marked
// "converged": false (docs/fitting.md). 1 = error, 2 = usage error.
static const int EXIT_NOT_CONVERGED = 3;

// The order scan (cmd_fit_modal.cpp) runs a fit per order into a temporary file: its warning named that
// file and an exit status the scan does not return. The scan reports non-convergence itself.
static bool g_scan_member = false;
void fit_in_order_scan(bool on) { g_scan_member = on; }

static Json stability_json(const SSModel &ss, bool enforced)
{
    Json j;
    j["stable"] = ss_stable(ss);
    j["enforced"] = enforced;
    double worst = ss.domain == Domain::CT ? -1e300 : 0.0;
    if (ss.A.rows()) {
        const VecC ev = ss_eigenvalues(ss.A);   // balanced: the same poles as the modal table
        for (Eigen::Index k = 0; k < ss.A.rows(); ++k) {
            const cd l = ev(k);
            worst = ss.domain == Domain::CT ? std::max(worst, l.real()) : std::max(worst, std::abs(l));
        }
        j[ss.domain == Domain::CT ? "max_real_pole" : "max_abs_pole"] = worst;
    } else {
        j[ss.domain == Domain::CT ? "max_real_pole" : "max_abs_pole"] = nullptr;
    }
    return j;
}

static Feedthrough parse_feedthrough(const Args &a)
{
    if (a.has("no-d")) {
        if (a.has("feedthrough") && a.get("feedthrough") != "no") throw UsageError("--no-d contradicts --feedthrough " + a.get("feedthrough"));
        return Feedthrough::No;
    }
    return a.enum_<Feedthrough>("feedthrough", Feedthrough::Auto,
                                {{"auto", Feedthrough::Auto}, {"yes", Feedthrough::Yes}, {"no", Feedthrough::No}});
}

static Json feedthrough_json(Feedthrough ft, bool included, double p)
{
    Json j;
    j["mode"] = ft == Feedthrough::Auto ? "auto" : ft == Feedthrough::Yes ? "yes" : "no";
    j["included"] = included;
    if (p >= 0) j["lr_p_value"] = p; else j["lr_p_value"] = nullptr;
    return j;
}

// --start MODEL.json of ml --param poles: the model's poles (its pole_residue block, else the eigenvalues
// of A) as pole_list stores them. The model must describe the fit's frequencies: the same domain and, in
// DT, the same sample time. Its inputs and outputs may differ (the poles are common to every entry).
static std::vector<cd> model_start_poles(const std::string &path, Domain d, double h)
{
    if (path == "subspace" || path == "sk")
        throw UsageError("--start " + path + " chooses the start of --param lmfd; --param poles runs every start "
                         "(vector fitting, relaxed vector fitting, subspace at several r) and keeps the best; "
                         "--start MODEL.json refines a model from its poles");
    ModelFile mf;
    try {
        mf = read_model(path);
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
static bool use_poles(const Args &a, Domain d, size_t nu)
{
    return a.enum_index("param", d == Domain::DT && nu > 1 ? "lmfd" : "poles", {"poles", "lmfd"}) == 0;
}

// The weighted fits invert sample covariances: B, D of subspace need M >= 4 periods (Pintelon 2002
// Thm 2), and an ny x ny noise covariance from M periods is singular unless M > ny. One message
// naming the periods and the outputs, for any number of outputs.
// `w` are the weights of each line's own covariance (before any pooling: the pooled weights of ml rest
// on more dof, but the cost block and msid validate use each line's own). With `validating` the message
// speaks of the cost's law: its F(2, 2n) terms have a finite mean only for n > ny and a finite variance
// only for n > 2, so with fewer periods no p-value is defined (it came out 0 or NaN for any model).
static void check_periods(const std::vector<WeightedLine> &w, const FrfData &f, bool validating = false)
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

// ML of an LMFD from the subspace or the SK start. The subspace start is the model `msid fit --method
// subspace` writes at this order (r scan on `w_scan`, each line's own covariance; refined on `w`, the
// weights ml minimises; stable unless `stable` is off), in DT carried over exactly into the LMFD, so ml
// never ends above it; in CT (or when the conversion does not exist) fitted by SK to its FRF.
static MlResult lmfd_ml_from(const FrfData &f, Domain d, const std::vector<WeightedLine> &w,
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
            for (const auto &l : w) target.push_back(ss_eval(sr.model, l.x));
            st = lmfd_sk(w, d, f.h, s, 30, &target);
        }
    } else {
        st = lmfd_sk(w, d, f.h, s, 30);
    }
    return lmfd_ml(w, d, f.h, s, st, mo, known);
}

// Weighted cost (40) of model FRFs Gm at the lines.
static double cost_at(const std::vector<WeightedLine> &w, const std::vector<MatC> &Gm)
{
    double V = 0;
    for (size_t l = 0; l < w.size(); ++l) {
        const MatC E = w[l].G - Gm[l];
        V += (w[l].real ? 0.5 : 1.0) * (w[l].Linv * Eigen::Map<const VecC>(E.data(), E.size())).squaredNorm();
    }
    return V;
}

// LPM files: the fitted model's cost over every (2W+1)-th line (independent) with the cost law
// of those lines: validate's statistic (validation_stat.hpp); null when the file has no usable
// covariance.
static Json lpm_independent_cost(const FrfData &f, Domain d, const std::vector<MatC> &Gm, int nparams)
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

int cmd_fit(int argc, char **argv)
{
#ifdef __GLIBC__
    // A fit is one short process that reads a file of up to some MB into a JSON tree and frees it:
    // keep large blocks on the heap (not a fresh mmap each, whose pages fault in zeroed every time)
    // and grow the heap 4 MB at a time. 2x2 202-line fit: 25% fewer page faults, ~1-2 ms CPU less.
    mallopt(M_MMAP_THRESHOLD, 32 << 20);
    mallopt(M_TOP_PAD, 4 << 20);
#endif
    if (fit_method_is(argc, argv, "multi")) return cmd_fit_multi(argc, argv);   // cmd_fit_multi.cpp
    if (cissim_requested(argc, argv)) return cmd_fit_cissim(argc, argv);
    help_if_asked(argc, argv, 2, FIT_HELP);
    if (fit_order_is_scan(argc, argv)) return cmd_fit_scan(argc, argv);   // --order auto | a:b (cmd_fit_modal.cpp)
    if (order_defaults_to_auto(argc, argv)) {   // no --order: chosen, as msid measure --fit does
        std::vector<char *> av(argv, argv + argc);
        char order_key[] = "--order", order_auto[] = "auto";
        av.push_back(order_key);
        av.push_back(order_auto);
        return cmd_fit_scan((int)av.size(), av.data());
    }
    Args a(argc, argv, 2, FIT_HELP,
           {"method", "order", "nd", "nn", "domain", "weight", "noise-var", "r", "start", "max-iter", "delta", "beta",
            "feedthrough", "param", "output", "refine", "weight-smooth"},
           {"stable", "no-d", "allow-unstable"}, {"pin"});
    if (a.positional().size() != 1) throw UsageError("give exactly one msid-frf/1 file");
    const std::string out = a.require("output");
    const std::string method = a.require("method");
    // multi and cissim went their own ways above: listed so that a wrong name shows every method
    parse_enum(method, "--method", {"subspace", "lmfd", "ml", "multi", "cissim"});
    try {
        const FrfData f = read_frf(a.positional()[0]);
        const Domain d = parse_domain(a, f);
        const Weight wt = a.enum_<Weight>("weight", Weight::Cov, WEIGHTS);
        const double noise_var = a.f64("noise-var", 0.0);
        if (a.has("noise-var") && !(noise_var > 0)) throw UsageError("--noise-var must be positive");
        auto w = weigh(f, d, wt, noise_var);
        const bool known = noise_var > 0;
        const int wsmooth = (int)a.u32("weight-smooth", (uint32_t)ML_WEIGHT_SMOOTH);
        if (a.has("start") && method != "ml")
            throw UsageError("--start belongs to --method ml (subspace|sk for --param lmfd, a model file for --param poles)");
        if (a.has("weight-smooth") && ((method != "ml" && method != "subspace") || wt == Weight::None || known))
            throw UsageError("--weight-smooth belongs to --method ml or subspace with estimated weights "
                             "(--weight cov|known-input)");
        // Pooling needs the window to be a small part of the band: by default only with at least
        // ML_WEIGHT_SMOOTH_MIN_WINDOWS windows of lines (docs/fitting.md, "Pooled weights").
        const bool dense = w.size() >= (size_t)ML_WEIGHT_SMOOTH_MIN_WINDOWS * (size_t)(2 * wsmooth + 1);
        const bool pool = wt != Weight::None && !known && wsmooth > 0 && (a.has("weight-smooth") || dense);
        bool smoothed = method == "ml" && pool;
        std::vector<WeightedLine> w_line;   // per-line weights, for the cost block of a smoothed fit
        PoolStats pstats;
        const size_t pblock = pool_block(f, wt);
        if (smoothed) { w_line = w; pstats = smooth_weights(w, wsmooth, pblock); }
        // subspace: the r scan on each line's covariance, the refinement on pooled ones (docs/fitting.md)
        std::vector<WeightedLine> w_pool;
        if (method == "subspace" && pool) { w_pool = w; pstats = smooth_weights(w_pool, wsmooth, pblock); }
        // no line pooled (precise own weights, or covariances that change): the per-line fit, bit for bit
        if (pool && pstats.pooled == 0) {
            smoothed = false;
            w_line.clear();
            w_pool.clear();
        }
        Json doc;
        doc["format"] = "msid-model/1";
        doc["generator"] = std::string("msid ") + MSID_VERSION;
        doc["source"] = f.path;
        doc["domain"] = d == Domain::CT ? "ct" : "dt";
        if (f.h > 0) doc["sample_time"] = f.h;
        doc["method"] = method;
        Json settings;
        settings["weight"] = a.get("weight", "cov");
        if (pool && (method == "ml" || method == "subspace")) {
            settings["weight_smooth"] = wsmooth;
            // which lines pooled (docs/fitting.md "Pooled weights": imprecise own weights, equal covariance)
            settings["weight_pooling"] = Json{{"complex_lines", pstats.lines}, {"pooled", pstats.pooled},
                                              {"precise_own_weights", pstats.precise},
                                              {"neighbours_left_out", pstats.left_out}};
        }
        if (known) settings["noise_var"] = noise_var;
        const size_t ny = f.ny, nu = f.nu;
        double neq = 0;
        for (const auto &l : w) neq += (l.real ? 1.0 : 2.0) * (double)f.g();
        SSModel ss;
        int nparams = 0;
        Json extra;
        std::vector<MatC> Gm;
        std::vector<MatC> Gc;
        bool have_cov = false;
        double V = 0;
        const Feedthrough ft = parse_feedthrough(a);
        settings["feedthrough"] = a.has("no-d") ? "no" : a.get("feedthrough", "auto");
        const bool weighted = wt != Weight::None;
        if (method != "lmfd" && weighted) check_periods(smoothed ? w_line : w, f);
        bool converged = true;
        double grad_norm = 0.0;
        int iterations = 0;
        // an ml result (either parametrisation): parameters, model FRF with covariance, convergence
        auto take = [&](const auto &r) {
            nparams = (int)r.theta.size();
            Gm = r.G;
            Gc = r.Gcov;
            have_cov = true;
            converged = r.converged;
            grad_norm = r.grad_norm;
            iterations = r.iterations;
        };
        // Stable models by default (subspace and ml, both parametrisations): the test that kept unstable
        // poles when the data "needed" them assumes the model is right, and a model whose cost is rejected
        // (nonlinear distortion, an order too low) makes it meaningless. --allow-unstable is for plants
        // that are unstable (measured in closed loop). settings.stability names the rule that applied.
        if (a.has("stable") && a.has("allow-unstable")) throw UsageError("--stable contradicts --allow-unstable");
        const bool allow_unstable = a.has("allow-unstable");
        settings["stability"] = allow_unstable ? "allow-unstable" : a.has("stable") ? "stable" : "stable (default)";
        bool enforced_stable = !allow_unstable && method != "lmfd";
        if (method == "lmfd" && (a.has("stable") || allow_unstable))
            throw UsageError("--stable and --allow-unstable belong to --method subspace and ml: the closed-form lmfd "
                             "interpolates the data, whatever its poles");
        if (method == "lmfd") settings.erase("stability");
        if (method != "subspace" && a.has("refine")) throw UsageError("--refine belongs to --method subspace");
        if (method == "subspace") {
            SubspaceOptions o;
            o.order = (int)a.u32("order", 0);
            if (a.has("order") && o.order == 0) throw UsageError("--order must be positive");
            o.r = (int)a.u32("r", 0);
            o.stable = a.has("stable");
            o.stable_auto = !allow_unstable;
            // --refine ml|none as for cissim (the LM steps lower the weighted cost (35), the ML cost of
            // Gaussian FRF errors); a number is the step budget (ml = 30, none = 0)
            const std::string rspec = a.get("refine", "ml");
            if (rspec != "ml" && rspec != "none" && (rspec.empty() || rspec.find_first_not_of("0123456789") != std::string::npos))
                throw UsageError("--refine must be ml, none or a number of steps (got '" + rspec + "')");
            o.refine_iter = rspec == "ml" ? 30 : rspec == "none" ? 0 : (int)a.u32("refine", 30);
            o.estimate_D = ft != Feedthrough::No;
            o.feedthrough_auto = ft == Feedthrough::Auto;
            if (!w_pool.empty()) o.refine_w = &w_pool;
            const SubspaceResult r = fit_subspace(f, d, w, weighted, o);
            ss = r.model;
            enforced_stable = o.stable || o.stable_auto;
            V = r.cost;
            const int n = (int)ss.n();
            nparams = n * (int)(nu + ny) + (r.feedthrough ? (int)(nu * ny) : 0);
            settings["r"] = r.r;
            settings["stable"] = o.stable;
            settings["estimate_D"] = r.feedthrough;
            if (d == Domain::CT) settings["wscale"] = r.wscale;
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
            extra["subspace"] = sub;
            if (r.stable_lr_p >= 0 && r.stable_lr_p < 0.01)
                std::fprintf(stderr, "msid fit: note: the unconstrained model (unstable) has a significantly lower cost "
                                     "(likelihood ratio p = %.3g); for a stable plant that is model error (nonlinear "
                                     "distortion, the order), for an unstable one (measured in closed loop) refit with "
                                     "--allow-unstable\n", r.stable_lr_p);
            extra["feedthrough"] = feedthrough_json(ft, r.feedthrough, r.feedthrough_p);
            for (const auto &l : w) Gm.push_back(ss_eval(ss, l.x));
        } else if (method == "ml" && use_poles(a, d, nu)) {
            if (a.has("nd") || a.has("nn") || !a.all("pin").empty())
                throw UsageError("--nd/--nn/--pin belong to the LMFD parametrisation: add --param lmfd");
            PrOptions po;
            if (a.has("order")) {
                po.order = (int)parse_u32(a.get("order"), "--order");
                if (po.order == 0) throw UsageError("--order must be positive");
            }
            if (a.has("start")) {   // refine a model: its poles are the only start (docs/fitting.md, "Starting from a model")
                const std::string sp = a.get("start");
                po.pole_starts.push_back({"model", model_start_poles(sp, d, f.h)});
                int cnt = 0;
                for (const cd &p : po.pole_starts.back().second) cnt += p.imag() > 0 ? 2 : 1;
                if (!a.has("order")) po.order = cnt;
                else if (po.order != cnt)
                    throw UsageError(fmt("--order %d and the start model '%s' has %d distinct poles (pairs count twice): "
                                         "give its order or leave --order out", po.order, sp.c_str(), cnt));
                settings["start"] = sp;
            }
            if (po.order == 0) throw UsageError("give --order");
            // --weight none: the cost has no noise scale for the likelihood-ratio test, auto keeps D (as subspace)
            po.feedthrough = ft == Feedthrough::Auto && !weighted ? Feedthrough::Yes : ft;
            po.stable = !allow_unstable;
            po.known_noise = known;
            po.max_iter = (int)a.u32("max-iter", (uint32_t)po.max_iter);
            if (smoothed) po.subspace_scan_w = &w_line;   // subspace's r scan on each line's own weights, as msid fit
            const PrResult r = fit_ml_poles(f, d, w, weighted, po);   // cmd_fit_poles.cpp (not in the demo build)
            ss = pr_to_ss(r.model);
            settings["param"] = "poles";
            settings["stable"] = po.stable;
            settings["max_iter"] = po.max_iter;
            extra["parameters"] = params_json(r.names, r.theta, r.cov, r.cov_factor, r.cov_rank);
            Json pj, pl = Json::array(), rl = Json::array();
            for (size_t k = 0; k < r.model.poles.size(); ++k) {
                pl.push_back(Json{{"re", r.model.poles[k].real()}, {"im", r.model.poles[k].imag()}});
                rl.push_back(cmat_json(r.model.R[k]));
            }
            pj["variable"] = d == Domain::CT ? "s" : "z";
            pj["poles"] = pl;
            pj["residues"] = rl;
            pj["D"] = rmat_json(r.model.D);
            extra["pole_residue"] = pj;
            Json st = Json::array();
            for (const auto &x : r.starts) st.push_back(Json{{"start", x.name}, {"cost", x.cost}});
            extra["starts"] = st;
            extra["best_start"] = r.best_start;
            extra["reflected_poles"] = r.reflected;
            extra["feedthrough"] = feedthrough_json(ft, r.model.feedthrough, r.feedthrough_lr_p);
            take(r);
            V = r.cost;
        } else {
            if (method == "ml" && a.has("start") && a.get("start") != "subspace" && a.get("start") != "sk")
                throw UsageError("--start " + a.get("start") + ": --param lmfd starts from subspace or sk; a model file is refined "
                                 "in the pole-residue form: add --param poles" +
                                 (a.has("param") ? std::string() : " (ml's default for discrete time with several inputs is lmfd)"));
            LmfdSpec s;
            bool auto_nn = false;
            if (a.has("nd") || a.has("nn")) {
                if (a.has("order")) throw UsageError("give --order or --nd/--nn, not both");
                s.nD = (int)a.u32("nd", 1);
                s.nN = a.has("nn") ? (int)a.u32("nn", 0) : (d == Domain::CT ? s.nD - 1 : s.nD);
            } else if (a.has("order")) {
                const uint32_t n = parse_u32(a.get("order"), "--order");
                if (n == 0 || n % ny) throw UsageError("--order must be a positive multiple of the number of outputs for an LMFD");
                s.nD = (int)(n / ny);
                // properness from --feedthrough: CT yes -> nN = nD (direct term), no -> nN = nD - 1,
                // auto -> both, kept by a likelihood-ratio test; DT: the direct term is N_0 (pinned to 0 for no)
                s.nN = d == Domain::CT && ft == Feedthrough::No ? s.nD - 1 : s.nD;
                if (d == Domain::DT && ft == Feedthrough::No) s.pins.push_back(parse_pin("N0=0"));
                // --weight none: the cost has no noise scale for the test, auto keeps D (as subspace)
                auto_nn = d == Domain::CT && ft == Feedthrough::Auto && method == "ml" && weighted;
            } else {
                throw UsageError("give --order or --nd/--nn");
            }
            if (s.nN < 0) s.nN = 0;
            for (const auto &p : a.all("pin")) s.pins.push_back(parse_pin(p));
            Json pins = Json::array();
            for (const auto &p : a.all("pin")) pins.push_back(p);
            settings["pins"] = pins;
            if (method == "ml") settings["param"] = "lmfd";
            MlOptions mo;
            mo.max_iter = (int)a.u32("max-iter", (uint32_t)mo.max_iter);
            mo.delta = a.f64("delta", mo.delta);
            mo.beta = a.f64("beta", mo.beta);
            if (!(mo.delta > 0 && mo.delta <= 1) || !(mo.beta > 0 && mo.beta < 1))
                throw UsageError("--delta must be in (0, 1] and --beta in (0, 1)");
            LmfdModel lm;
            if (method == "lmfd") {
                settings["nD"] = s.nD;
                settings["nN"] = s.nN;
                const ClosedForm cf = lmfd_closed_form(w, d, f.h, s);
                lm = cf.model;
                extra["kernel"] = rmat_json(cf.kernel);
                Json names = Json::array();
                const auto nm = lmfd_param_names(s, ny, nu);
                for (size_t i = 0; i < (size_t)cf.unknowns; ++i) names.push_back(nm[i].substr(0, nm[i].find('[')) + "[k," + nm[i].substr(nm[i].find(',') + 1));
                extra["kernel_rows"] = names;
                extra["equations_per_row"] = cf.equations;
                extra["unknowns_per_row"] = cf.unknowns;
                extra["unique"] = cf.unique;
                if (cf.unique) {
                    const MlResult ev = lmfd_evaluate(w, d, f.h, s, lm, mo, known);
                    extra["parameters"] = params_json(ev.names, ev.theta, ev.cov, ev.cov_factor, ev.cov_rank);
                    nparams = (int)ev.theta.size();
                } else {
                    nparams = (int)(cf.equations * ny);
                }
                // an interpolating model reproduces the FRF: its covariance at the lines is the data's (Cor. 3)
                for (const auto &l : w) { Gm.push_back(lmfd_eval(lm, l.x)); Gc.push_back(l.cov); }
                have_cov = true;
                settings["wscale"] = s.wscale;
            } else {
                const std::string start = a.get("start", "subspace");   // subspace|sk (others refused above)
                settings["start"] = start;
                const std::vector<WeightedLine> &w_scan = smoothed ? w_line : w;
                MlResult r = lmfd_ml_from(f, d, w, w_scan, weighted, s, start, mo, known, !allow_unstable);
                double lr_p = -1;
                if (auto_nn) {
                    LmfdSpec s0 = s;
                    s0.nN = s.nD - 1;
                    const MlResult r0 = lmfd_ml_from(f, d, w, w_scan, weighted, s0, start, mo, known, !allow_unstable);
                    lr_p = chi2_sf((double)(ny * nu), std::max(0.0, 2.0 * (r0.cost - r.cost)));
                    if (lr_p >= 0.01) { r = r0; s = s0; }
                }
                settings["nD"] = s.nD;
                settings["nN"] = s.nN;
                extra["feedthrough"] = feedthrough_json(ft, s.nN == s.nD, lr_p);
                extra["cost_start"] = r.cost_start;
                if (!allow_unstable && !r.stable_constrained) {
                    // the start (SK, or an SK fit to the subspace model) has unstable poles: no stable path
                    enforced_stable = false;
                    settings["stability"] = "not enforced: unstable start";
                    std::fprintf(stderr, "msid fit: warning: the LMFD start is unstable, so ml could not keep the model "
                                         "stable; --param poles constrains every start\n");
                }
                lm = r.model;
                extra["parameters"] = params_json(r.names, r.theta, r.cov, r.cov_factor, r.cov_rank);
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
                extra["bounds"] = b;
                take(r);
                settings["max_iter"] = mo.max_iter;
            }
            try {
                ss = lmfd_to_ss(lm);
            } catch (const FitError &) {
                ss = SSModel();   // no proper realisation (e.g. improper LMFD): LMFD only
                ss.domain = d;
                ss.A = MatR(0, 0); ss.B = MatR(0, nu); ss.C = MatR(ny, 0); ss.D = MatR::Zero(ny, nu);
                extra["realisation"] = "none: the LMFD is improper";
            }
            extra["lmfd"] = lmfd_json(lm);
            V = weighted_cost_lmfd(lm, w);
        }
        if (method == "ml") {
            extra["converged"] = converged;
            extra["gradient_norm"] = grad_norm;
            extra["iterations"] = iterations;
        }
        doc["order"] = (int)ss.n();
        doc["n_inputs"] = nu;
        doc["n_outputs"] = ny;
        doc["settings"] = settings;
        doc["A"] = rmat_json(ss.A);
        doc["B"] = rmat_json(ss.B);
        doc["C"] = rmat_json(ss.C);
        doc["D"] = rmat_json(ss.D);
        doc["stable"] = ss_stable(ss);
        doc["stability"] = stability_json(ss, enforced_stable);
        doc["n_params"] = nparams;
        for (auto it = extra.begin(); it != extra.end(); ++it) doc[it.key()] = it.value();
        const double dof = neq - nparams;
        // The cost block always comes from the FRF covariance when the file has one, whatever weighting
        // the fit used: an unweighted fit's p-value would otherwise depend on the units of the data.
        Json cost = cost_json(V, dof, known || wt == Weight::None ? 1e300 : min_dof(w), (double)ny);
        cost["weight"] = settings["weight"];
        if (smoothed) {
            // the p-value from each line's own covariance (as validate computes it); the fit's own cost beside it
            cost = cost_json(cost_at(w_line, Gm), dof, min_dof(w_line), (double)ny);
            cost["weight"] = settings["weight"];
            cost["fit_cost_smoothed_weights"] = V;
        } else if (wt == Weight::None) {
            try {
                const auto wc = weigh(f, d, Weight::Cov);
                if (Gm.size() == wc.size() && min_dof(wc) <= (double)ny) {
                    // a covariance from too few periods (dof <= outputs: the weighted cost has no finite
                    // expectation, which is why --weight none was needed): no p-value, said so
                    cost["p_value"] = nullptr;
                    cost["note"] = fmt("the FRF covariance has %.3g dof at the fewest, at most the %zu outputs: the "
                                       "weighted cost has no finite expectation; unit weights, no p-value",
                                       min_dof(wc), ny);
                } else if (Gm.size() == wc.size()) {
                    cost = cost_json(cost_at(wc, Gm), dof, min_dof(wc), (double)ny);
                    cost["weight"] = "cov";
                    cost["fit_cost_unweighted"] = V;
                }
            } catch (const FitError &) {
                // no usable covariance in the file: the unit-weight cost has no noise scale, so no p-value
                // (it printed "p = 1" against an expectation of half the real dof)
                cost["p_value"] = nullptr;
                cost["note"] = "no usable FRF covariance: unit weights, no p-value";
            }
        }
        if (f.method == "lpm") {   // neighbouring LPM lines are correlated: the p-value of independent lines
            const Json ic = lpm_independent_cost(f, d, Gm, nparams);
            if (!ic.is_null()) cost["independent_lines"] = ic;
        }
        doc["cost"] = cost;
        doc["frf"] = frf_at_lines(f, Gm, have_cov ? &Gc : nullptr);
        add_modes(doc, true);   // modal parameters with standard deviations (cmd_fit_modal.cpp)
        write_json_file(out, doc, false);   // derived from files: atomic, not fsynced (docs/model-format.md)
        // ml in the pole-residue form with several inputs: --order counts poles, the realisation repeats
        // each per input (state order n nu); "order 48" alone after --order 24 read as a different model
        const bool repeated = doc.contains("pole_residue") && nu > 1;
        int npoles = 0;   // pairs are stored once (Im > 0)
        if (repeated)
            for (const auto &p : doc["pole_residue"]["poles"]) npoles += p["im"].get<double>() != 0.0 ? 2 : 1;
        const std::string order_txt = repeated ? fmt("order %d (%d poles; state order %d: each pole once per input)",
                                                     npoles, npoles, (int)ss.n())
                                               : fmt("order %d", (int)ss.n());
        std::printf("wrote %s: %s fit, %s, weighted cost %.6g (expected %.6g, %s)%s\n", out.c_str(), method.c_str(),
                    order_txt.c_str(), doc["cost"]["value"].get<double>(), doc["cost"]["expected"].get<double>(),
                    doc["cost"]["p_value"].is_null() ? "no p-value"
                                                     : fmt("p = %.3g", doc["cost"]["p_value"].get<double>()).c_str(),
                    doc["stable"].get<bool>() ? "" : ", UNSTABLE");
        if (doc["cost"].contains("independent_lines") && !doc["cost"]["independent_lines"]["p_value"].is_null())
            std::printf("LPM file: p = %.3g on every %d-th line (independent; the p-value msid validate gives)\n",
                        doc["cost"]["independent_lines"]["p_value"].get<double>(),
                        doc["cost"]["independent_lines"]["line_stride"].get<int>());
        if (!converged && !g_scan_member) {
            // V is the cost the fit minimised: with pooled weights not the cost block's (per-line weights)
            std::fprintf(stderr, "msid fit: warning: ml did not converge in %d iterations (cost %.6g%s, gradient norm %.3g): "
                                 "wrote the best iterate to %s marked \"converged\": false (exit status %d)\n",
                         iterations, V, smoothed ? " with the pooled weights it minimises" : "", grad_norm, out.c_str(),
                         EXIT_NOT_CONVERGED);
            return EXIT_NOT_CONVERGED;
        }
        if (!converged) return EXIT_NOT_CONVERGED;
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

static const char *VAL_HELP =
    "usage: msid validate model.json frf.json [--weight cov|known-input|none] [--lpm-lines independent|all]\n"
    "                     [-o report.json]\n"
    "       msid validate multi-model.json --experiment r1.csv ... [--lags M] [-o report.json]\n"
    "The weighted residual cost of the model on the FRF data against its expectation, with a p-value,\n"
    "per-line normalised residuals, and a verdict at 5%. Models of --method multi (free responses too)\n"
    "are validated on time records: residual whiteness and cost (msid validate --experiment x --help).\n"
    "LPM files: neighbouring lines share 2W of their 2W+1 window bins, so the cost is summed over every\n"
    "(2W+1)-th line, which are independent (--lpm-lines all: every line, an optimistic p-value).\n";

int cmd_validate(int argc, char **argv)
{
    if (validate_on_records(argc, argv)) return cmd_validate_multi(argc, argv);   // time records (cmd_fit_multi.cpp)
    Args a(argc, argv, 2, VAL_HELP, {"weight", "output", "lpm-lines"}, {});
    if (a.positional().size() != 2) throw UsageError("give a model file and an FRF file");
    try {
        const ModelFile mf = read_model(a.positional()[0]);
        if (mf.ss.B.cols() == 0)
            throw FitError("'" + mf.path + "' is a free-response model (no inputs, from msid fit --method multi): it has no "
                           "FRF; validate it on time records with --experiment FILE");
        const FrfData f = read_frf(a.positional()[1]);
        if (mf.ss.B.cols() != (Eigen::Index)f.nu || mf.ss.C.rows() != (Eigen::Index)f.ny)
            throw FitError("the model has " + std::to_string(mf.ss.B.cols()) + " inputs and " +
                           std::to_string(mf.ss.C.rows()) + " outputs, the FRF " + std::to_string(f.nu) + " and " +
                           std::to_string(f.ny));
        // A continuous-time model is evaluated at s = j omega (rad/s): an FRF without a sample time has
        // its lines in rad/sample, where the model was evaluated without a word (a verdict on the wrong
        // frequencies). A DT model fitted at another sample time describes other frequencies too.
        if (mf.domain == Domain::CT && f.domain == Domain::DT && f.h <= 0)
            throw FitError("'" + mf.path + "' is a continuous-time model and '" + f.path +
                           "' a discrete-time FRF without a sample time: its lines have no frequency in rad/s "
                           "(give --fs to msid frf)");
        if (mf.domain == Domain::DT && mf.h > 0 && f.h > 0 && std::abs(mf.h - f.h) > 1e-9 * f.h)
            throw FitError(fmt("'%s' was fitted at sample time %g s and '%s' has %g s: the lines are at other "
                               "frequencies", mf.path.c_str(), mf.h, f.path.c_str(), f.h));
        // The verdict comes from the FRF covariance whatever weighting the fit used (a --weight none
        // fit is validated with the covariance: unit weights would make the verdict depend on the units).
        Weight wt = a.enum_<Weight>("weight", mf.weight == "known-input" ? Weight::KnownInput : Weight::Cov, WEIGHTS);
        std::string wname = a.has("weight") ? a.get("weight") : (mf.weight == "known-input" ? "known-input" : "cov");
        std::vector<WeightedLine> w;
        // unit weights only for a file without covariance (noted below); a covariance that is there but
        // unusable (too few periods for the outputs, not positive definite) is refused with its cause:
        // a fall-back to unit weights gave "consistent, p = 1" for any model
        bool has_cov = false;
        for (const auto &l : f.lines) has_cov = has_cov || l.cov.size() > 0;
        if (!has_cov && !a.has("weight") && wt == Weight::Cov) {
            wname = "none";
            wt = Weight::None;
        }
        w = weigh(f, mf.domain, wt);
        if (wt != Weight::None) check_periods(w, f, true);
        const size_t stride = lpm_line_stride(f, a.has("lpm-lines") ? a.get("lpm-lines") : "independent");
        std::vector<MatC> Gm;
        for (const auto &l : w) Gm.push_back(mf.lmfd ? lmfd_eval(*mf.lmfd, l.x) : ss_eval(mf.ss, l.x));
        const ValidationStat vs = validation_stat(w, Gm, mf.n_params, stride, (double)f.ny, wt == Weight::None);
        if (!(vs.dof > 0))
            throw FitError("the model has as many parameters as the data: nothing to validate (dof " + std::to_string(vs.dof) + ")");
        const double V = vs.cost, dof = vs.dof, pv = vs.p_value;
        if (!std::isfinite(V) || std::isnan(pv))   // never a verdict from a cost that is not a number
            throw FitError(fmt("the weighted cost of '%s' on '%s' is %g: the model's FRF is not finite at the lines",
                               mf.path.c_str(), f.path.c_str(), V));
        Json per = Json::array();
        const double g = (double)f.g();
        int worst = -1;
        double worst_q = -1;
        for (size_t l = 0; l < w.size(); ++l) {
            const double q = vs.q[l];
            // per line: q / (expected under the model) ~ 1
            const double ex = (w[l].real ? 0.5 : 1.0) * g * (w[l].dof < 1e8 && w[l].dof > f.ny ? w[l].dof / (w[l].dof - f.ny) : 1.0);
            Json pl;
            pl["bin"] = f.lines[l].bin;
            pl["freq"] = f.lines[l].freq;
            pl["normalised_residual"] = q / ex;
            per.push_back(pl);
            if (q / ex > worst_q) { worst_q = q / ex; worst = (int)l; }
        }
        const bool ok = pv >= 0.05;
        std::printf("model %s on %s: weighted cost %.6g, expected %.6g (dof %.0f), p-value %.4g\n", mf.path.c_str(),
                    f.path.c_str(), V, vs.expected, dof, pv);
        if (worst >= 0)
            std::printf("largest normalised residual %.3g at bin %u (1 expected on average)\n", worst_q, f.lines[(size_t)worst].bin);
        if (stride > 1)
            std::printf("LPM file: the cost sums every %zu-th line (2W+1 bins apart: independent), %zu of %zu lines\n",
                        stride, (w.size() + stride - 1) / stride, w.size());
        std::printf("verdict: %s\n", ok ? "consistent with the data at 5%" : "NOT consistent with the data at 5%");
        if (wt == Weight::None) std::printf("note: unweighted residuals: the p-value assumes unit noise\n");
        const Json nlv = distortion_verdict(f.path, mf, wname, pv);   // noise vs distortion level (frf_bla.cpp)
        if (a.has("output")) {
            Json r;
            r["format"] = "msid-validation/1";
            r["model"] = mf.path;
            r["frf"] = f.path;
            r["weight"] = wname;
            r["cost"] = V;
            r["expected"] = vs.expected;
            r["dof"] = dof;
            r["p_value"] = pv;
            r["consistent_at_5pct"] = ok;
            r["lines_in_statistic"] = stride > 1 ? fmt("every %zu-th line (2W+1, independent LPM lines)", stride)
                                                 : std::string("all");
            r["line_stride"] = stride;
            if (!nlv.is_null()) r["nonlinear_distortion"] = nlv;
            r["lines"] = per;
            write_json_file(a.get("output"), r, false);
        }
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

int cmd_compare(int argc, char **argv)
{
    static const char *HELP = "usage: msid compare model.json reference.json [-o out.json]\n"
                              "Relative H2 and Hinf distance ||model - reference|| / ||reference||.\n";
    Args a(argc, argv, 2, HELP, {"output"}, {});
    if (a.positional().size() != 2) throw UsageError("give two model files (the second is the reference)");
    try {
        const ModelFile m1 = read_model(a.positional()[0]), m2 = read_model(a.positional()[1]);
        const Distance dd = ss_distance(m1.ss, m2.ss);
        if (!(dd.h2_ref > 0) || !(dd.hinf_ref > 0) || !std::isfinite(dd.h2_ref) || !std::isfinite(dd.hinf_ref))
            throw Error(fmt("'%s': the reference's H2 norm is %g and its Hinf norm %g: relative distances need a "
                            "reference with finite, non-zero norms", m2.path.c_str(), dd.h2_ref, dd.hinf_ref));
        std::printf("relative H2 distance %.6g, relative Hinf distance %.6g (reference H2 %.6g, Hinf %.6g)\n", dd.h2,
                    dd.hinf, dd.h2_ref, dd.hinf_ref);
        if (a.has("output"))
            write_json_file(a.get("output"), Json{{"format", "msid-compare/1"}, {"model", m1.path}, {"reference", m2.path},
                                                   {"h2_rel", dd.h2}, {"hinf_rel", dd.hinf}, {"h2_ref", dd.h2_ref},
                                                   {"hinf_ref", dd.hinf_ref}}, false);
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

}  // namespace msidcli
