// `msid frf --realisations R`: the best linear approximation and the split of
// the FRF variance into noise (period to period) and nonlinear distortion
// (realisation to realisation), Pintelon & Schoukens 2012 §4.3.1 (robust
// method; equations in tools/fit/bla.hpp and docs/statistics.md).
#include "frf_job_detail.hpp"
#include "frf_bla.hpp"

#include "bla.hpp"
#include "stats.hpp"
#include "frf_data.hpp"

#include <cstdio>

#include <cmath>

namespace msidjob {

using msidfit::MatC;
using msidfit::cd;

// A matrix of a document this job built (shape from the document itself).
static MatC jcmat(const Json &v)
{
    const Json &re = v.at("re");
    return msidfrf::parse_cmat(v, re.size(), re.empty() ? 0 : re[0].size(), "FRF", "matrix");
}

static Json cjson(const MatC &M) { return msidfrf::cmat(M); }

static std::vector<double> vvec(const msidfit::VecR &v) { return std::vector<double>(v.data(), v.data() + v.size()); }

FrfOutcome run_frf_realisations(const FrfRequest &rq, const std::vector<Record> &recs, uint32_t R)
{
    if (R < 2) throw UsageError("--realisations must be at least 2 (one realisation: use --detect-lines for the distortion level)");
    if (recs.size() % R)
        throw UsageError("--realisations " + std::to_string(R) + ": the " + std::to_string(recs.size()) +
                         " experiments do not split into " + std::to_string(R) + " blocks of equal size");
    const size_t per = recs.size() / R;
    std::vector<FrfOutcome> outs;
    for (uint32_t r = 0; r < R; ++r) {
        std::vector<Record> block(recs.begin() + (long)(r * per), recs.begin() + (long)((r + 1) * per));
        try {
            outs.push_back(run_frf(rq, block));
        } catch (const msidutil::Error &e) {
            throw msidutil::Error("realisation " + std::to_string(r + 1) + " (experiments " + std::to_string(r * per + 1) +
                                      ".." + std::to_string((r + 1) * per) + "): " + e.what(),
                                  e.code, e.kind);
        }
    }
    FrfOutcome o = outs[0];
    Json &doc = o.doc;
    const size_t L = doc["lines"].size();
    doc["n_experiments"] = recs.size();
    uint64_t used = 0, rej = 0;
    Json exps = Json::array();
    MatC ncov = MatC::Zero(jcmat(doc["noise_cov"]).rows(), jcmat(doc["noise_cov"]).cols());
    for (uint32_t r = 0; r < R; ++r) {
        used += outs[r].doc["periods_used"].get<uint64_t>();
        rej += outs[r].doc["periods_rejected"].get<uint64_t>();
        for (auto e : outs[r].doc["experiments"]) {
            e["realisation"] = r;
            exps.push_back(e);
        }
        ncov += jcmat(outs[r].doc["noise_cov"]) / (double)R;
        if (r > 0)
            for (const auto &n : outs[r].notes) o.notes.push_back("realisation " + std::to_string(r + 1) + ": " + n);
    }
    doc["periods_used"] = used;
    doc["periods_rejected"] = rej;
    doc["experiments"] = exps;
    doc["noise_cov"] = cjson(ncov);
    std::vector<msidfit::BlaLine> bl;
    for (size_t l = 0; l < L; ++l) {
        std::vector<MatC> G, C;
        std::vector<double> dof;
        MatC cki;
        double dki = 0;
        for (uint32_t r = 0; r < R; ++r) {
            const Json &e = outs[r].doc["lines"][l];
            G.push_back(jcmat(e["G"]));
            C.push_back(jcmat(e["cov"]));
            dof.push_back(e["dof"].get<double>());
            const MatC k = jcmat(e["cov_known_input"]) / ((double)R * R);
            cki = r ? MatC(cki + k) : k;
            dki += e.contains("dof_known_input") ? e["dof_known_input"].get<double>() : dof.back();
        }
        const msidfit::BlaLine b = msidfit::bla_line(G, C, dof);
        Json &e = doc["lines"][l];
        e["G"] = cjson(b.G);
        e["cov"] = cjson(b.cov);
        e["dof"] = b.dof;
        e["cov_noise"] = cjson(b.cov_noise);
        e["dof_noise"] = b.dof_noise;
        e["var_nl"] = vvec(b.var_nl);
        e["var_s"] = vvec(b.var_s);
        Json pv = Json::array();
        for (Eigen::Index i = 0; i < b.p_value.size(); ++i)
            pv.push_back(std::isfinite(b.p_value(i)) ? Json(b.p_value(i)) : Json(nullptr));
        e["nl_p_value"] = pv;
        e["cov_known_input"] = cjson(cki);   // noise only, pooled (no distortion in it)
        e["dof_known_input"] = dki;
        if (e.contains("noise_cov")) {
            MatC nc = MatC::Zero(ncov.rows(), ncov.cols());
            for (uint32_t r = 0; r < R; ++r) nc += jcmat(outs[r].doc["lines"][l]["noise_cov"]) / (double)R;
            e["noise_cov"] = cjson(nc);
        }
        bl.push_back(b);
    }
    const msidfit::BlaSummary s = msidfit::bla_summary(bl);
    Json nl;
    nl["method"] = "robust (Pintelon & Schoukens 2012 §4.3.1): BLA = mean over realisations; cov = total covariance "
                   "from the realisation-to-realisation spread; cov_noise from the periods; var_nl = diag(cov - cov_noise)";
    nl["realisations"] = R;
    nl["experiments_per_realisation"] = per;
    nl["entries_tested"] = s.entries;
    nl["entries_significant_1pct"] = s.significant;
    nl["p_value"] = s.p_value;
    nl["distortion_detected"] = s.detected;
    nl["nl_to_noise_db"] = std::isfinite(s.nl_to_noise_db) ? Json(s.nl_to_noise_db) : Json(nullptr);
    doc["nonlinear_distortion"] = nl;
    if (s.detected)
        o.notes.push_back(fmt("nonlinear distortion detected (%d of %d line entries significant at 1%%, p = %.3g); its "
                              "variance is %.1f dB relative to the noise; cov holds noise + distortion",
                              s.significant, s.entries, s.p_value, s.nl_to_noise_db));
    return o;
}

}  // namespace msidjob

