// msid frf --method lpm|etfe: FRFs from arbitrary records (tools/est) -> msid-frf/1.
#include "commands.hpp"
#include "host_libs.hpp"
#include "msid_candump_dbc.hpp"

#include "msid_frf_est.hpp"

#include <algorithm>
#include <cstdio>
#include <thread>

namespace msidcli {

static const char *HELP_EST =
    "usage: msid frf --method lpm [--order R] [--window W] [--band F1:F2] [--fs HZ]\n"
    "                --experiment e1.csv [--experiment e2.csv ...] -o frf.json\n"
    "       msid frf --method etfe --period M [--delta D] [--gstar S] [--band F1:F2] [--fs HZ]\n"
    "                --experiment e1.csv [...] -o frf.json\n"
    "\n"
    "  --method lpm     local polynomial method (Pintelon et al. 2010): any input (noise, sweeps, steps);\n"
    "                   G and the transient are local polynomials of degree R over 2W+1 DFT bins of the\n"
    "                   whole record; every bin in the band is a line; dof = m(2W+1) - (R+1)(nu+m)\n"
    "  --order R        polynomial degree (default 2)\n"
    "  --window W       half-width (default: smallest W with dof >= n_outputs + 4)\n"
    "  --reference r1=COL,...  noisy input or closed loop: the LPM of [y; u] on these reference (command)\n"
    "                   signals, one per input, then G = G_yr G_ur^-1 with its linearised covariance\n"
    "                   (`--reference r1,r2`: the record's columns r1, r2); dof = m(2W+1) - (R+1)(nu+m)\n"
    "  --method etfe    empirical transfer function estimate for inputs of period M (Tsiamis et al. 2024),\n"
    "                   with the finite-sample bound of their Theorem 1 per line (field `bound`)\n"
    "  --period M       input period in samples; the record holds Np >= 2 whole periods\n"
    "  --delta D        failure probability of the bound, jointly over the M lines (default 0.05)\n"
    "  --gstar S        ||G||_* = sum_t t ||g_t||, adds the transient term of the bound (default: left out)\n"
    "  --band F1:F2     lines in [F1, F2]: Hz with --fs, else cycles/sample (default: all, DC excluded;\n"
    "                   long records give N/2 lines, each with its covariance: narrow the band)\n"
    "  --threads T      split the bins over T threads (default: up to 2); results do not depend on T\n"
    "  --experiment     record (CSV with header u1..u<nu>, y1..y<ny>, .npy/.npz, .mat); lpm: any m >= 1\n"
    "                   records of equal length; etfe: m >= nu records\n"
    "  --columns        map named columns to u1.., y1.. (as for the periodic estimator)\n";

namespace {

// --band F1:F2 as numbers (the ranges are the library's to check).
void parse_band(const Args &a, msidjob::EstPlan &p)
{
    if (!a.has("band")) return;
    const std::string s = a.get("band");
    const auto c = s.find(':');
    if (c == std::string::npos) throw UsageError("--band must be F1:F2 (got '" + s + "')");
    p.band = true;
    p.band_text = s;
    p.f1 = parse_double(s.substr(0, c), "--band");
    p.f2 = parse_double(s.substr(c + 1), "--band");
}

// The plan's options, each only when given: the library says which method they apply to.
msidjob::EstPlan est_plan(const Args &a)
{
    msidjob::EstPlan p;
    p.method = msidjob::est_method(a.get("method"));
    if (a.has("order")) p.order = a.u32("order", 0);
    if (a.has("window")) p.window = a.u32("window", 0);
    if (a.has("period")) p.period = a.u32("period", 0);
    if (a.has("delta")) p.delta = a.f64("delta", 0.0);
    if (a.has("gstar")) p.gstar = a.f64("gstar", 0.0);
    if (a.has("reference")) p.reference = parse_reference(a.get("reference"));
    // not given: the job's default (up to 2); the ranges are the job's (check_est_plan)
    for (const char *k : {"threads", "fs"})
        if (a.has(k)) p.given.add(k);
    p.threads = a.u32("threads", 0);
    parse_band(a, p);
    return p;
}

}  // namespace

int cmd_frf_est(int argc, char **argv)
{
    Args a(argc, argv, 2, HELP_EST, {"method", "order", "window", "band", "fs", "period", "delta", "gstar", "threads", "output", "columns", "reference"},
           {}, {"experiment"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "' (use --experiment)");
    const std::string method = a.get("method");
    const msidjob::EstPlan plan = est_plan(a);
    FrfRequest rq;
    rq.fs = a.f64("fs", 0.0);
    msidjob::check_est_plan(plan, rq.fs);
    const std::string out = a.require("output");
    if (a.all("experiment").empty()) throw UsageError("missing --experiment <file.csv>");
    const ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns")) : ColumnMap{};
    msidjob::check_reference_columns(plan.reference, cols);
    std::vector<Record> recs;
    for (const auto &p : a.all("experiment")) msidrec::refuse_candump_without_dbc(p);   // --dbc: periodic only
    for (const auto &p : a.all("experiment")) recs.push_back(read_experiment(p, cols));
    FrfOutcome o = msidjob::estimate_frf_est(rq, recs, plan);
    const size_t nlines = o.doc["lines"].size();
    write_json_file(out, o.doc);
    std::printf("wrote %s: %zu lines, %u output(s) x %u input(s), %u experiment(s), %zu samples each (%s)\n",
                out.c_str(), nlines, recs[0].ny, recs[0].nu, (unsigned)recs.size(), recs[0].n_rows, method.c_str());
    return 0;
}

}  // namespace msidcli
