// msid fit --method multi: maximum likelihood from several time-domain records
// (ring-downs, free decays, short transient-laden input-output experiments) with
// every record's initial conditions eliminated (tools/fit/multi.hpp; Markovsky &
// Pintelon §IV-VI). Writes the normal msid-model/1 file plus a "multi" section.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "model_io.hpp"
#include "models.hpp"
#include "multi.hpp"
#include "order_select.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace msidcli {

using namespace msidfit;

static const char *MULTI_HELP =
    "usage: msid fit --method multi --experiment r1.csv --experiment r2.csv ... --order n|auto|a:b -o model.json\n"
    "                [--columns u1=NAME,y1=NAME,...] [--fs HZ] [--feedthrough no|yes] [--start auto|kung|prony|sm]\n"
    "                [--max-iter N] [--order-rule mdl|aic] [--noise-ar c1,...,cp | --noise-ar-order p\n"
    "                [--noise-record noise.csv ...]] [--input-noise-ratio R]\n"
    "\n"
    "Maximum likelihood from N records of any lengths (Markovsky & Pintelon): each record's initial\n"
    "conditions are eliminated by least squares (variable projection), the n poles shared by all records\n"
    "and outputs found by Levenberg-Marquardt from Kung (stacked Hankel), Prony and Steiglitz-McBride starts.\n"
    "  records with only y columns: free responses, sum of n damped exponentials (poles, frequencies, damping)\n"
    "  records with u and y columns: y = b(q^-1)/a(q^-1) u + free response of every record (output error)\n"
    "  --order n        number of poles (required); auto (1..12) or a:b: fit every order and keep the least\n"
    "                   MDL (default) or AIC, -2 log L + k ln S (2k), k = n + numerator + N ny n initial conditions;\n"
    "                   the table and the stacked-Hankel singular values go to the model file (order_selection)\n"
    "  --noise-ar c1,..,cp  coloured output noise c(q^-1) v = e (stationary AR, same for every output): the\n"
    "                   ML cost in the weighted norm ||W (y - yhat)||, W the exact whitening factor\n"
    "  --noise-ar-order p   estimate the AR(p) noise: from --noise-record files (noise-only records, same\n"
    "                   columns) by Yule-Walker, else from the residuals of the unweighted fit (two-stage GLS)\n"
    "  --input-noise-ratio R  noisy inputs (errors-in-variables, one output): white noise on u and y with\n"
    "                   sigma_u = R sigma_y; the true inputs are eliminated with the initial conditions\n"
    "  --columns        map file columns to u1.., y1.. as in msid frf (u may be left out: free responses)\n"
    "  --fs HZ          sample rate: modes in Hz and rad/s (else cycles and rad per sample)\n"
    "  --feedthrough    yes: b has a direct term b_0 (default no)\n"
    "Reports the parameter covariance s^2 (J^T J)^-1 (J: Jacobian with the initial conditions projected\n"
    "out) and the Cramer-Rao bound at the estimate computed independently (full Fisher matrix over every\n"
    "parameter and initial condition by finite differences); exit status 3 if the iterations run out.\n"
    "Validate a model on records (fresh ones, or its own): msid validate model.json --experiment r.csv ...\n";

static Json params_block(const MultiResult &r)
{
    Json p;
    p["names"] = r.names;
    p["values"] = std::vector<double>(r.theta.data(), r.theta.data() + r.theta.size());
    p["cov"] = rmat_json(r.cov);
    p["cov_rank"] = r.cov_rank;
    return p;
}

static Json num_or_null_guard(double x) { return std::isfinite(x) ? Json(x) : Json(nullptr); }

