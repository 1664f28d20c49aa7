// `msid validate MODEL FRF` as a library call: the weighted residual cost of a model on an FRF
// against its law (validation_stat.hpp), per-line normalised residuals, the verdict at 5%, and,
// when the FRF carries nonlinear-distortion information, whether the residuals sit at the noise
// level, at the distortion level or above both. docs/fitting.md, "Validation".
#include "fit_job_detail.hpp"
#include "validation_stat.hpp"

#include "msid_cancel.hpp"
#include "nl_verdict.hpp"
#include "stats.hpp"

#include <cmath>

namespace msidfitjob {

namespace {

// The model describes the FRF's channels and frequencies.
void check_model_matches_frf(const ModelFile &mf, const FrfData &f)
{
    check_model_has_frf(mf);
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
}

MatC model_at(const ModelFile &mf, const cd &x) { return mf.lmfd ? lmfd_eval(*mf.lmfd, x) : ss_eval(mf.ss, x); }

// The weighting of the verdict: the FRF covariance whatever weighting the fit used (a --weight none
// fit is validated with the covariance: unit weights would make the verdict depend on the units);
// known-input for a model fitted with it. Unit weights only for an FRF without any covariance: a
// covariance that is there but unusable is refused with its cause (a fall-back to unit weights gave
// "consistent, p = 1" for any model).
Weight verdict_weight(const ModelFile &mf, const FrfData &f, const ValidateRequest &rq, std::string &name)
{
    if (rq.weight) {
        name = *rq.weight == Weight::Cov ? "cov" : *rq.weight == Weight::KnownInput ? "known-input" : "none";
        return *rq.weight;
    }
    const bool ki = mf.weight == "known-input";
    bool has_cov = false;
    for (const auto &l : f.lines) has_cov = has_cov || l.cov.size() > 0;
    if (!ki && !has_cov) {
        name = "none";
        return Weight::None;
    }
    name = ki ? "known-input" : "cov";
    return ki ? Weight::KnownInput : Weight::Cov;
}

// Noise level against distortion level, from the FRF document's nonlinear_distortion (a robust BLA:
// the same cost weighted by the noise covariance alone) or its detection lines; null without either.
Json distortion_verdict(const Json &frf_doc, const FrfData &frf, const ModelFile &mf, const std::string &weight,
                        double p_total, std::vector<std::string> &text)
{
    const Json nl = frf_doc.contains("nonlinear_distortion") ? frf_doc["nonlinear_distortion"]
                                                              : msidjob::detection_distortion(frf_doc);
    if (nl.is_null()) return nullptr;
    Json v;
    if (nl.contains("noise_separated") && nl["noise_separated"].is_boolean() && !nl["noise_separated"].get<bool>()) {
        // one period per realisation: cov is the total (noise + distortion), with no noise part to compare
        v["noise_separated"] = false;
        v["p_value_total"] = p_total;
        const std::string finding =
            weight != "cov"  ? "not judged: the weights are not the total covariance"
            : p_total >= 0.05 ? "residuals consistent with the total (noise + distortion) covariance; the noise alone "
                                "is not known (one period per realisation), so a model error below the distortion "
                                "level cannot be told apart"
                              : "residuals above the noise and the nonlinear distortion: model error";
        v["finding"] = finding;
        text.push_back(fmt("nonlinear distortion (%d realisations of one period: noise and distortion not separated): %s "
                           "(p = %.3g with the total covariance)",
                           nl["realisations"].get<int>(), finding.c_str(), p_total));
        return v;
    }
    v["distortion_detected"] = nl["distortion_detected"];
    v["nl_to_noise_db"] = nl["nl_to_noise_db"];
    const bool det = nl["distortion_detected"].get<bool>();
    const std::string lvl = nl["nl_to_noise_db"].is_number() ? fmt("%.1f dB", nl["nl_to_noise_db"].get<double>()) : "below the noise";
    if (nl["realisations"].get<int>() >= 2 && weight == "cov") {
        // the same cost weighted by the noise covariance only
        FrfData f = frf;
        const Json &lines = frf_doc.at("lines");
        for (size_t l = 0; l < f.lines.size(); ++l) {
            const Json &c = lines.at(l).at("cov_noise");
            f.lines[l].cov = msidfrf::parse_cmat(c, f.g(), f.g(), f.path, "lines[" + std::to_string(l) + "].cov_noise");
            f.lines[l].dof = lines[l].at("dof_noise").get<double>();
        }
        const auto w = weigh(f, mf.domain, Weight::Cov);
        double V = 0, neq = 0, nmin = 1e300;
        for (size_t l = 0; l < w.size(); ++l) {
            const MatC d = w[l].G - model_at(mf, w[l].x);
            V += (w[l].real ? 0.5 : 1.0) * (w[l].Linv * Eigen::Map<const MatC>(d.data(), d.size(), 1)).squaredNorm();
            neq += (w[l].real ? 1.0 : 2.0) * (double)f.g();
            nmin = std::min(nmin, w[l].dof);
        }
        const double pn = cost_pvalue(cost_law(neq - mf.n_params, nmin, (double)f.ny), V);
        v["p_value_noise_only"] = pn;
        v["p_value_total"] = p_total;
        std::string finding;
        if (p_total >= 0.05 && pn >= 0.05) finding = "residuals at the noise level";
        else if (p_total >= 0.05) finding = "residuals at the nonlinear distortion level: consistent with the total (noise + distortion) covariance, not with the noise alone";
        else finding = "residuals above the noise and the nonlinear distortion: model error";
        v["finding"] = finding;
        text.push_back(fmt("nonlinear distortion (%d realisations, %s relative to the noise%s): %s (p = %.3g with the total "
                           "covariance, %.3g with the noise alone)",
                           nl["realisations"].get<int>(), lvl.c_str(), det ? ", detected" : ", not detected",
                           finding.c_str(), p_total, pn));
        return v;
    }
    std::string finding;
    if (!det) finding = "the detection lines show no nonlinear distortion";
    else if (p_total >= 0.05) finding = "the detection lines show nonlinear distortion; residuals are consistent";
    else finding = "the detection lines show nonlinear distortion (" + lvl + " relative to the noise): the residuals may be at the distortion level; measure several realisations (msid frf --realisations R) to weigh with it";
    v["finding"] = finding;
    text.push_back("nonlinear distortion (one realisation, from the detection lines): " + finding);
    return v;
}

// Per line: q / (its expectation under the model), about 1; and the largest.
Json normalised_residuals(const std::vector<WeightedLine> &w, const ValidationStat &vs, const FrfData &f, int &worst,
                          double &worst_q)
{
    Json per = Json::array();
    const double g = (double)f.g();
    worst = -1;
    worst_q = -1;
    for (size_t l = 0; l < w.size(); ++l) {
        const double ex = (w[l].real ? 0.5 : 1.0) * g * (w[l].dof < 1e8 && w[l].dof > f.ny ? w[l].dof / (w[l].dof - f.ny) : 1.0);
        Json pl;
        pl["bin"] = f.lines[l].bin;
        pl["freq"] = f.lines[l].freq;
        pl["normalised_residual"] = vs.q[l] / ex;
        per.push_back(pl);
        if (vs.q[l] / ex > worst_q) {
            worst_q = vs.q[l] / ex;
            worst = (int)l;
        }
    }
    return per;
}

}  // namespace

void check_model_has_frf(const ModelFile &mf)
{
    if (mf.ss.B.cols() == 0)
        throw FitError("'" + mf.path + "' is a free-response model (no inputs, from msid fit --method multi): it has no "
                       "FRF; validate it on time records with --experiment FILE");
}

ValidateOutcome validate_frf(const ModelFile &mf, const FrfData &f, const Json &frf_doc, const ValidateRequest &rq)
{
    check_model_matches_frf(mf, f);
    ValidateOutcome out;
    std::string wname;
    const Weight wt = verdict_weight(mf, f, rq, wname);
    const std::vector<WeightedLine> w = weigh(f, mf.domain, wt);
    if (wt != Weight::None) check_weight_periods(w, f, true);
    const size_t stride = lpm_line_stride(f, rq.lpm_lines);
    // the model at every line: a solve of the model's order per line, the long part of a high order on many lines
    std::vector<MatC> Gm;
    Gm.reserve(w.size());
    for (const auto &l : w) {
        Gm.push_back(model_at(mf, l.x));
        msidutil::checkpoint(msidutil::Step::lines, 1, "the validation");
    }
    const ValidationStat vs = validation_stat(w, Gm, mf.n_params, stride, (double)f.ny, wt == Weight::None);
    if (!(vs.dof > 0))
        throw FitError("the model has as many parameters as the data: nothing to validate (dof " + std::to_string(vs.dof) + ")");
    const double V = vs.cost, pv = vs.p_value;
    if (!std::isfinite(V) || std::isnan(pv))   // never a verdict from a cost that is not a number
        throw FitError(fmt("the weighted cost of '%s' on '%s' is %g: the model's FRF is not finite at the lines",
                           mf.path.c_str(), f.path.c_str(), V));
    int worst = -1;
    double worst_q = -1;
    Json per = normalised_residuals(w, vs, f, worst, worst_q);
    // An FRF without any covariance (measured by another tool, msid import) has no noise scale: the
    // unit-weight cost is reported, but no p-value and no verdict (one would depend on the data's units).
    bool any_cov = false;
    for (const auto &l : f.lines) any_cov = any_cov || l.cov.size() > 0;
    const bool no_scale = wt == Weight::None && !any_cov && !rq.weight;
    out.consistent = pv >= 0.05 && !no_scale;
    out.has_verdict = !no_scale;
    if (no_scale)
        out.text.push_back(fmt("model %s on %s: unweighted cost %.6g (dof %.0f); the FRF has no covariance: no "
                               "p-value, no verdict", mf.path.c_str(), f.path.c_str(), V, vs.dof));
    else
        out.text.push_back(fmt("model %s on %s: weighted cost %.6g, expected %.6g (dof %.0f), p-value %.4g",
                               mf.path.c_str(), f.path.c_str(), V, vs.expected, vs.dof, pv));
    if (worst >= 0)
        out.text.push_back(fmt("largest normalised residual %.3g at bin %u (1 expected on average)", worst_q,
                               f.lines[(size_t)worst].bin));
    if (stride > 1)
        out.text.push_back(fmt("LPM file: the cost sums every %zu-th line (2W+1 bins apart: independent), %zu of %zu lines",
                               stride, (w.size() + stride - 1) / stride, w.size()));
    if (!no_scale)
        out.text.push_back(std::string("verdict: ") +
                           (out.consistent ? "consistent with the data at 5%" : "NOT consistent with the data at 5%"));
    if (wt == Weight::None && !no_scale) out.text.push_back("note: unweighted residuals: the p-value assumes unit noise");
    const Json nlv = distortion_verdict(frf_doc, f, mf, wname, pv, out.text);

    Json &r = out.report;
    r["format"] = "msid-validation/1";
    r["model"] = mf.path;
    r["frf"] = f.path;
    r["weight"] = wname;
    r["cost"] = V;
    r["expected"] = vs.expected;
    r["dof"] = vs.dof;
    if (no_scale) {
        r["expected"] = nullptr;
        r["p_value"] = nullptr;
        r["consistent_at_5pct"] = nullptr;
        r["note"] = "the FRF has no covariance: the unweighted cost has no noise scale, so no p-value and no verdict";
    } else {
        r["p_value"] = pv;
        r["consistent_at_5pct"] = out.consistent;
    }
    r["lines_in_statistic"] = stride > 1 ? fmt("every %zu-th line (2W+1, independent LPM lines)", stride) : std::string("all");
    r["line_stride"] = stride;
    if (!nlv.is_null()) r["nonlinear_distortion"] = nlv;
    r["lines"] = per;
    return out;
}

}  // namespace msidfitjob
