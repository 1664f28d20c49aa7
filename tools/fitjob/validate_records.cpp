// `msid validate MODEL --experiment ...` as a library call: a model of --method multi on time
// records. The records' initial conditions are re-estimated, the poles, numerator and noise model
// kept; the recursive residuals give a cost test (F against the model's noise variance) and a
// whiteness test (multi.hpp, multi_check). On the model's own records only whiteness counts.
#include "fit_job_detail.hpp"

#include "multi.hpp"

#include <algorithm>
#include <cmath>

namespace msidfitjob {

void check_multi_model(const Json &model_doc, const std::string &path) { (void)multi_model_doc(model_doc, path); }

ValidateOutcome validate_records(const Json &model_doc, const std::string &path, const std::vector<Record> &rr,
                                 int lags, std::optional<bool> own_given)
{
    const MultiModelDoc m = multi_model_doc(model_doc, path);
    if (lags < 1) throw UsageError(MSID_OPT("lags") " must be at least 1");
    const std::vector<MultiRecord> recs = multi_records(rr);
    const uint32_t nu = rr.empty() ? 0 : rr[0].nu, ny = rr.empty() ? 0 : rr[0].ny;
    if ((int)nu != m.nu || (int)ny != m.ny)
        throw Error(fmt("the model has %d input(s) and %d output(s), the records %u and %u", m.nu, m.ny, nu, ny));
    std::vector<std::string> files;
    for (const Record &r : rr) files.push_back(r.path);
    bool own = files.size() == m.sources.size();
    for (size_t i = 0; own && i < files.size(); ++i) own = files[i] == m.sources[i];
    if (own_given) own = *own_given;
    const MultiCheck c = multi_check(recs, m.alpha, m.beta, m.d0, m.noise, m.s2, m.dof, lags);
    // never a verdict from residuals that are not numbers (they gave "consistent, p = 1")
    if (!std::isfinite(c.cost) || !std::isfinite(c.s2) || !std::isfinite(c.q_lb))
        throw Error(fmt("the recursive residuals of '%s' on the records are not finite (their variance is %g): the "
                        "model's prediction diverges on them (an unstable model: msid modes shows its poles); no verdict",
                        path.c_str(), c.s2));
    ValidateOutcome out;
    out.consistent = own ? c.p_white >= 0.05 : c.p_white >= 0.025 && c.p_cost >= 0.025;
    out.text.push_back(fmt("model %s on %zu record(s): %.0f recursive residuals, noise variance %.6g against the model's "
                           "%.6g (F = %.4g, p = %.4g%s)",
                           path.c_str(), recs.size(), c.dof, c.s2, m.s2, c.f_stat, c.p_cost,
                           own ? ", the model's own records: not a test" : ""));
    out.text.push_back(fmt("whiteness: residual autocorrelation at lags 1..%d, Q = %.4g against chi2(%d), p = %.4g",
                           c.lags, c.q_lb, c.lags, c.p_white));
    out.text.push_back(std::string("verdict: ") + (out.consistent ? "consistent with the records at 5%"
                                                                   : "NOT consistent with the records at 5%"));
    Json &r = out.report;
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
    r["consistent_at_5pct"] = out.consistent;
    return out;
}

}  // namespace msidfitjob