static Json modes_block(const MultiResult &r, double h)
{
    Json a = Json::array();
    for (const auto &m : r.modes) {
        Json j;
        j["pole_z"] = Json{{"re", m.z.real()}, {"im", m.z.imag()}};
        j["sd_pole_z"] = Json{{"re", num_or_null_guard(m.sd_z_re)}, {"im", num_or_null_guard(m.sd_z_im)}};
        j["pole_ct"] = Json{{"re", m.s.real()}, {"im", m.s.imag()}};
        j["real"] = m.real;
        j[h > 0 ? "fn_hz" : "fn_cycles_per_sample"] = m.fn;
        j[h > 0 ? "sd_fn_hz" : "sd_fn_cycles_per_sample"] = num_or_null_guard(m.sd_fn);
        j[h > 0 ? "wn_rad_s" : "wn_rad_per_sample"] = m.wn;
        j[h > 0 ? "sd_wn_rad_s" : "sd_wn_rad_per_sample"] = num_or_null_guard(m.sd_wn);
        j["zeta"] = m.zeta;
        j["sd_zeta"] = num_or_null_guard(m.sd_zeta);
        a.push_back(j);
    }
    return a;
}

// Relative spectral-norm distance ||A - B|| / ||B||.
static double rel_spec(const MatR &A, const MatR &B)
{
    const double nb = Eigen::JacobiSVD<MatR>(B).singularValues()(0);
    return nb > 0 ? Eigen::JacobiSVD<MatR>(A - B).singularValues()(0) / nb : NAN;
}

// Read the records of --experiment (or --noise-record): same channels in every file.
static std::vector<MultiRecord> read_records(const std::vector<std::string> &files, const ColumnMap &cols,
                                             std::vector<size_t> *lengths, uint32_t *nu_out, uint32_t *ny_out)
{
    std::vector<MultiRecord> recs;
    uint32_t nu = 0, ny = 0;
    for (size_t i = 0; i < files.size(); ++i) {
        const Record r = read_experiment(files[i], cols);
        if (i == 0) {
            nu = r.nu;
            ny = r.ny;
        } else if (r.nu != nu || r.ny != ny) {
            throw Error(fmt("'%s' has %u input(s) and %u output(s), '%s' has %u and %u: every record of --method multi "
                            "must have the same channels",
                            files[i].c_str(), r.nu, r.ny, files[0].c_str(), nu, ny));
        }
        const size_t C = (size_t)r.nu + r.ny;
        MultiRecord m;
        m.u.resize((Eigen::Index)r.n_rows, r.nu);
        m.y.resize((Eigen::Index)r.n_rows, r.ny);
        const double *d = r.data();
        for (size_t t = 0; t < r.n_rows; ++t) {
            for (uint32_t k = 0; k < r.nu; ++k) m.u((Eigen::Index)t, k) = d[t * C + k];
            for (uint32_t j = 0; j < r.ny; ++j) m.y((Eigen::Index)t, j) = d[t * C + r.nu + j];
        }
        if (lengths) lengths->push_back(r.n_rows);
        recs.push_back(std::move(m));
    }
    if (nu_out) *nu_out = nu;
    if (ny_out) *ny_out = ny;
    return recs;
}

static VecR parse_ar(const std::string &s)
{
    std::vector<double> v;
    size_t pos = 0;
    while (pos <= s.size()) {
        const size_t c = s.find(',', pos);
        const std::string tok = s.substr(pos, c == std::string::npos ? std::string::npos : c - pos);
        v.push_back(parse_double(tok, "--noise-ar"));
        if (c == std::string::npos) break;
        pos = c + 1;
    }
    if (v.empty() || v.size() > 50) throw UsageError("--noise-ar takes 1..50 comma-separated coefficients c1,...,cp");
    return Eigen::Map<const VecR>(v.data(), (Eigen::Index)v.size());
}

