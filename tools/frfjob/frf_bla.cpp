// `msid frf --realisations R`: the best linear approximation and the split of
// the FRF variance into noise (period to period) and nonlinear distortion
// (realisation to realisation), Pintelon & Schoukens 2012 §4.3.1 (robust
// method; equations in tools/frfstat/bla.hpp and docs/statistics.md). When some realisation has one
// usable period (the nonlinear-benchmark layout: R realisations of one period each) only the BLA
// and its total covariance exist (total_only): the split needs the periods' noise.
#include "frf_job_detail.hpp"
#include "frf_bla.hpp"
#include "periodicity.hpp"

#include "bla.hpp"     // the robust BLA and its tests (tools/frfstat)
#include "frf_file.hpp"

#include <cstdio>

#include <cmath>

namespace msidjob {

using msidfrf::MatC;
using msidfrf::cd;

// A matrix of a document this job built (shape from the document itself).
static MatC jcmat(const Json &v)
{
    const Json &re = v.at("re");
    return msidfrf::parse_cmat(v, re.size(), re.empty() ? 0 : re[0].size(), "FRF", "matrix");
}

static Json cjson(const MatC &M) { return msidfrf::cmat(M); }

static std::vector<double> vvec(const msidstat::VecR &v) { return std::vector<double>(v.data(), v.data() + v.size()); }

// f() for realisation r (0-based) of `per` experiments, its error naming the realisation.
template <class F> static auto in_realisation(uint32_t r, size_t per, F f) -> decltype(f())
{
    try {
        return f();
    } catch (const msidutil::Error &e) {
        throw msidutil::Error("realisation " + std::to_string(r + 1) + " (experiments " + std::to_string(r * per + 1) +
                                  ".." + std::to_string((r + 1) * per) + "): " + e.text(),
                              e.code, e.kind);
    }
}

// One realisation's FRF with what the total covariance of the BLA needs: G per line, the input
// matrix's condition number, and the experiments' accounting.
struct RealisationFrf {
    std::vector<MatC> G;          // per line, ny x nu
    std::vector<double> cond;     // per line
    Json experiments = Json::array();
    uint64_t used = 0, rejected = 0;
    std::vector<std::string> notes;
    std::string dft_path;         // "stream" or "fft"
};

// Usable whole periods of a record after --skip-periods (before the core rejects any).
static uint64_t usable_periods(const Record &r, const FrfRequest &rq)
{
    const uint64_t K = r.n_rows / rq.period;
    return K > rq.skip ? K - rq.skip : 0;
}

// A realisation whose experiments all have >= 2 periods: the periodic job's FRF (its transient and
// drift tests and notes as always); its covariances are not used.
static RealisationFrf from_periodic(const FrfRequest &rq, const std::vector<Record> &block)
{
    FrfOutcome o = run_frf(rq, block);
    o.tree();
    RealisationFrf f;
    for (const auto &e : o.doc["lines"]) {
        f.G.push_back(jcmat(e["G"]));
        f.cond.push_back(e.contains("cond") ? e["cond"].get<double>() : NAN);
    }
    f.experiments = o.doc["experiments"];
    f.used = o.doc["periods_used"].get<uint64_t>();
    f.rejected = o.doc["periods_rejected"].get<uint64_t>();
    f.notes = std::move(o.notes);
    f.dft_path = o.dft_path;
    return f;
}

// A realisation with one usable period in some experiment: per line G = Ybar Ubar^+ (the LS FRF
// of the period means, Ubar nu x m, Ybar ny x m; González et al. 2025 eq. 37 without its
// covariance), the input matrix's condition number and the core's excitation floor (the weakest
// input direction's power above 1e-20 of the strongest line's; the input-noise part of that test
// needs two periods). The transient test needs three periods and is off.
static RealisationFrf from_means(const FrfRequest &rq0, const std::vector<Record> &block)
{
    FrfRequest rq = rq0;
    rq.transient = MSID_TRANSIENT_OFF;
    rq.detect.clear();
    validate_lines(rq);
    check_records(rq, block);
    const uint32_t nu = block[0].nu, ny = block[0].ny, m = (uint32_t)block.size(), P = rq.period;
    RealisationFrf f;
    uint32_t maxK = 0;
    for (const auto &r : block) {
        maxK = std::max(maxK, (uint32_t)record_periods(r, rq, 1));
        if (r.n_rows % P)
            f.notes.push_back(fmt("'%s': %llu samples after the last whole period are not used", r.path.c_str(),
                                  (unsigned long long)(r.n_rows % P)));
    }
    FrfJob job(rq, nu, ny, m, maxK, maxK, 1);
    measure_records(job, rq, block);
    const msid_dft_path path = rq.path == MSID_DFT_AUTO
                                   ? msid_linedft_choose(P, (uint32_t)rq.bins.size(), nu + ny, 1)
                                   : rq.path;   // as FrfJob chose it
    f.dft_path = path == MSID_DFT_FFT ? "fft" : "stream";
    std::vector<const msid_pstats *> ps(m);
    std::vector<std::string> names;
    for (uint32_t e = 0; e < m; ++e) {
        const Record &r = block[e];
        names.push_back(r.path);
        ps[e] = msid_meas_stats(job.meas(0), e);
        const msid_pstats_counts c = msid_pstats_get_counts(ps[e]);
        if (c.used < 1)
            throw Error(fmt("'%s': no usable period after skipping %u (%u with samples missing or out of order, %u with "
                            "NaN/Inf samples)",
                            r.path.c_str(), c.skipped, c.gap, c.nonfinite));
        msidfrf::Experiment x;
        x.source = r.path;
        x.samples = r.n_rows;
        x.periods_total = r.n_rows / P;
        x.periods_skipped = c.skipped;
        x.periods_used = c.used;
        x.periods_gap = c.gap;
        x.periods_nonfinite = c.nonfinite;
        x.transient_tested = false;
        x.leftover_samples = r.n_rows % P;
        f.experiments.push_back(msidfrf::experiment(x));
        f.used += c.used;
        f.rejected += c.gap + c.nonfinite;
    }
    check_periodic_lines(ps.data(), m, nu, P, rq.bins, names);   // experiments with >= 2 periods
    const size_t L = rq.bins.size();
    std::vector<MatC> U(L, MatC(nu, m)), Y(L, MatC(ny, m));
    double uscale = 0;
    for (size_t l = 0; l < L; ++l) {
        for (uint32_t e = 0; e < m; ++e) {
            const msid_cplx *z = msid_pstats_mean(ps[e], (uint32_t)l);
            for (uint32_t j = 0; j < nu; ++j) U[l](j, e) = cd(z[j].re, z[j].im);
            for (uint32_t i = 0; i < ny; ++i) Y[l](i, e) = cd(z[nu + i].re, z[nu + i].im);
        }
        uscale = std::max(uscale, U[l].squaredNorm());
    }
    for (size_t l = 0; l < L; ++l) {
        // G^H = (Ubar^H)^+ Ybar^H: the minimum-norm LS solution, Ubar's singular values on the way
        Eigen::JacobiSVD<MatC> sv(U[l].adjoint(), Eigen::ComputeThinU | Eigen::ComputeThinV);
        const auto &s = sv.singularValues();
        const double smax = s(0), smin = s(s.size() - 1), cond = smin > 0 ? smax / smin : HUGE_VAL;
        if (!(smin * smin > 1e-20 * uscale))
            throw Error(fmt("the inputs do not excite line %zu (bin %u): its weakest input direction is %.1f dB below "
                            "the strongest line; drop the line or excite it",
                            l + 1, rq.bins[l], -10.0 * std::log10(smin * smin / uscale)));
        if (!(cond < 1e12))
            throw Error(fmt("the input matrix is singular at line %zu (bin %u, condition number %.3g): the experiments "
                            "do not excite the %u inputs independently there",
                            l + 1, rq.bins[l], cond, nu));
        MatC G = sv.solve(Y[l].adjoint()).adjoint();
        if (!rq.folded.empty() && rq.folded[l]) G = G.conjugate().eval();   // a folded CT line: G at +omega
        if (!G.allFinite()) throw Error(fmt("line %zu (bin %u): the FRF is beyond the range of doubles", l + 1, rq.bins[l]));
        f.G.push_back(G);
        f.cond.push_back(cond);
    }
    return f;
}

// The realisations' BLA when some realisation has one usable period: G_BLA and its total covariance
// from the realisations' spread alone (bla_total), dof R - 1. The noise part (the periods' spread)
// is not in the file: noise_cov, cov_noise, cov_known_input, snr and the distortion test.
static FrfOutcome total_only(const FrfRequest &rq, const std::vector<Record> &recs, uint32_t R, size_t per)
{
    const uint32_t nu = recs[0].nu, ny = recs[0].ny, g = nu * ny;
    if (R < g + 1)
        throw UsageError(fmt(MSID_OPT("realisations") " %u with one period per realisation: the total covariance of the %u entries "
                             "of G is the spread of the realisations' FRFs, of rank at most R - 1 = %u: at least %u "
                             "realisations are needed",
                             R, g, R - 1, g + 1));
    std::vector<RealisationFrf> rs;
    std::string one;   // the realisations with one period, "1, 3, 4"
    uint32_t n_one = 0;
    for (uint32_t r = 0; r < R; ++r) {
        std::vector<Record> block(recs.begin() + (long)(r * per), recs.begin() + (long)((r + 1) * per));
        bool periods2 = true;
        for (const Record &x : block) periods2 = periods2 && usable_periods(x, rq) >= 2;
        if (!periods2) {
            one += (one.empty() ? "" : ", ") + std::to_string(r + 1);
            ++n_one;
        }
        rs.push_back(in_realisation(r, per, [&] { return periods2 ? from_periodic(rq, block) : from_means(rq, block); }));
    }
    FrfOutcome o;
    o.dft_path = rs[0].dft_path;
    Json doc = frf_header(rq, nu, ny, (uint32_t)recs.size());
    uint64_t used = 0, rej = 0;
    Json exps = Json::array();
    for (uint32_t r = 0; r < R; ++r) {
        used += rs[r].used;
        rej += rs[r].rejected;
        for (auto e : rs[r].experiments) {
            e["realisation"] = r;
            exps.push_back(e);
        }
        for (const auto &n : rs[r].notes) o.notes.push_back("realisation " + std::to_string(r + 1) + ": " + n);
    }
    doc["periods_used"] = used;
    doc["periods_rejected"] = rej;
    doc["dft_path"] = o.dft_path;
    doc["vec_convention"] = msidfrf::VEC_CONVENTION;
    doc["experiments"] = exps;
    Json lines = Json::array();
    for (size_t l = 0; l < rq.bins.size(); ++l) {
        std::vector<MatC> G;
        double cond = 1;
        for (const auto &x : rs) {
            G.push_back(x.G[l]);
            if (std::isfinite(x.cond[l])) cond = std::max(cond, x.cond[l]);
        }
        const msidstat::BlaLine b = msidstat::bla_total(G);
        Json e = line_position(rq, l);
        e["G"] = cjson(b.G);
        e["cov"] = cjson(b.cov);
        e["dof"] = b.dof;
        e["cond"] = cond;
        lines.push_back(std::move(e));
    }
    doc["lines"] = std::move(lines);
    const bool all = n_one == R;
    const std::string why =
        fmt("%s: noise and nonlinear distortion cannot be separated (that needs two periods of every realisation)%s; "
            "cov is their total, from the spread of the %u realisations' FRFs (dof %u); noise_cov, cov_noise, "
            "cov_known_input, snr and the distortion test are not estimated",
            all ? "one period per realisation"
                : fmt("one usable period in realisation%s %s", n_one > 1 ? "s" : "", one.c_str()).c_str(),
            all ? "" : ", the others' periods serve their FRFs only", R, R - 1);
    Json nl;
    nl["method"] = "robust (Pintelon & Schoukens 2012 §4.3.1), total covariance only: BLA = mean over realisations; "
                   "cov = total covariance (noise + distortion) from the realisation-to-realisation spread, dof R - 1";
    nl["realisations"] = R;
    nl["experiments_per_realisation"] = per;
    nl["noise_separated"] = false;
    nl["note"] = why;
    doc["nonlinear_distortion"] = nl;
    if (!rq.detect.empty())
        o.notes.push_back("the detection lines are not reported: their test needs the noise level of two periods "
                          "in every realisation");
    o.notes.push_back(why);
    o.doc = std::move(doc);
    return o;
}

FrfOutcome run_frf_realisations(const FrfRequest &rq, const std::vector<Record> &recs, uint32_t R)
{
    if (R < 2) throw UsageError(MSID_OPT("realisations") " must be at least 2 (one realisation: use " MSID_OPT("detect_lines") " for the distortion level)");
    if (recs.size() % R)
        throw UsageError(MSID_OPT("realisations") " " + std::to_string(R) + ": the " + std::to_string(recs.size()) +
                         " experiments do not split into " + std::to_string(R) + " blocks of equal size");
    const size_t per = recs.size() / R;
    if (rq.period >= 1)
        for (const Record &r : recs)
            if (usable_periods(r, rq) < 2) return total_only(rq, recs, R, per);
    std::vector<FrfOutcome> outs;
    for (uint32_t r = 0; r < R; ++r) {
        std::vector<Record> block(recs.begin() + (long)(r * per), recs.begin() + (long)((r + 1) * per));
        outs.push_back(in_realisation(r, per, [&] { return run_frf(rq, block); }));
    }
    for (FrfOutcome &x : outs) x.tree();
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
    std::vector<msidstat::BlaLine> bl;
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
        const msidstat::BlaLine b = msidstat::bla_line(G, C, dof);
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
    const msidstat::BlaSummary s = msidstat::bla_summary(bl);
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
    const double p = msidstat::fisher_combined(pv, &n, &sig);
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
    o["distortion_detected"] = p < msidstat::BLA_DETECT_ALPHA;
    o["nl_to_noise_db"] = excess > 0 ? Json(10.0 * std::log10(excess)) : Json(nullptr);
    return o;
}

}  // namespace msidjob