namespace msidjob {

Json detection_distortion(const Json &doc)
{
    if (!doc.contains("detection_lines") || doc["detection_lines"].empty()) return nullptr;
    const uint32_t m = doc["n_experiments"].get<uint32_t>(), ny = doc["n_outputs"].get<uint32_t>();
    std::vector<double> K;
    for (const auto &e : doc["experiments"]) K.push_back((double)e["periods_used"].get<uint64_t>());
    double qsum = 0, dof = 0;
    for (double k : K) dof += k - 1.0;
    std::vector<double> pv;
    for (const auto &d : doc["detection_lines"]) {
        const MatC Y = jcmat(d["Y_mean"]);   // m x ny
        for (uint32_t i = 0; i < ny; ++i) {
            const double v = d["noise_var"][i].get<double>();
            if (!(v > 0)) continue;
            double s = 0;
            for (uint32_t e = 0; e < m; ++e) s += K[e] * std::norm(Y(e, i));
            qsum += s / (m * v);   // F(2m, 2 dof) without periodic content: mean dof/(dof-1)
            pv.push_back(d["p_value"][i].is_number() ? d["p_value"][i].get<double>() : NAN);
        }
    }
    int n = 0, sig = 0;
    const double p = msidfit::fisher_combined(pv, &n, &sig);
    if (!n) return nullptr;
    const double excess = qsum / (double)pv.size() - (dof > 1 ? dof / (dof - 1.0) : 1.0);
    Json o;
    o["method"] = "detection lines (one realisation): output power at the non-excited lines over its noise level; "
                  "assumes the nonlinear contributions there stand for those at the excited lines (odd/even "
                  "detection lines of a random-phase multisine); not added to cov";
    o["realisations"] = 1;
    o["entries_tested"] = n;
    o["entries_significant_1pct"] = sig;
    o["p_value"] = p;   // Fisher's combination of the detection-line p-values
    o["distortion_detected"] = p < msidfit::BLA_DETECT_ALPHA;
    o["nl_to_noise_db"] = excess > 0 ? Json(10.0 * std::log10(excess)) : Json(nullptr);
    return o;
}

}  // namespace msidjob
