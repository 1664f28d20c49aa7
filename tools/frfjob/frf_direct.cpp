// msid frf --direct: the direct time-domain LS FRF (González et al. 2025,
// eqs. 19-23, Theorem 2; tools/est/direct.cpp) written as msid-frf/1 by tools/frffile.
#include "frf_job_detail.hpp"
#include "msid_frf_job.hpp"
#include "direct.hpp"
#include "frf_file.hpp"

#include <cmath>

namespace msidjob {

FrfOutcome run_frf_direct(const FrfRequest &rq, const Design &D, const std::vector<Record> &recs)
{
    FrfOutcome out;
    const msid_design &d = D.d;
    if (recs.empty()) throw Error("no experiment files given (" MSID_OPT("experiment") ")");
    const uint32_t nu = recs[0].nu, ny = recs[0].ny, m = (uint32_t)recs.size();
    for (const auto &r : recs)
        if (r.nu != nu || r.ny != ny) throw Error("'" + r.path + "' has other columns than '" + recs[0].path + "'");
    if (d.n_inputs != nu) throw Error(fmt("the design has %u inputs but the files have %u input columns", d.n_inputs, nu));
    if (d.n_experiments != m)
        throw Error(fmt("the design has %u experiments but %u experiment files are given", d.n_experiments, m));
    std::vector<msidest::DirectRecord> dr;
    for (const auto &r : recs) {
        if (r.n_rows <= rq.skip * (size_t)d.period)
            throw Error(fmt("'%s': %zu samples, nothing left after skipping %u periods", r.path.c_str(), r.n_rows, rq.skip));
        msidest::DirectRecord x;
        x.rows = r.data() + (size_t)rq.skip * d.period * (nu + ny);
        x.n = r.n_rows - (size_t)rq.skip * d.period;
        x.stride = nu + ny;
        x.y_col = nu;
        dr.push_back(x);
    }
    msidest::DirectResult res;
    try {
        res = msidest::direct_frf(d, D.tw, dr, ny);
    } catch (const msidest::EstError &e) {
        throw Error(e.what());
    }
    const size_t L = d.n_lines;
    Json doc = frf_header(rq, nu, ny, m);
    uint64_t whole = 0;
    Json exps = Json::array();
    for (uint32_t e = 0; e < m; ++e) {
        msidfrf::Experiment x;
        x.source = recs[e].path;
        x.samples = recs[e].n_rows;
        x.periods_total = recs[e].n_rows / d.period;
        x.periods_skipped = rq.skip;
        x.periods_used = dr[e].n / d.period;
        x.leftover_samples = 0;   // the direct method uses every sample
        whole += dr[e].n / d.period;
        exps.push_back(msidfrf::experiment(x));
    }
    doc["periods_used"] = whole;
    doc["periods_rejected"] = 0;
    doc["method"] = "direct";
    doc["whole_periods"] = res.whole_periods;
    doc["lines_correlated"] = !res.whole_periods;
    doc["dof_real"] = res.dof_real;
    doc["vec_convention"] = msidfrf::VEC_CONVENTION;
    doc["noise_cov"] = msidfrf::cmat(res.sigma.cast<std::complex<double>>());
    doc["experiments"] = exps;
    const msidfrf::MatC nz = (res.sigma * (double)d.period).cast<std::complex<double>>();
    Json lines = Json::array();
    for (size_t l = 0; l < L; ++l) {
        const auto &dl = res.lines[l];
        msidfrf::LineStats s;
        s.G = dl.G;
        s.cov = dl.cov;
        s.dof = 0.5 * res.dof_real;
        s.pcov = dl.pcov;
        s.noise = nz;
        for (uint32_t i = 0; i < ny; ++i) {
            double sg = 0, v = 0;
            for (uint32_t j = 0; j < nu; ++j) {
                sg += std::norm(dl.G(i, j));
                v += dl.cov(i + ny * j, i + ny * j).real();
            }
            s.snr.push_back(v > 0 ? 10 * std::log10(sg / v) : NAN);
        }
        s.cond = msid_design_cond(&d, (uint32_t)l);
        s.input_snr = NAN;
        lines.push_back(msidfrf::line(line_position(rq, l), s));
    }
    doc["lines"] = lines;
    if (!res.whole_periods)
        out.notes.push_back("the records are not whole periods: the lines are correlated (Gonzalez Thm 2); each line's "
                            "cov and pcov are exact, the cross-line covariance is not written");
    out.doc = std::move(doc);
    out.dft_path = "direct";
    return out;
}

}  // namespace msidjob