int cmd_fit_multi(int argc, char **argv)
{
    Args a(argc, argv, 2, MULTI_HELP,
           {"method", "order", "columns", "fs", "feedthrough", "start", "max-iter", "output", "order-rule", "noise-ar",
            "noise-ar-order", "input-noise-ratio"},
           {}, {"experiment", "noise-record"});
    if (!a.positional().empty())
        throw UsageError("--method multi takes its records with --experiment FILE (got '" + a.positional()[0] + "')");
    const auto &files = a.all("experiment");
    if (files.empty()) throw UsageError("give at least one record with --experiment FILE");
    const std::string out = a.require("output");
    if (!a.has("order")) throw UsageError("give --order n (the number of poles), auto or a:b");
    MultiOptions o;
    const std::string ord = a.get("order");
    const bool scan = ord == "auto" || ord.find(':') != std::string::npos;
    std::vector<int> orders;
    if (scan) {
        try {
            orders = parse_order_range(ord, 1, 12, nullptr);
        } catch (const FitError &e) {
            throw UsageError(e.what());
        }
        o.order = orders.front();
    } else {
        o.order = (int)parse_u32(ord, "--order");
        if (o.order < 1 || o.order > 200) throw UsageError("--order must be 1..200, auto or a:b");
    }
    const std::string rule = a.get("order-rule", "mdl");
    if (rule != "mdl" && rule != "aic") throw UsageError("--order-rule must be mdl or aic (got '" + rule + "')");
    if (a.has("order-rule") && !scan) throw UsageError("--order-rule needs --order auto or a:b");
    if (a.has("noise-ar") && (a.has("noise-ar-order") || !a.all("noise-record").empty()))
        throw UsageError("give the noise model either as --noise-ar c1,..,cp or estimate it with --noise-ar-order p");
    if (!a.all("noise-record").empty() && !a.has("noise-ar-order"))
        throw UsageError("--noise-record needs --noise-ar-order p (the order of the AR model to estimate)");
    if (a.has("noise-ar")) {
        o.noise_ar = parse_ar(a.get("noise-ar"));
        try {
            multi_noise_from_ar(o.noise_ar);
        } catch (const FitError &e) {
            throw UsageError(std::string("--noise-ar: ") + e.what());
        }
    }
    double eiv_ratio = 0;
    if (a.has("input-noise-ratio")) {
        eiv_ratio = parse_double(a.get("input-noise-ratio"), "--input-noise-ratio");
        if (!(eiv_ratio >= 0) || !std::isfinite(eiv_ratio)) throw UsageError("--input-noise-ratio must be a finite number >= 0");
        if (a.has("noise-ar") || a.has("noise-ar-order"))
            throw UsageError("--input-noise-ratio (noisy inputs) takes white noise: leave out --noise-ar / --noise-ar-order");
    }
    if (a.has("noise-ar-order")) {
        o.noise_ar_order = (int)parse_u32(a.get("noise-ar-order"), "--noise-ar-order");
        if (o.noise_ar_order < 1 || o.noise_ar_order > 50) throw UsageError("--noise-ar-order must be 1..50");
    }
    if (a.has("fs")) {
        const double fs = parse_double(a.get("fs"), "--fs");
        if (!(fs > 0) || !std::isfinite(fs)) throw UsageError("--fs must be a positive sample rate in Hz");
        o.h = 1.0 / fs;
    }
    const std::string ft = a.get("feedthrough", "no");
    if (ft != "no" && ft != "yes") throw UsageError("--feedthrough must be no or yes (got '" + ft + "')");
    o.feedthrough = ft == "yes";
    o.start = a.get("start", "auto");
    if (o.start != "auto" && o.start != "kung" && o.start != "prony" && o.start != "sm")
        throw UsageError("--start must be auto, kung, prony or sm (got '" + o.start + "')");
    if (a.has("max-iter")) o.max_iter = (int)parse_u32(a.get("max-iter"), "--max-iter");
    ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns"), true) : ColumnMap{};
    cols.inputs_optional = true;

    // read every record (the reader names file, line and column of any bad cell, NaN or Inf)
    std::vector<size_t> lengths;
    uint32_t nu = 0, ny = 0;
    std::vector<MultiRecord> recs = read_records(files, cols, &lengths, &nu, &ny);
    for (size_t i = 0; i < recs.size() && !scan; ++i)
        if (lengths[i] <= (size_t)o.order)
            throw Error(fmt("'%s' has %zu samples: too few for order %d (each record needs more than n = %d samples: its "
                            "%d initial conditions per output are estimated from it)",
                            files[i].c_str(), lengths[i], o.order, o.order, o.order));
    std::string noise_source = o.noise_ar.size() ? "given (--noise-ar)" : "white";
    if (!a.all("noise-record").empty()) {
        uint32_t nnu = 0, nny = 0;
        const std::vector<MultiRecord> nrec = read_records(a.all("noise-record"), cols, nullptr, &nnu, &nny);
        if (nnu != nu || nny != ny)
            throw Error(fmt("the noise records have %u input(s) and %u output(s), the experiments %u and %u: give them "
                            "the same columns", nnu, nny, nu, ny));
        std::vector<MatR> v;
        for (const auto &x : nrec) v.push_back(x.y.rowwise() - x.y.colwise().mean());
        try {
            o.noise_ar = multi_ar_yule_walker(v, o.noise_ar_order);
            multi_noise_from_ar(o.noise_ar);
        } catch (const FitError &e) {
            throw Error(std::string("the noise records: ") + e.what());
        }
        noise_source = fmt("estimated from %zu noise record(s) (Yule-Walker AR(%d))", nrec.size(), o.noise_ar_order);
        o.noise_ar_order = 0;
    } else if (o.noise_ar_order > 0) {
        noise_source = fmt("estimated from the residuals (two-stage, Yule-Walker AR(%d))", o.noise_ar_order);
    }
    if (a.has("input-noise-ratio") && (nu == 0 || ny != 1))
        throw UsageError("--input-noise-ratio needs input columns and one output (noisy inputs, one output)");
    if (nu == 0 && o.feedthrough) throw UsageError("--feedthrough yes needs input columns: free responses have no inputs");
    if (nu == 0 && o.start == "sm") throw UsageError("--start sm needs input columns; free responses use kung or prony");
    if (nu > 0 && o.start == "kung") throw UsageError("--start kung needs free responses (records without input columns)");

    try {
        MultiOrderSelection sel;
        if (scan) {
            sel = multi_select_order(recs, o, orders, rule, true);
            o.order = sel.chosen;
        }
        MultiResult r = scan ? sel.best : multi_fit(recs, o);
        const bool eiv = a.has("input-noise-ratio");
        if (eiv) {   // noisy inputs: the errors-in-variables estimate replaces the output-error one (multi_eiv.cpp)
            const MultiEivResult e = multi_fit_eiv(recs, o, eiv_ratio);
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
        // the model as an LMFD with D(q^-1) = a(q^-1) I and N_d = beta_d, realised in observer form
        LmfdModel lm;
        lm.domain = Domain::DT;
        lm.h = o.h;
        lm.nD = r.n;
        lm.nN = r.n;
        for (int m = 1; m <= r.n; ++m) lm.Dm.push_back(MatR::Identity(ny, ny) * r.alpha(m - 1));
        for (int d = 0; d <= r.n; ++d)
            lm.Nm.push_back(d >= r.d0 && nu > 0 ? r.beta[(size_t)(d - r.d0)] : MatR::Zero(ny, nu));
        const SSModel ss = lmfd_to_ss(lm);

        Json doc;
        doc["format"] = "msid-model/1";
        doc["generator"] = std::string("msid ") + MSID_VERSION;
        doc["source"] = files;
        doc["domain"] = "dt";
        if (o.h > 0) doc["sample_time"] = o.h;
        doc["method"] = "multi";
        doc["order"] = (int)ss.n();
        doc["n_inputs"] = nu;
        doc["n_outputs"] = ny;
        Json settings;
        settings["order"] = o.order;
        settings["feedthrough"] = ft;
        settings["start"] = o.start;
        settings["max_iter"] = o.max_iter;
        settings["weight"] = r.noise_ar.size() ? "noise-ar" : "none";
        if (eiv) settings["input_noise_ratio"] = eiv_ratio;
        if (scan) settings["order_range"] = ord;
        if (a.has("columns")) settings["columns"] = a.get("columns");
        doc["settings"] = settings;
        doc["A"] = rmat_json(ss.A);
        doc["B"] = rmat_json(ss.B);
        doc["C"] = rmat_json(ss.C);
        doc["D"] = rmat_json(ss.D);
        doc["stable"] = ss_stable(ss);
        doc["n_params"] = (int)r.theta.size();
        doc["converged"] = r.converged;
        doc["parameters"] = params_block(r);
        if (nu > 0) {
            Json l;
            l["nD"] = lm.nD;
            l["nN"] = lm.nN;
            l["variable"] = "z^-1";
            Json D = Json::array(), N = Json::array();
            for (const auto &x : lm.Dm) D.push_back(rmat_json(x));
            for (const auto &x : lm.Nm) N.push_back(rmat_json(x));
            l["D"] = D;
            l["N"] = N;
            doc["lmfd"] = l;
        }
        Json mj;
        mj["model"] = nu > 0 ? "y_j = sum_k b_jk(q^-1)/a(q^-1) u_k + free response of a(q^-1) per record and output"
                             : "every output of every record: a sum of the same n damped exponentials z_k^t";
        mj["alpha"] = std::vector<double>(r.alpha.data(), r.alpha.data() + r.alpha.size());
        mj["alpha_convention"] = "a(q^-1) = 1 + alpha_1 q^-1 + ... + alpha_n q^-n; poles: roots of z^n + alpha_1 z^(n-1) + ... + alpha_n";
        mj["modes"] = modes_block(r, o.h);
        Json recj = Json::array();
        for (size_t i = 0; i < files.size(); ++i)
            recj.push_back(Json{{"file", files[i]}, {"samples", lengths[i]},
                                {"initial_conditions", eiv ? Json(nullptr) : rmat_json(r.x0[i])}});
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
        for (const auto &s : r.starts) st.push_back(Json{{"start", s.name}, {"cost", s.cost}});
        mj["starts"] = st;
        Json nz;
        nz["model"] = r.noise_ar.size() ? "stationary AR: c(q^-1) v = e, the same for every output" : "white";
        nz["ar"] = std::vector<double>(r.noise_ar.data(), r.noise_ar.data() + r.noise_ar.size());
        nz["source"] = noise_source;
        nz["innovations_variance"] = r.s2;
        nz["note"] = "the cost, noise_variance and covariance are in the whitened norm ||W (y - yhat)||^2 (W^T W = Sigma^-1)";
        mj["noise"] = nz;
        if (scan) {
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
            mj["order_selection"] = os;
        }
        mj["best_start"] = r.best_start;
        // the Cramer-Rao bound at the estimate, computed by the independent route of multi_crb()
        const long P = (long)r.theta.size() + (long)recs.size() * ny * r.n;
        Json crb;
        if (eiv) {
            crb["cov"] = nullptr;
            crb["note"] = "not computed for noisy inputs (the bound of multi_crb is the output-error one)";
            Json ej;
            ej["input_noise_ratio"] = eiv_ratio;
            ej["model"] = "white noise on the inputs and the output, sigma_u = ratio * sigma_y; true inputs and initial "
                          "conditions eliminated (errors-in-variables ML); noise_variance estimates sigma_y^2";
            ej["cost"] = r.cost;
            mj["errors_in_variables"] = ej;
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
        mj["cramer_rao"] = crb;
        doc["multi"] = mj;
        write_json_file(out, doc);
        if (scan) {
            std::printf("order  cost          k      %-12s %s\n", rule == "mdl" ? "MDL" : "AIC", "converged");
            for (const auto &row : sel.rows) {
                if (!row.ok) {
                    std::printf("%-6d failed: %s\n", row.order, row.error.c_str());
                    continue;
                }
                std::printf("%-6d %-13.6g %-6.0f %-12.6g %s%s\n", row.order, row.cost, row.k, rule == "mdl" ? row.mdl : row.aic,
                            row.converged ? "yes" : "no", row.order == sel.chosen ? "  <- chosen" : "");
            }
            if (sel.hankel_gap_order > 0)
                std::printf("stacked Hankel singular values: largest gap after %d\n", sel.hankel_gap_order);
        }
        if (r.noise_ar.size()) std::printf("noise: AR(%d) %s\n", (int)r.noise_ar.size(), noise_source.c_str());
        std::printf("wrote %s: multi fit of %zu record(s), %d pole(s), noise sd %.4g, %s after %d iterations (start %s)\n",
                    out.c_str(), recs.size(), r.n, std::sqrt(r.s2), r.converged ? "converged" : "NOT converged",
                    r.iterations, r.best_start.c_str());
        for (const auto &m : r.modes)
            std::printf("  %s %.6g +- %.2g %s, damping %.5g +- %.2g\n", m.real ? "real pole" : "mode", m.fn, m.sd_fn,
                        o.h > 0 ? "Hz" : "cycles/sample", m.zeta, m.sd_zeta);
        if (!crb["cov"].is_null())
            std::printf("  covariance vs Cramer-Rao bound (independent route): relative difference %.2g\n",
                        crb["rel_diff_cov"].get<double>());
        if (!r.converged) {
            std::fprintf(stderr, "msid fit: warning: multi did not converge in %d iterations: wrote the best iterate to %s "
                                 "marked \"converged\": false (exit status 3)\n", r.iterations, out.c_str());
            return 3;
        }
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

// ---------------- msid validate model.json --experiment r.csv ... ----------------

// The model of a --method multi file: poles, numerator, noise AR, noise variance and its dof.
struct MultiModelDoc {
    VecR alpha, noise;
    std::vector<MatR> beta;
    int d0 = 1, nu = 0, ny = 0;
    double s2 = 0, dof = 0, h = 0;
    std::vector<std::string> sources;
};

static MultiModelDoc multi_model_doc(const Json &j, const std::string &path)
{
    if (!j.is_object() || j.value("format", "") != "msid-model/1")
        throw Error("'" + path + "': not an msid-model/1 file");
    if (j.value("method", "") != "multi" || !j.contains("multi") || !j["multi"].is_object())
        throw Error("'" + path + "': validation on records needs a model written by msid fit --method multi (this one is '" +
                    j.value("method", std::string("?")) + "'; validate FRF models against an FRF file)");
    try {
        MultiModelDoc m;
        const Json &mj = j["multi"];
        const auto al = mj.at("alpha").get<std::vector<double>>();
        m.alpha = Eigen::Map<const VecR>(al.data(), (Eigen::Index)al.size());
        m.nu = j.at("n_inputs").get<int>();
        m.ny = j.at("n_outputs").get<int>();
        m.s2 = mj.at("noise_variance").get<double>();
        m.dof = mj.at("dof").get<double>();
        m.h = j.contains("sample_time") && j["sample_time"].is_number() ? j["sample_time"].get<double>() : 0.0;
        if (mj.contains("noise") && mj["noise"].contains("ar")) {
            const auto c = mj["noise"]["ar"].get<std::vector<double>>();
            m.noise = Eigen::Map<const VecR>(c.data(), (Eigen::Index)c.size());
        }
        const int n = (int)m.alpha.size();
        if (n < 1 || !m.alpha.allFinite() || m.ny < 1 || m.nu < 0 || !(m.s2 > 0))
            throw Error("'" + path + "': the multi section has no usable poles, channels or noise variance");
        if (m.nu > 0) {
            m.d0 = j.at("settings").value("feedthrough", std::string("no")) == "yes" ? 0 : 1;
            const Json &N = j.at("lmfd").at("N");
            if ((int)N.size() != n + 1) throw Error("'" + path + "': lmfd.N must hold n + 1 matrices");
            for (int d = m.d0; d <= n; ++d) {
                MatR B(m.ny, m.nu);
                for (int r = 0; r < m.ny; ++r)
                    for (int k = 0; k < m.nu; ++k) B(r, k) = N.at((size_t)d).at((size_t)r).at((size_t)k).get<double>();
                m.beta.push_back(B);
            }
        }
        if (j.contains("source") && j["source"].is_array())
            for (const auto &s : j["source"]) m.sources.push_back(s.get<std::string>());
        return m;
    } catch (const Json::exception &e) {
        throw Error("'" + path + "': malformed multi model (" + e.what() + ")");
    }
}

int cmd_validate_multi(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid validate model.json --experiment r1.csv [--experiment r2.csv ...] [--columns ...] [--lags M]\n"
        "                     [-o report.json]\n"
        "A model of msid fit --method multi (free responses or input-output) on time records. The initial\n"
        "conditions of each record are not part of the model: they are re-estimated by least squares, the\n"
        "poles, numerator and noise model are fixed. The residuals are the recursive residuals (standardised\n"
        "one-step prediction errors of the initial conditions in time order, whitened by the noise model):\n"
        "T - n per record and output, independent N(0, s^2) if the model is right. Two tests:\n"
        "  cost       s^2 of the records against the model's noise variance: F(dof, dof of the fit), upper tail\n"
        "  whiteness  pooled residual autocorrelation at lags 1..M (default 10): chi2(M)\n"
        "Verdict at 5%: both p-values >= 2.5% (Bonferroni). On the model's own records only the whiteness test\n"
        "counts (the cost was minimised on them).\n";
    Args a(argc, argv, 2, HELP, {"columns", "lags", "output"}, {}, {"experiment"});
    if (a.positional().size() != 1) throw UsageError("give one model file (and its records with --experiment FILE)");
    const std::string path = a.positional()[0];
    const MultiModelDoc m = multi_model_doc(read_json_file(path), path);
    ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns"), true) : ColumnMap{};
    cols.inputs_optional = true;
    const auto &files = a.all("experiment");
    const int lags = (int)a.u32("lags", 10);
    if (lags < 1) throw UsageError("--lags must be at least 1");
    uint32_t nu = 0, ny = 0;
    std::vector<size_t> lengths;
    const std::vector<MultiRecord> recs = read_records(files, cols, &lengths, &nu, &ny);
    if ((int)nu != m.nu || (int)ny != m.ny)
        throw Error(fmt("the model has %d input(s) and %d output(s), the records %u and %u", m.nu, m.ny, nu, ny));
    bool own = files.size() == m.sources.size();
    for (size_t i = 0; own && i < files.size(); ++i) own = files[i] == m.sources[i];
    try {
        const MultiCheck c = multi_check(recs, m.alpha, m.beta, m.d0, m.noise, m.s2, m.dof, lags);
        const bool ok = own ? c.p_white >= 0.05 : c.p_white >= 0.025 && c.p_cost >= 0.025;
        std::printf("model %s on %zu record(s): %.0f recursive residuals, noise variance %.6g against the model's %.6g "
                    "(F = %.4g, p = %.4g%s)\n", path.c_str(), recs.size(), c.dof, c.s2, m.s2, c.f_stat, c.p_cost,
                    own ? ", the model's own records: not a test" : "");
        std::printf("whiteness: residual autocorrelation at lags 1..%d, Q = %.4g against chi2(%d), p = %.4g\n", c.lags, c.q_lb,
                    c.lags, c.p_white);
        std::printf("verdict: %s\n", ok ? "consistent with the records at 5%" : "NOT consistent with the records at 5%");
        if (a.has("output")) {
            Json r;
            r["format"] = "msid-validation/1";
            r["model"] = path;
            r["records"] = files;
            r["kind"] = "records";
            r["own_records"] = own;
            r["residuals"] = "recursive residuals of the initial conditions (Brown-Durbin-Evans), whitened by the noise model";
            r["cost"] = c.cost;
            r["dof"] = c.dof;
            r["noise_variance"] = c.s2;
            r["model_noise_variance"] = m.s2;
            r["model_dof"] = m.dof;
            r["f_statistic"] = c.f_stat;
            r["p_value_cost"] = c.p_cost;
            r["lags"] = c.lags;
            r["autocorrelation"] = std::vector<double>(c.rho.data(), c.rho.data() + c.rho.size());
            r["q_statistic"] = c.q_lb;
            r["p_value_whiteness"] = c.p_white;
            r["p_value"] = own ? c.p_white : std::min(1.0, 2.0 * std::min(c.p_white, c.p_cost));
            r["consistent_at_5pct"] = ok;
            write_json_file(a.get("output"), r);
        }
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

// ---------------- msid modes for a --method multi model ----------------

int cmd_modes_multi(const Json &j, const std::string &path, const std::string &out)
{
    const MultiModelDoc m = multi_model_doc(j, path);
    const int n = (int)m.alpha.size();
    MatR cov;
    try {
        const Json &c = j.at("parameters").at("cov");
        if ((int)c.size() >= n) {
            cov.resize(n, n);
            for (int r = 0; r < n; ++r)
                for (int k = 0; k < n; ++k) cov(r, k) = c.at((size_t)r).at((size_t)k).get<double>();
        }
    } catch (const Json::exception &) {
        cov.resize(0, 0);
    }
    const std::vector<MultiMode> md = multi_modes(m.alpha, cov, m.h);
    const bool hz = m.h > 0;
    std::printf("%s: %d pole(s) from msid fit --method multi (%s), standard deviations %s\n", path.c_str(), n,
                m.nu ? "input-output" : "free responses", cov.size() ? "by the delta method from the pole covariance" : "not available");
    std::printf("  %-10s %-24s %-24s\n", "", hz ? "fn (Hz)" : "fn (cycles/sample)", "damping ratio");
    for (const auto &x : md)
        std::printf("  %-10s %-24s %-24s\n", x.real ? "real pole" : "mode", fmt("%.6g +- %.2g", x.fn, x.sd_fn).c_str(),
                    fmt("%.5g +- %.2g", x.zeta, x.sd_zeta).c_str());
    if (!out.empty()) {
        Json o;
        o["format"] = "msid-modes/1";
        o["model"] = path;
        o["frequency_unit"] = hz ? "Hz" : "cycles/sample";
        o["sd_source"] = cov.size() ? "delta method from the covariance of the characteristic coefficients alpha (multi)"
                                    : "none: the model file holds no parameter covariance";
        o["residue_note"] = "no residues: a multi model's modes are shared by every record, whose amplitudes are its initial conditions";
        Json arr = Json::array();
        for (const auto &x : md) {
            Json e;
            e["pole"] = {x.z.real(), x.z.imag()};
            e["pole_ct"] = {x.s.real(), x.s.imag()};
            e["real_pole"] = x.real;
            e["fn"] = x.fn;
            e["wn"] = x.wn;
            e["zeta"] = x.zeta;
            e["sd_fn"] = num_or_null_guard(x.sd_fn);
            e["sd_wn"] = num_or_null_guard(x.sd_wn);
            e["sd_zeta"] = num_or_null_guard(x.sd_zeta);
            arr.push_back(e);
        }
        o["modes"] = arr;
        write_json_file(out, o);
    }
    return 0;
}

}  // namespace msidcli
