// `msid modes` of a model of --method multi: its shared poles with standard deviations by the delta
// method from the covariance of the characteristic coefficients (no residues: the records'
// amplitudes are their initial conditions).
#include "fit_job_detail.hpp"

#include "multi.hpp"

#include <cmath>

namespace msidfitjob {

namespace {

Json num_or_null(double x) { return std::isfinite(x) ? Json(x) : Json(nullptr); }

// The covariance of a multi model's characteristic coefficients, when the file holds it (n x n).
MatR alpha_cov(const Json &j, int n)
{
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
    return cov;
}

}  // namespace

ModesOutcome modes_of_multi(const Json &j, const std::string &path)
{
    const MultiModelDoc m = multi_model_doc(j, path);
    const int n = (int)m.alpha.size();
    const MatR cov = alpha_cov(j, n);
    const std::vector<MultiMode> md = multi_modes(m.alpha, cov, m.h);
    const bool hz = m.h > 0;
    ModesOutcome out;
    out.text = fmt("%s: %d pole(s) from msid fit --method multi (%s), standard deviations %s\n", path.c_str(), n,
                   m.nu ? "input-output" : "free responses",
                   cov.size() ? "by the delta method from the pole covariance" : "not available");
    out.text += fmt("  %-10s %-24s %-24s\n", "", hz ? "fn (Hz)" : "fn (cycles/sample)", "damping ratio");
    for (const auto &x : md)
        out.text += fmt("  %-10s %-24s %-24s\n", x.real ? "real pole" : "mode", fmt("%.6g +- %.2g", x.fn, x.sd_fn).c_str(),
                        fmt("%.5g +- %.2g", x.zeta, x.sd_zeta).c_str());
    Json &o = out.report;
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
        e["sd_fn"] = num_or_null(x.sd_fn);
        e["sd_wn"] = num_or_null(x.sd_wn);
        e["sd_zeta"] = num_or_null(x.sd_zeta);
        arr.push_back(e);
    }
    o["modes"] = arr;
    return out;
}

}  // namespace msidfitjob
