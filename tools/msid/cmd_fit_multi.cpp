// msid fit --method multi (records with eliminated initial conditions) and msid validate model.json
// --experiment ...: options -> one library call (tools/fitjob) -> output.
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
    const Json model = read_json_file(path);
    msidfitjob::check_multi_model(model, path);   // a model of another method is named before its records are read
    ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns"), true) : ColumnMap{};
    cols.inputs_optional = true;
    const int lags = (int)a.u32("lags", 10);
    if (lags < 1) throw UsageError("--lags must be at least 1");
    const std::vector<Record> recs = read_records(a.all("experiment"), cols);
    try {
        const msidfitjob::ValidateOutcome v = msidfitjob::validate_records(model, path, recs, lags);
        for (const std::string &line : v.text) std::printf("%s\n", line.c_str());
        if (a.has("output")) write_json_file(a.get("output"), v.report);
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

}  // namespace msidcli
