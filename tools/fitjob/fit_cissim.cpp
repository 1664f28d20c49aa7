// --method cissim: discrete-cISSIM from periodic time records (You et al. 2023), refined by weighted
// output error, with the noise covariances of section 4.3. docs/fitting.md, section "cissim".
#include "fit_job_detail.hpp"

#include "cissim.hpp"
#include "periodicity.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <exception>
#include <system_error>
#include <thread>

namespace msidfitjob {

namespace {

// The records' shapes: the same channels, enough whole periods, a periodic input.
void check_records(const std::vector<Record> &recs, const CissimRequest &rq, FitOutcome &out, const Report &report)
{
    const uint32_t P = rq.period, skip = rq.skip_periods;
    const uint32_t nu = recs[0].nu, ny = recs[0].ny;
    for (const auto &r : recs) {
        if (r.nu != nu || r.ny != ny)
            throw Error(fmt("'%s' has %u input(s) and %u output(s), '%s' %u and %u: the experiments must share the channels",
                            r.path.c_str(), r.nu, r.ny, recs[0].path.c_str(), nu, ny));
        const size_t K = r.n_rows / P;
        if (K < (size_t)skip + 2)
            throw Error(fmt("'%s' holds %zu whole period(s) of %u samples: cissim needs at least %u (" MSID_OPT("skip_periods") " %u, "
                            "plus 2 to check that the input is periodic, Assumption 4)",
                            r.path.c_str(), K, P, skip + 2, skip));
        const double eta = msidjob::nonperiodic_fraction(r, P, skip, K - skip);
        if (!(eta <= msidjob::NONPERIODIC_FRACTION))
            throw Error(fmt("'%s': the input is not periodic with period %u: %.0f%% of its power changes from period to "
                            "period (You et al. Assumption 4 needs u(k + P) = u(k)); give the right " MSID_OPT("period") " "
                            "(`msid frf --period auto` finds it) or use `msid frf --method lpm`",
                            r.path.c_str(), P, 100.0 * eta));
        if (r.n_rows % P)
            add_note(out, report, fmt("note: '%s': the last %zu sample(s) do not fill a period and are not used",
                                      r.path.c_str(), r.n_rows % P));
    }
}

// The phasors of the full set restricted to the excited lines (the weighted output error uses those).
std::vector<IspResult> at_lines(const std::vector<IspResult> &isp, const std::vector<uint32_t> &bins,
                                const std::vector<uint32_t> &lines, uint32_t nu, uint32_t ny)
{
    std::vector<IspResult> out = isp;
    std::vector<Eigen::Index> pick;
    for (uint32_t b : lines) pick.push_back((Eigen::Index)(std::find(bins.begin(), bins.end(), b) - bins.begin()));
    for (auto &r : out) {
        IspResult s2 = r;
        s2.bins = lines;
        s2.U.resize(nu, (Eigen::Index)pick.size());
        s2.Y.resize(ny, (Eigen::Index)pick.size());
        s2.line_cov.clear();
        for (size_t l = 0; l < pick.size(); ++l) {
            s2.U.col((Eigen::Index)l) = r.U.col(pick[l]);
            s2.Y.col((Eigen::Index)l) = r.Y.col(pick[l]);
            if (!r.line_cov.empty()) s2.line_cov.push_back(r.line_cov[(size_t)pick[l]]);
        }
        r = s2;
    }
    return out;
}

Json settings_json(const CissimRequest &rq, const CissimResult &res, const std::vector<IspResult> &isp,
                   const CissimOptions &o)
{
    Json st;
    st["weight"] = "none";
    st["period"] = rq.period;
    st["lines"] = msidjob::format_bins(rq.lines);
    st["frequency_set"] = rq.reduced ? "reduced" : "full";
    st["isp"] = isp[0].used_fft ? "fft (Alg. 3)" : "direct (Alg. 1)";
    st["block_rows"] = res.block_rows;
    st["order_estimated"] = res.order_estimated;
    st["skip_periods"] = rq.skip_periods;
    st["periods_used"] = Json::array();
    for (const auto &r : isp) st["periods_used"].push_back(r.periods);
    st["estimate_D"] = o.estimate_D;
    st["weighted"] = o.weighted;
    st["refine"] = rq.refine;
    return st;
}

// The number of correlation lags M of the noise covariance at order n (--lags, or the default of
// section 4.3.3), checked against Assumption 8.
int noise_lags(const Record &r0, const CissimRequest &rq, int n)
{
    const uint32_t P = rq.period, skip = rq.skip_periods, ny = r0.ny;
    const uint64_t N = (uint64_t)(r0.n_rows / P - skip) * P;
    const int M = rq.lags ? (int)*rq.lags
                          : std::max<int>((int)std::ceil((double)n * n / ((double)ny * ny)) + 1,
                                          std::min(50, (int)std::lround(std::cbrt((double)N))));
    const int Mmin = (int)std::ceil((double)n * n / ((double)ny * ny)) + 1;
    // the default lags follow from the order: a message about them names the order, not an option not given
    const std::string lags = rq.lags ? fmt("--lags %d", M) : fmt("order %d needs %d noise correlation lags, which", n, M);
    if (M < Mmin) throw UsageError(fmt("%s is below ceil(n^2 / ny^2) + 1 = %d (Assumption 8)", lags.c_str(), Mmin));
    if ((uint64_t)M >= N / 2)
        throw UsageError(fmt("%s needs M << N = %llu samples (Assumption 8)%s", lags.c_str(), (unsigned long long)N,
                             rq.lags ? "" : ": a lower order, more periods, or " MSID_OPT("no_covariance")));
    return M;
}

// The residual correlations of the first experiment (Alg. 6) at M lags: the noise covariance and the
// white-noise cost use them. They need the record alone, not the model: with the order given they
// are computed on a second thread while the model is fitted (the same numbers as in line).
class NoiseCorrelations {
public:
    NoiseCorrelations(const Record &r0, const CissimRequest &rq) : r0_(r0), rq_(rq) {}
    ~NoiseCorrelations()
    {
        if (th_.joinable()) th_.join();
    }
    void start(int M)
    {
        M_ = M;
        try {
            th_ = std::thread([this, M] {
                try {
                    c_ = compute(M);
                } catch (...) {
                    err_ = std::current_exception();
                }
            });
        } catch (const std::system_error &) {   // no thread to be had: in line, at get()
        }
    }
    Correlations get(int M)
    {
        if (!th_.joinable()) return compute(M);
        th_.join();
        if (M != M_) return compute(M);
        if (err_) std::rethrow_exception(err_);
        return std::move(c_);
    }

private:
    Correlations compute(int M) const
    {
        return cissim_correlations(r0_.data(), r0_.n_rows, r0_.nu, r0_.ny, rq_.period, rq_.skip_periods, M);
    }
    const Record &r0_;
    const CissimRequest &rq_;
    std::thread th_;
    int M_ = 0;
    Correlations c_;
    std::exception_ptr err_;
};

// The noise covariances (section 4.3) on the full set, from the first experiment's residuals.
Json noise_cov_json(const Record &r0, const Correlations &c, const SSModel &ss, FitOutcome &out, const Report &report)
{
    const NoiseCov nc = cissim_noise_cov(ss, c);
    Json nj;
    nj["Sigma_ww"] = rmat_json(nc.Sigma_ww);
    nj["Sigma_vv"] = rmat_json(nc.Sigma_vv);
    nj["Sigma_tt"] = rmat_json(nc.Sigma_tt);
    nj["Xi_zz"] = rmat_json(nc.Xi_zz);
    Json xr = Json::array();
    for (const auto &X : c.Xi_rr) xr.push_back(rmat_json(X));
    nj["Xi_rr"] = xr;
    nj["lags"] = nc.lags;
    nj["samples"] = c.n;
    nj["source"] = r0.path;
    nj["strongly_detectable"] = nc.detectable;
    nj["nominal"] = !nc.detectable;
    nj["note"] = nc.note.empty() ? Json(nullptr) : Json(nc.note);
    nj["solver"] = Json{{"method", nc.solver == "ADMM" ? "ADMM on (35) with the PSD constraints of (36)"
                                                        : "interior point (log barrier, Newton) on (35) with the PSD "
                                                          "constraints of (36)"},
                        {"iterations", nc.iterations},
                        {"duality_gap", nc.duality_gap >= 0 ? Json(nc.duality_gap) : Json(nullptr)},
                        {"constraint_residual", nc.primal_residual},
                        {"relative_fit_residual", nc.fit_residual}};
    nj["basis"] = "the states of A, B, C above (Sigma_ww depends on the similarity transform)";
    if (!nc.detectable) add_note(out, report, "note: " + nc.note);
    return nj;
}

// The model FRF at the excited lines, with the refinement's covariance when it has one.
Json frf_json(const CissimRequest &rq, const SSModel &ss, const CissimMlResult &ml, bool refined)
{
    const uint32_t P = rq.period;
    Json fr = Json::array();
    for (size_t l = 0; l < rq.lines.size(); ++l) {
        const uint32_t b = rq.lines[l];
        const MatC G = cissim_eval(ss, std::polar(1.0, 2.0 * M_PI * b / P));
        MatC Cc;
        if (refined && std::isfinite(ml.cov_factor)) {
            // E[dg dg^H] = C_aa + C_bb + j (C_ba - C_ab) from the real [Re vec G; Im vec G] covariance
            const MatR &Cr = ml.Gcov[l];
            const Eigen::Index g = Cr.rows() / 2;
            Cc.resize(g, g);
            Cc.real() = Cr.topLeftCorner(g, g) + Cr.bottomRightCorner(g, g);
            Cc.imag() = Cr.bottomLeftCorner(g, g) - Cr.topRightCorner(g, g);
        }
        fr.push_back(model_frf_line(b, (double)b / P, 2.0 * M_PI * b / P, G, Cc.size() ? &Cc : nullptr));
    }
    return fr;
}

// A white-noise cost of the phasor residuals at the excited lines: var(P_r) = 4 Xi_rr^0 / (K T) per
// complex phasor (white approximation); zero without the noise covariance.
Json cost_json(const CissimRequest &rq, const std::vector<IspResult> &isp, const std::vector<uint32_t> &bins,
               const SSModel &ss, int nparams, const Correlations *corr)
{
    const uint32_t P = rq.period;
    const Eigen::Index ny = ss.C.rows();
    const std::vector<uint32_t> &lines = rq.lines;
    Json cost;
    double V = 0, neq = 0;
    MatR Xi0;
    if (corr) Xi0 = corr->Xi_rr[0] * ((double)corr->periods / (double)(corr->periods - 1));
    if (Xi0.size() && Eigen::FullPivLU<MatR>(Xi0).rank() == ny) {
        const MatR Xinv = Xi0.inverse();
        for (const auto &r : isp) {
            const double scale = (double)r.periods * P / 4.0;
            for (size_t l = 0; l < bins.size(); ++l) {
                if (std::find(lines.begin(), lines.end(), bins[l]) == lines.end()) continue;
                const cd z = std::polar(1.0, 2.0 * M_PI * bins[l] / P);
                const VecC e = r.Y.col((Eigen::Index)l) - cissim_eval(ss, z) * r.U.col((Eigen::Index)l);
                const bool dc = bins[l] == 0;
                V += (dc ? 0.5 : 1.0) * scale * (e.adjoint() * Xinv.cast<cd>() * e)(0, 0).real();
                neq += (dc ? 1.0 : 2.0) * ny;
            }
        }
        cost["value"] = V;
        cost["expected"] = 0.5 * (neq - nparams);
        cost["dof"] = neq - nparams;
    } else {
        cost["value"] = 0.0;
        cost["expected"] = 0.0;
        cost["dof"] = 0.0;
    }
    cost["p_value"] = nullptr;
    cost["weight"] = "none";
    cost["note"] = "phasor residuals at --lines weighted by the white-noise phasor covariance 4 Xi_rr^0 / (K T); "
                   "no p-value (the input noise and coloured output noise are not in this weight)";
    return cost;
}

}  // namespace

void check_cissim(const CissimRequest &rq)
{
    const uint32_t P = rq.period;
    if (P < 4) throw UsageError(MSID_OPT("period") " must be at least 4 samples");
    if (rq.lines.empty()) throw UsageError(MSID_OPT("lines") " is empty");
    for (uint32_t b : rq.lines)
        if (2 * (uint64_t)b >= P) throw UsageError(fmt(MSID_OPT("lines") ": bin %u is not below P/2 = %u", b, P / 2));
    if (rq.order && *rq.order == 0) throw UsageError(MSID_OPT("order") " must be positive");
    if (rq.max_order && *rq.max_order == 0) throw UsageError(MSID_OPT("max_order") " must be positive");
    // the order sizes matrices of order x order and more: a state-space model of more states than this
    // is beyond memory (and would wrap to a negative order)
    for (auto [v, name] : {std::make_pair(rq.order, "--order"), std::make_pair(rq.max_order, "--max-order"),
                           std::make_pair(rq.block_rows, "--block-rows"), std::make_pair(rq.lags, "--lags")})
        if (v && *v > MAX_STATES) throw UsageError(fmt("%s %u is too large (at most %u)", name, *v, MAX_STATES));
    if (rq.isp != "auto" && rq.isp != "direct" && rq.isp != "fft")
        throw UsageError(MSID_OPT("isp") " must be auto, direct or fft (got '" + rq.isp + "')");
    if (rq.refine != "ml" && rq.refine != "none") throw UsageError(MSID_OPT("refine") " must be ml or none (got '" + rq.refine + "')");
}

FitOutcome fit_cissim(const std::vector<Record> &recs, const CissimRequest &rq, const Report &report)
{
    check_cissim(rq);
    if (recs.empty()) throw UsageError("missing " MSID_OPT("experiment") " <file.csv>");
    FitOutcome out;
    check_records(recs, rq, out, report);
    CissimOptions o;
    if (rq.order) o.order = (int)*rq.order;
    if (rq.max_order) o.max_order = (int)*rq.max_order;
    if (rq.block_rows) o.block_rows = (int)*rq.block_rows;
    o.estimate_D = !rq.no_d;
    o.weighted = !rq.unweighted;
    o.stable = !rq.allow_unstable;
    const IspMethod method = rq.isp == "direct" ? IspMethod::Direct : rq.isp == "fft" ? IspMethod::Fft : IspMethod::Auto;
    const bool refine = rq.refine == "ml";
    const uint32_t P = rq.period, nu = recs[0].nu, ny = recs[0].ny;
    std::vector<uint32_t> bins = rq.lines;
    if (!rq.reduced) {
        bins.clear();
        for (uint32_t b = 0; 2 * b < P; ++b) bins.push_back(b);
    }
    NoiseCorrelations nc_corr(recs[0], rq);
    if (!rq.no_covariance && rq.order) nc_corr.start(noise_lags(recs[0], rq, (int)*rq.order));
    try {
        std::vector<IspResult> isp;
        for (const auto &r : recs)
            isp.push_back(cissim_isp(r.data(), r.n_rows, nu, ny, P, bins, rq.skip_periods, method, refine, &rq.lines));
        const CissimResult res = cissim_fit(isp, o);
        CissimMlResult ml;
        if (refine) ml = cissim_refine(res.model, at_lines(isp, bins, rq.lines, nu, ny));
        const SSModel &ss = refine ? ml.model : res.model;
        const int n = res.order;
        Json ex = Json::array();
        for (const auto &r : recs) ex.push_back(r.path);
        Json &doc = out.model;
        doc = model_head(recs[0].path, Domain::DT, 0.0, "cissim", ex);
        model_put_ss(doc, ss, n, nu, ny, settings_json(rq, res, isp, o));
        doc["stability"] = model_stability(ss, o.stable, Eigen::EigenSolver<MatR>(ss.A, false).eigenvalues());
        const int nparams = n * (int)(nu + ny) + (o.estimate_D ? (int)(nu * ny) : 0);
        doc["n_params"] = nparams;
        Json cj;
        cj["singular_values"] = res.sv;
        cj["lines_per_experiment"] = res.lines;
        cj["real_columns"] = res.real_columns;
        cj["reflected_poles"] = res.reflected;
        if (refine && !std::isfinite(ml.cov_factor))
            add_note(out, report, fmt("note: %llu period(s) after the skipped ones are too few for an uncertainty (the "
                                      "per-line weights need more than %u + 2): frf[].cov is null",
                                      (unsigned long long)isp[0].periods, ny));
        if (refine)
            cj["refinement"] = Json{{"method", "weighted output error (ML) on the ISP phasors at --lines, Levenberg-Marquardt"},
                                    {"cost_start", ml.cost_start},
                                    {"cost", ml.cost},
                                    {"expected", 0.5 * ml.dof},
                                    {"dof", ml.dof},
                                    {"iterations", ml.iterations},
                                    {"converged", ml.converged},
                                    {"cov_factor", std::isfinite(ml.cov_factor) ? Json(ml.cov_factor) : Json(nullptr)},
                                    {"cov_rank", ml.cov_rank},
                                    {"cov_note", "FRF covariance from the Fisher information of the weighted output error "
                                                 "(weights: per-line sample covariance over the periods), sample-ML factor applied"}};
        Correlations corr;
        if (!rq.no_covariance) {
            corr = nc_corr.get(noise_lags(recs[0], rq, n));
            doc["noise_covariance"] = noise_cov_json(recs[0], corr, ss, out, report);
        }
        const Json fr = frf_json(rq, ss, ml, refine);
        doc["cost"] = cost_json(rq, isp, bins, ss, nparams, rq.no_covariance ? nullptr : &corr);
        doc["cissim"] = cj;
        doc["frf"] = fr;
        model_put_modes(doc, &out.before);
        out.tail = fmt(": cissim fit (%s set, %zu line(s), ISP by %s), order %d%s, block rows %d%s%s\n",
                       rq.reduced ? "reduced" : "full", bins.size(), isp[0].used_fft ? "FFT" : "direct products", n,
                       res.order_estimated ? " (estimated)" : "", res.block_rows,
                       refine ? fmt(", ML refined (cost %.4g -> %.4g, expected %.4g)", ml.cost_start, ml.cost, 0.5 * ml.dof).c_str()
                              : "",
                       ss_stable(ss) ? "" : ", UNSTABLE");
    } catch (const FitError &e) {
        throw Error(e.what());
    }
    return out;
}

}  // namespace msidfitjob
