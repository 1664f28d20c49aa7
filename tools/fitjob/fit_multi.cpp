// --method multi: maximum likelihood from several time-domain records (ring-downs, free decays,
// short transient-laden input-output experiments) with every record's initial conditions
// eliminated (tools/fit/multi.hpp; Markovsky & Pintelon §IV-VI). The normal msid-model/1
// document plus a "multi" section.
#include "fit_job_detail.hpp"

#include "models.hpp"
#include "order_select.hpp"

#include <cmath>

namespace msidfitjob {

namespace {

Json num_or_null(double x) { return std::isfinite(x) ? Json(x) : Json(nullptr); }

Json modes_block(const MultiResult &r, double h)
{
    Json a = Json::array();
    for (const auto &m : r.modes) {
        Json j;
        j["pole_z"] = Json{{"re", m.z.real()}, {"im", m.z.imag()}};
        j["sd_pole_z"] = Json{{"re", num_or_null(m.sd_z_re)}, {"im", num_or_null(m.sd_z_im)}};
        // a pole at z = 0 (a pure delay: an FIR plant) has no continuous-time pole, ln 0 = -inf: null
        j["pole_ct"] = Json{{"re", num_or_null(m.s.real())}, {"im", num_or_null(m.s.imag())}};
        j["real"] = m.real;
        j[h > 0 ? "fn_hz" : "fn_cycles_per_sample"] = num_or_null(m.fn);
        j[h > 0 ? "sd_fn_hz" : "sd_fn_cycles_per_sample"] = num_or_null(m.sd_fn);
        j[h > 0 ? "wn_rad_s" : "wn_rad_per_sample"] = num_or_null(m.wn);
        j[h > 0 ? "sd_wn_rad_s" : "sd_wn_rad_per_sample"] = num_or_null(m.sd_wn);
        j["zeta"] = num_or_null(m.zeta);
        j["sd_zeta"] = num_or_null(m.sd_zeta);
        a.push_back(j);
    }
    return a;
}

// Relative spectral-norm distance ||A - B|| / ||B||.
double rel_spec(const MatR &A, const MatR &B)
{
    const double nb = Eigen::JacobiSVD<MatR>(B).singularValues()(0);
    return nb > 0 ? Eigen::JacobiSVD<MatR>(A - B).singularValues()(0) / nb : NAN;
}

bool is_scan(const MultiRequest &rq) { return rq.order == "auto" || rq.order.find(':') != std::string::npos; }

// The options, as the fit reads them.
struct Plan {
    MultiOptions o;
    bool scan = false, eiv = false;
    std::vector<int> orders;
    std::string rule;
    double eiv_ratio = 0;
};

Plan plan(const MultiRequest &rq, bool noise_records)
{
    Plan p;
    if (rq.order.empty()) throw UsageError("give " MSID_OPT("order") " n (the number of poles), auto or a:b");
    p.scan = is_scan(rq);
    if (p.scan) {
        try {
            p.orders = parse_order_range(rq.order, 1, 12, nullptr);
        } catch (const FitError &e) {
            throw UsageError(e.what());
        }
        p.o.order = p.orders.front();
    } else {
        p.o.order = (int)msidutil::parse_u32(rq.order, "--order");
        if (p.o.order < 1 || p.o.order > 200) throw UsageError(MSID_OPT("order") " must be 1..200, auto or a:b");
    }
    p.rule = rq.order_rule.empty() ? "mdl" : rq.order_rule;
    if (p.rule != "mdl" && p.rule != "aic") throw UsageError(MSID_OPT("order_rule") " must be mdl or aic (got '" + p.rule + "')");
    if (!rq.order_rule.empty() && !p.scan) throw UsageError(MSID_OPT("order_rule") " needs " MSID_OPT("order") " auto or a:b");
    if (!rq.noise_ar.empty() && (rq.noise_ar_order || noise_records))
        throw UsageError("give the noise model either as " MSID_OPT("noise_ar") " c1,..,cp or estimate it with " MSID_OPT("noise_ar_order") " p");
    if (noise_records && !rq.noise_ar_order)
        throw UsageError(MSID_OPT("noise_record") " needs " MSID_OPT("noise_ar_order") " p (the order of the AR model to estimate)");
    if (!rq.noise_ar.empty()) {
        if (rq.noise_ar.size() > 50) throw UsageError(MSID_OPT("noise_ar") " takes 1..50 comma-separated coefficients c1,...,cp");
        p.o.noise_ar = Eigen::Map<const VecR>(rq.noise_ar.data(), (Eigen::Index)rq.noise_ar.size());
        try {
            multi_noise_from_ar(p.o.noise_ar);
        } catch (const FitError &e) {
            throw UsageError(std::string(MSID_OPT("noise_ar") ": ") + e.what());
        }
    }
    if (rq.input_noise_ratio) {
        p.eiv = true;
        p.eiv_ratio = *rq.input_noise_ratio;
        if (!(p.eiv_ratio >= 0) || !std::isfinite(p.eiv_ratio))
            throw UsageError(MSID_OPT("input_noise_ratio") " must be a finite number >= 0");
        if (!rq.noise_ar.empty() || rq.noise_ar_order)
            throw UsageError(MSID_OPT("input_noise_ratio") " (noisy inputs) takes white noise: leave out " MSID_OPT("noise_ar") " / " MSID_OPT("noise_ar_order"));
    }
    if (rq.noise_ar_order) {
        p.o.noise_ar_order = (int)*rq.noise_ar_order;
        if (p.o.noise_ar_order < 1 || p.o.noise_ar_order > 50) throw UsageError(MSID_OPT("noise_ar_order") " must be 1..50");
    }
    if (rq.fs) {
        if (!(*rq.fs > 0) || !std::isfinite(*rq.fs)) throw UsageError(MSID_OPT("fs") " must be a positive sample rate in Hz");
        p.o.h = 1.0 / *rq.fs;
    }
    if (rq.feedthrough != "no" && rq.feedthrough != "yes")
        throw UsageError(MSID_OPT("feedthrough") " must be no or yes (got '" + rq.feedthrough + "')");
    p.o.feedthrough = rq.feedthrough == "yes";
    p.o.start = rq.start;
    if (p.o.start != "auto" && p.o.start != "kung" && p.o.start != "prony" && p.o.start != "sm")
        throw UsageError(MSID_OPT("start") " must be auto, kung, prony or sm (got '" + p.o.start + "')");
    if (rq.max_iter) p.o.max_iter = (int)*rq.max_iter;
    return p;
}

// The AR model of the output noise from noise-only records (Yule-Walker); its description.
std::string noise_from_records(const std::vector<Record> &noise_recs, uint32_t nu, uint32_t ny, MultiOptions &o)
{
    const std::vector<MultiRecord> nrec = multi_records(noise_recs);
    if (noise_recs[0].nu != nu || noise_recs[0].ny != ny)
        throw Error(fmt("the noise records have %u input(s) and %u output(s), the experiments %u and %u: give them "
                        "the same columns", noise_recs[0].nu, noise_recs[0].ny, nu, ny));
    std::vector<MatR> v;
    for (const auto &x : nrec) v.push_back(x.y.rowwise() - x.y.colwise().mean());
    try {
        o.noise_ar = multi_ar_yule_walker(v, o.noise_ar_order);
        multi_noise_from_ar(o.noise_ar);
    } catch (const FitError &e) {
        throw Error(std::string("the noise records: ") + e.what());
    }
    const std::string s = fmt("estimated from %zu noise record(s) (Yule-Walker AR(%d))", nrec.size(), o.noise_ar_order);
    o.noise_ar_order = 0;
    return s;
}

// Noisy inputs: the errors-in-variables estimate replaces the output-error one (multi_eiv.cpp).
void replace_by_eiv(MultiResult &r, const std::vector<MultiRecord> &recs, const MultiOptions &o, double ratio)
{
    const MultiEivResult e = multi_fit_eiv(recs, o, ratio);
    r.alpha = e.alpha;
    r.theta = e.theta;
    for (int k = 0; k < r.nu; ++k)
        for (int d = 0; d < r.nb; ++d) r.beta[(size_t)d](0, k) = e.theta(r.n + k * r.nb + d);
    r.cov = e.cov;
    r.cost = e.cost;
    r.s2 = e.s2;
    r.dof = e.dof;
    r.iterations = e.iterations;
    r.converged = e.converged;
    r.modes = multi_modes(r.alpha, r.cov.topLeftCorner(r.n, r.n), o.h);
}

// The model as an LMFD with D(q^-1) = a(q^-1) I and N_d = beta_d.
LmfdModel multi_lmfd(const MultiResult &r, double h, uint32_t nu, uint32_t ny)
{
    LmfdModel lm;
    lm.domain = Domain::DT;
    lm.h = h;
    lm.nD = r.n;
    lm.nN = r.n;
    for (int m = 1; m <= r.n; ++m) lm.Dm.push_back(MatR::Identity(ny, ny) * r.alpha(m - 1));
    for (int d = 0; d <= r.n; ++d) lm.Nm.push_back(d >= r.d0 && nu > 0 ? r.beta[(size_t)(d - r.d0)] : MatR::Zero(ny, nu));
    return lm;
}

Json order_selection_block(const MultiOrderSelection &sel, const std::string &rule)
{
    Json os;
    os["rule"] = rule;
    os["chosen"] = sel.chosen;
    os["criterion"] = "-2 log L + k ln S (mdl) or + 2 k (aic); -2 log L = S ln(V / S) + ln det Sigma; "
                      "k = n + ny nu nb + N ny n (every record's initial conditions count)";
    Json rows = Json::array();
    for (const auto &row : sel.rows) {
        Json jr;
        jr["order"] = row.order;
        if (!row.ok) {
            jr["error"] = row.error;
        } else {
            jr["cost"] = row.cost;
            jr["noise_variance"] = row.s2;
            jr["k"] = row.k;
            jr["m2logl"] = row.m2logl;
            jr["aic"] = row.aic;
            jr["mdl"] = row.mdl;
            jr["converged"] = row.converged;
        }
        rows.push_back(jr);
    }
    os["rows"] = rows;
    os["hankel_singular_values"] = std::vector<double>(sel.hankel_sv.data(), sel.hankel_sv.data() + sel.hankel_sv.size());
    if (sel.hankel_gap_order > 0) os["hankel_gap_order"] = sel.hankel_gap_order;
    return os;
}

// The Cramer-Rao bound at the estimate, computed by the independent route of multi_crb().
Json cramer_rao_block(const MultiResult &r, const std::vector<MultiRecord> &recs, uint32_t ny, bool eiv)
{
    const long P = (long)r.theta.size() + (long)recs.size() * ny * r.n;
    Json crb;
    if (eiv) {
        crb["cov"] = nullptr;
        crb["note"] = "not computed for noisy inputs (the bound of multi_crb is the output-error one)";
    } else if (P <= 1500 && r.cov_rank == (int)r.theta.size()) {
        std::vector<MatR> us;
        for (const auto &x : recs) us.push_back(x.u);
        const MatR C = multi_crb(r.alpha, r.beta, r.d0, us, r.x0, (int)ny, r.s2, r.noise_ar);
        crb["cov"] = rmat_json(C);
        crb["rel_diff_cov"] = rel_spec(r.cov, C);
        crb["note"] = "at the estimate and the estimated noise variance: full Fisher matrix over the parameters and every "
                      "initial condition by central differences of the model recursion, inverted; rel_diff_cov = "
                      "||cov - CRB||_2 / ||CRB||_2";
    } else {
        crb["cov"] = nullptr;
        crb["note"] = P > 1500 ? "not computed: more than 1500 parameters with the initial conditions"
                               : "not computed: the Fisher matrix is singular (parameters not identifiable)";
    }
    return crb;
}

// The "multi" section: the poles' polynomial, modes, records with their initial conditions, noise.
Json multi_block(const MultiResult &r, const Plan &p, const std::vector<Record> &recs, const std::string &noise_source,
                 uint32_t nu)
{
    Json mj;
    mj["model"] = nu > 0 ? "y_j = sum_k b_jk(q^-1)/a(q^-1) u_k + free response of a(q^-1) per record and output"
                         : "every output of every record: a sum of the same n damped exponentials z_k^t";
    mj["alpha"] = std::vector<double>(r.alpha.data(), r.alpha.data() + r.alpha.size());
    mj["alpha_convention"] = "a(q^-1) = 1 + alpha_1 q^-1 + ... + alpha_n q^-n; poles: roots of z^n + alpha_1 z^(n-1) + ... + alpha_n";
    mj["modes"] = modes_block(r, p.o.h);
    Json recj = Json::array();
    for (size_t i = 0; i < recs.size(); ++i)
        recj.push_back(Json{{"file", recs[i].path}, {"samples", recs[i].n_rows},
                            {"initial_conditions", p.eiv ? Json(nullptr) : rmat_json(r.x0[i])}});
    mj["records"] = recj;
    mj["initial_conditions_convention"] = "per record ny x n: the model output's pre-initial values yhat(-1) .. yhat(-n)";
    mj["cost"] = r.cost;
    mj["noise_variance"] = r.s2;
    mj["dof"] = r.dof;
    mj["output_samples"] = r.n_samples;
    mj["converged"] = r.converged;
    mj["iterations"] = r.iterations;
    mj["gradient_norm"] = r.grad_norm;
    Json st = Json::array();
    for (const auto &s : r.starts) {
        Json js{{"start", s.name}, {"cost", num_or_null(s.cost)}};
        if (!s.failed.empty()) js["failed"] = s.failed;
        st.push_back(js);
    }
    mj["starts"] = st;
    Json nz;
    nz["model"] = r.noise_ar.size() ? "stationary AR: c(q^-1) v = e, the same for every output" : "white";
    nz["ar"] = std::vector<double>(r.noise_ar.data(), r.noise_ar.data() + r.noise_ar.size());
    nz["source"] = noise_source;
    nz["innovations_variance"] = r.s2;
    nz["note"] = "the cost, noise_variance and covariance are in the whitened norm ||W (y - yhat)||^2 (W^T W = Sigma^-1)";
    mj["noise"] = nz;
    return mj;
}

// What msid prints: the scan's table and the noise model before the "wrote" line, the modes after.
void summarise(FitOutcome &out, const MultiResult &r, const Plan &p, const MultiOrderSelection &sel,
               const std::string &noise_source, size_t n_records, const Json &crb)
{
    if (p.scan) {
        out.before += fmt("order  cost          k      %-12s %s\n", p.rule == "mdl" ? "MDL" : "AIC", "converged");
        for (const auto &row : sel.rows) {
            if (!row.ok) {
                out.before += fmt("%-6d failed: ", row.order) + row.error + "\n";
                continue;
            }
            out.before += fmt("%-6d %-13.6g %-6.0f %-12.6g %s%s\n", row.order, row.cost, row.k,
                              p.rule == "mdl" ? row.mdl : row.aic, row.converged ? "yes" : "no",
                              row.order == sel.chosen ? "  <- chosen" : "");
        }
        if (sel.hankel_gap_order > 0)
            out.before += fmt("stacked Hankel singular values: largest gap after %d\n", sel.hankel_gap_order);
    }
    for (const auto &s : r.starts)
        if (!s.failed.empty()) out.before += "start " + s.name + " failed (not used): " + s.failed + "\n";
    if (r.noise_ar.size()) out.before += fmt("noise: AR(%d) ", (int)r.noise_ar.size()) + noise_source + "\n";
    out.tail = fmt(": multi fit of %zu record(s), %d pole(s), noise sd %.4g, %s after %d iterations (start %s)\n",
                   n_records, r.n, std::sqrt(r.s2), r.converged ? "converged" : "NOT converged", r.iterations,
                   r.best_start.c_str());
    for (const auto &m : r.modes)
        out.after += fmt("  %s %.6g +- %.2g %s, damping %.5g +- %.2g\n", m.real ? "real pole" : "mode", m.fn, m.sd_fn,
                         p.o.h > 0 ? "Hz" : "cycles/sample", m.zeta, m.sd_zeta);
    if (!crb["cov"].is_null())
        out.after += fmt("  covariance vs Cramer-Rao bound (independent route): relative difference %.2g\n",
                         crb["rel_diff_cov"].get<double>());
    out.converged = r.converged;
    if (!r.converged)
        out.not_converged = fmt("multi did not converge in %d iterations: wrote the best iterate to ", r.iterations);
}

}  // namespace

std::vector<MultiRecord> multi_records(const std::vector<Record> &recs)
{
    std::vector<MultiRecord> out;
    for (size_t i = 0; i < recs.size(); ++i) {
        const Record &r = recs[i];
        if (r.nu != recs[0].nu || r.ny != recs[0].ny)
            throw Error(fmt("'%s' has %u input(s) and %u output(s), '%s' has %u and %u: every record of " MSID_OPT("method") " multi "
                            "must have the same channels",
                            r.path.c_str(), r.nu, r.ny, recs[0].path.c_str(), recs[0].nu, recs[0].ny));
        const size_t C = (size_t)r.nu + r.ny;
        MultiRecord m;
        m.u.resize((Eigen::Index)r.n_rows, r.nu);
        m.y.resize((Eigen::Index)r.n_rows, r.ny);
        const double *d = r.data();
        for (size_t t = 0; t < r.n_rows; ++t) {
            for (uint32_t k = 0; k < r.nu; ++k) m.u((Eigen::Index)t, k) = d[t * C + k];
            for (uint32_t j = 0; j < r.ny; ++j) m.y((Eigen::Index)t, j) = d[t * C + r.nu + j];
        }
        out.push_back(std::move(m));
    }
    return out;
}

void check_multi(const MultiRequest &rq, bool noise_records) { plan(rq, noise_records); }

FitOutcome fit_multi(const std::vector<Record> &files, const std::vector<Record> &noise_recs, const MultiRequest &rq,
                     const Report &)
{
    if (files.empty()) throw UsageError("give at least one record with " MSID_OPT("experiment") " FILE");
    Plan p = plan(rq, !noise_recs.empty());
    MultiOptions &o = p.o;
    const std::vector<MultiRecord> recs = multi_records(files);
    const uint32_t nu = files[0].nu, ny = files[0].ny;
    for (size_t i = 0; i < recs.size() && !p.scan; ++i)
        if (files[i].n_rows <= (size_t)o.order)
            throw Error(fmt("'%s' has %zu samples: too few for order %d (each record needs more than n = %d samples: its "
                            "%d initial conditions per output are estimated from it)",
                            files[i].path.c_str(), files[i].n_rows, o.order, o.order, o.order));
    std::string noise_source = o.noise_ar.size() ? "given (--noise-ar)" : "white";
    if (!noise_recs.empty()) noise_source = noise_from_records(noise_recs, nu, ny, o);
    else if (o.noise_ar_order > 0)
        noise_source = fmt("estimated from the residuals (two-stage, Yule-Walker AR(%d))", o.noise_ar_order);
    if (p.eiv && (nu == 0 || ny != 1))
        throw UsageError(MSID_OPT("input_noise_ratio") " needs input columns and one output (noisy inputs, one output)");
    if (nu == 0 && o.feedthrough) throw UsageError(MSID_OPT("feedthrough") " yes needs input columns: free responses have no inputs");
    if (nu == 0 && o.start == "sm") throw UsageError(MSID_OPT("start") " sm needs input columns; free responses use kung or prony");
    if (nu > 0 && o.start == "kung") throw UsageError(MSID_OPT("start") " kung needs free responses (records without input columns)");

    FitOutcome out;
    try {
        MultiOrderSelection sel;
        if (p.scan) {
            sel = multi_select_order(recs, o, p.orders, p.rule, true);
            o.order = sel.chosen;
        }
        MultiResult r = p.scan ? sel.best : multi_fit(recs, o);
        if (p.eiv) replace_by_eiv(r, recs, o, p.eiv_ratio);
        const LmfdModel lm = multi_lmfd(r, o.h, nu, ny);   // realised in observer form
        const SSModel ss = lmfd_to_ss(lm);

        Json sources = Json::array();
        for (const auto &f : files) sources.push_back(f.path);
        Json &doc = out.model;
        doc = model_head(sources, Domain::DT, o.h, "multi");
        Json settings;
        settings["order"] = o.order;
        settings["feedthrough"] = rq.feedthrough;
        settings["start"] = o.start;
        settings["max_iter"] = o.max_iter;
        settings["weight"] = r.noise_ar.size() ? "noise-ar" : "none";
        if (p.eiv) settings["input_noise_ratio"] = p.eiv_ratio;
        if (p.scan) settings["order_range"] = rq.order;
        if (!rq.columns.empty()) settings["columns"] = rq.columns;
        model_put_ss(doc, ss, (int)ss.n(), nu, ny, settings);
        doc["n_params"] = (int)r.theta.size();
        doc["converged"] = r.converged;
        doc["parameters"] = model_params(r.names, r.theta, r.cov, r.cov_rank);
        if (nu > 0) doc["lmfd"] = model_lmfd(lm);
        Json mj = multi_block(r, p, files, noise_source, nu);
        if (p.scan) mj["order_selection"] = order_selection_block(sel, p.rule);
        mj["best_start"] = r.best_start;
        const Json crb = cramer_rao_block(r, recs, ny, p.eiv);
        if (p.eiv) {
            Json ej;
            ej["input_noise_ratio"] = p.eiv_ratio;
            ej["model"] = "white noise on the inputs and the output, sigma_u = ratio * sigma_y; true inputs and initial "
                          "conditions eliminated (errors-in-variables ML); noise_variance estimates sigma_y^2";
            ej["cost"] = r.cost;
            mj["errors_in_variables"] = ej;
        }
        mj["cramer_rao"] = crb;
        doc["multi"] = mj;
        summarise(out, r, p, sel, noise_source, recs.size(), crb);
    } catch (const FitError &e) {
        throw Error(e.what());
    }
    return out;
}

}  // namespace msidfitjob
