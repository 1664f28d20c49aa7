// msid frf --direct: the direct time-domain LS FRF (González et al. 2025,
// eqs. 19-23, Theorem 2) written as msid-frf/1 through the shared writer parts.
#include "pipeline.hpp"
#include "direct.hpp"
#include "model_io.hpp"

#include <cmath>

namespace msidcli {

FrfOutcome run_frf_direct(const FrfRequest &rq, const Design &D, const std::vector<Record> &recs)
{
    FrfOutcome out;
    const msid_design &d = D.d;
    if (recs.empty()) throw Error("no experiment files given (--experiment)");
    const uint32_t nu = recs[0].nu, ny = recs[0].ny, m = (uint32_t)recs.size();
    for (const auto &r : recs)
        if (r.nu != nu || r.ny != ny) throw Error("'" + r.path + "' has other columns than '" + recs[0].path + "'");
    if (d.n_inputs != nu) throw Error(fmt("the design has %u inputs but the files have %u input columns", d.n_inputs, nu));
    if (d.n_experiments != m)
        throw Error(fmt("the design has %u experiments but %u experiment files are given", d.n_experiments, m));
    std::vector<msidfit::DirectRecord> dr;
    for (const auto &r : recs) {
        if (r.n_rows <= rq.skip * (size_t)d.period)
            throw Error(fmt("'%s': %zu samples, nothing left after skipping %u periods", r.path.c_str(), r.n_rows, rq.skip));
        msidfit::DirectRecord x;
        x.rows = r.data() + (size_t)rq.skip * d.period * (nu + ny);
        x.n = r.n_rows - (size_t)rq.skip * d.period;
        x.stride = nu + ny;
        x.y_col = nu;
        dr.push_back(x);
    }
    msidfit::DirectResult res;
    try {
        res = msidfit::direct_frf(d, D.tw, dr, ny);
    } catch (const msidfit::FitError &e) {
        throw Error(e.what());
    }
    const size_t g = (size_t)nu * ny, L = d.n_lines;
    Json doc = frf_header(rq, nu, ny, m);
    uint64_t whole = 0;
    Json exps = Json::array();
    for (uint32_t e = 0; e < m; ++e) {
        Json je;
        je["source"] = recs[e].path;
        je["samples"] = recs[e].n_rows;
        je["periods_total"] = recs[e].n_rows / d.period;
        je["periods_skipped"] = rq.skip;
        je["periods_used"] = dr[e].n / d.period;
        je["periods_gap"] = 0;
        je["periods_nonfinite"] = 0;
        je["transient_flagged"] = Json::array();
        je["transient_dropped"] = Json::array();
        je["leftover_samples"] = 0;   // the direct method uses every sample
        whole += dr[e].n / d.period;
        exps.push_back(je);
    }
    doc["periods_used"] = whole;
    doc["periods_rejected"] = 0;
    doc["method"] = "direct";
    doc["whole_periods"] = res.whole_periods;
    doc["lines_correlated"] = !res.whole_periods;
    doc["dof_real"] = res.dof_real;
    doc["vec_convention"] = "vec stacks columns: G[i][j] has index i + n_outputs*j";
    msidfit::MatC sig = res.sigma.cast<std::complex<double>>();
    doc["noise_cov"] = msidfit::cmat_json_c(sig);
    doc["experiments"] = exps;
    Json lines = Json::array();
    for (size_t l = 0; l < L; ++l) {
        const auto &dl = res.lines[l];
        Json e = line_position(rq, l);
        e["G"] = msidfit::cmat_json_c(dl.G);
        e["cov"] = msidfit::cmat_json_c(dl.cov);
        e["dof"] = 0.5 * res.dof_real;
        e["cov_known_input"] = msidfit::cmat_json_c(dl.cov);
        e["dof_known_input"] = 0.5 * res.dof_real;
        e["pcov"] = msidfit::cmat_json_c(dl.pcov);
        msidfit::MatC nz = (res.sigma * (double)d.period).cast<std::complex<double>>();
        e["noise_cov"] = msidfit::cmat_json_c(nz);
        Json snr = Json::array();
        for (uint32_t i = 0; i < ny; ++i) {
            double s = 0, v = 0;
            for (uint32_t j = 0; j < nu; ++j) {
                s += std::norm(dl.G(i, j));
                v += dl.cov(i + ny * j, i + ny * j).real();
            }
            if (v > 0) snr.push_back(10 * std::log10(s / v)); else snr.push_back(nullptr);
        }
        e["snr"] = snr;
        e["cond"] = msid_design_cond(&d, (uint32_t)l);
        e["input_snr"] = nullptr;
        lines.push_back(e);
        (void)g;
    }
    doc["lines"] = lines;
    if (!res.whole_periods)
        out.notes.push_back("the records are not whole periods: the lines are correlated (Gonzalez Thm 2); each line's "
                            "cov and pcov are exact, the cross-line covariance is not written");
    out.doc = std::move(doc);
    out.dft_path = "direct";
    return out;
}

}  // namespace msidcli
