// msid fit --method multi (records with eliminated initial conditions, tools/fitjob), msid validate
// model.json --experiment ... and msid modes of a multi model: options -> one library call -> output.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "msid_fit_job.hpp"
#include "multi.hpp"

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

// Read the records of --experiment (or --noise-record), in the order given.
static std::vector<Record> read_records(const std::vector<std::string> &files, const ColumnMap &cols)
{
    std::vector<Record> recs;
    for (const auto &f : files) recs.push_back(read_experiment(f, cols));
    return recs;
}

static Json num_or_null_guard(double x) { return std::isfinite(x) ? Json(x) : Json(nullptr); }

static std::vector<double> parse_ar(const std::string &s)
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
    return v;
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
    msidfitjob::MultiRequest rq;
    rq.order = a.get("order");
    rq.order_rule = a.get("order-rule");
    if (a.has("noise-ar")) rq.noise_ar = parse_ar(a.get("noise-ar"));
    if (a.has("noise-ar-order")) rq.noise_ar_order = parse_u32(a.get("noise-ar-order"), "--noise-ar-order");
    if (a.has("input-noise-ratio")) rq.input_noise_ratio = parse_double(a.get("input-noise-ratio"), "--input-noise-ratio");
    if (a.has("fs")) rq.fs = parse_double(a.get("fs"), "--fs");
    rq.feedthrough = a.get("feedthrough", "no");
    rq.start = a.get("start", "auto");
    if (a.has("max-iter")) rq.max_iter = parse_u32(a.get("max-iter"), "--max-iter");
    rq.columns = a.get("columns");
    msidfitjob::check_multi(rq, !a.all("noise-record").empty());
    ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns"), true) : ColumnMap{};
    cols.inputs_optional = true;
    // every record (the reader names file, line and column of any bad cell, NaN or Inf)
    const std::vector<Record> recs = read_records(files, cols);
    const std::vector<Record> noise = read_records(a.all("noise-record"), cols);
    return write_fit(msidfitjob::fit_multi(recs, noise, rq, print_fit_note), out, true);
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
    const std::vector<Record> rr = read_records(files, cols);
    const std::vector<MultiRecord> recs = msidfitjob::multi_records(rr);
    const uint32_t nu = rr.empty() ? 0 : rr[0].nu, ny = rr.empty() ? 0 : rr[0].ny;
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
