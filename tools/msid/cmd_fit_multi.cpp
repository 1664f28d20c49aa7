// msid fit --method multi: maximum likelihood from several time-domain records
// (ring-downs, free decays, short transient-laden input-output experiments) with
// every record's initial conditions eliminated (tools/fit/multi.hpp; Markovsky &
// Pintelon §IV-VI). Writes the normal msid-model/1 file plus a "multi" section.
#include "cli_util.hpp"
#include "commands.hpp"
#include "csv_io.hpp"
#include "frf_io.hpp"

#include "model_io.hpp"
#include "models.hpp"
#include "multi.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace msidcli {

using namespace msidfit;

static const char *MULTI_HELP =
    "usage: msid fit --method multi --experiment r1.csv --experiment r2.csv ... --order n -o model.json\n"
    "                [--columns u1=NAME,y1=NAME,...] [--fs HZ] [--feedthrough no|yes] [--start auto|kung|prony|sm]\n"
    "                [--max-iter N]\n"
    "\n"
    "Maximum likelihood from N records of any lengths (Markovsky & Pintelon): each record's initial\n"
    "conditions are eliminated by least squares (variable projection), the n poles shared by all records\n"
    "and outputs found by Levenberg-Marquardt from Kung (stacked Hankel), Prony and Steiglitz-McBride starts.\n"
    "  records with only y columns: free responses, sum of n damped exponentials (poles, frequencies, damping)\n"
    "  records with u and y columns: y = b(q^-1)/a(q^-1) u + free response of every record (output error)\n"
    "  --order n        number of poles (required)\n"
    "  --columns        map file columns to u1.., y1.. as in msid frf (u may be left out: free responses)\n"
    "  --fs HZ          sample rate: modes in Hz and rad/s (else cycles and rad per sample)\n"
    "  --feedthrough    yes: b has a direct term b_0 (default no)\n"
    "Reports the parameter covariance s^2 (J^T J)^-1 (J: Jacobian with the initial conditions projected\n"
    "out) and the Cramer-Rao bound at the estimate computed independently (full Fisher matrix over every\n"
    "parameter and initial condition by finite differences); exit status 3 if the iterations run out.\n";

bool fit_method_is(int argc, char **argv, const char *method)
{
    for (int i = 2; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--method") && i + 1 < argc && !std::strcmp(argv[i + 1], method)) return true;
        if (!std::strncmp(argv[i], "--method=", 9) && !std::strcmp(argv[i] + 9, method)) return true;
    }
    return false;
}

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

int cmd_fit_multi(int argc, char **argv)
{
    Args a(argc, argv, 2, MULTI_HELP, {"method", "order", "columns", "fs", "feedthrough", "start", "max-iter", "output"}, {},
           {"experiment"});
    if (!a.positional().empty())
        throw UsageError("--method multi takes its records with --experiment FILE (got '" + a.positional()[0] + "')");
    const auto &files = a.all("experiment");
    if (files.empty()) throw UsageError("give at least one record with --experiment FILE");
    const std::string out = a.require("output");
    if (!a.has("order")) throw UsageError("give --order n (the number of poles)");
    MultiOptions o;
    o.order = (int)parse_u32(a.get("order"), "--order");
    if (o.order < 1 || o.order > 200) throw UsageError("--order must be 1..200");
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
    std::vector<MultiRecord> recs;
    std::vector<size_t> lengths;
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
        if (r.n_rows <= (size_t)o.order)
            throw Error(fmt("'%s' has %zu samples: too few for order %d (each record needs more than n = %d samples: its "
                            "%d initial conditions per output are estimated from it)",
                            files[i].c_str(), r.n_rows, o.order, o.order, o.order));
        const size_t C = (size_t)r.nu + r.ny;
        MultiRecord m;
        m.u.resize((Eigen::Index)r.n_rows, r.nu);
        m.y.resize((Eigen::Index)r.n_rows, r.ny);
        const double *d = r.data();
        for (size_t t = 0; t < r.n_rows; ++t) {
            for (uint32_t k = 0; k < r.nu; ++k) m.u((Eigen::Index)t, k) = d[t * C + k];
            for (uint32_t j = 0; j < r.ny; ++j) m.y((Eigen::Index)t, j) = d[t * C + r.nu + j];
        }
        lengths.push_back(r.n_rows);
        recs.push_back(std::move(m));
    }
    if (nu == 0 && o.feedthrough) throw UsageError("--feedthrough yes needs input columns: free responses have no inputs");
    if (nu == 0 && o.start == "sm") throw UsageError("--start sm needs input columns; free responses use kung or prony");
    if (nu > 0 && o.start == "kung") throw UsageError("--start kung needs free responses (records without input columns)");

    try {
        const MultiResult r = multi_fit(recs, o);
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
        settings["weight"] = "none";
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
            recj.push_back(Json{{"file", files[i]}, {"samples", lengths[i]}, {"initial_conditions", rmat_json(r.x0[i])}});
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
        mj["best_start"] = r.best_start;
        // the Cramer-Rao bound at the estimate, computed by the independent route of multi_crb()
        const long P = (long)r.theta.size() + (long)recs.size() * ny * r.n;
        Json crb;
        if (P <= 1500 && r.cov_rank == (int)r.theta.size()) {
            std::vector<MatR> us;
            for (const auto &x : recs) us.push_back(x.u);
            const MatR C = multi_crb(r.alpha, r.beta, r.d0, us, r.x0, (int)ny, r.s2);
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

}  // namespace msidcli
