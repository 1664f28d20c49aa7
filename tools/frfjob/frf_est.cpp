// The FRF of arbitrary records by the LPM or the ETFE (tools/est) -> msid-frf/1 (msid_frf_est.hpp).
#include "msid_frf_est.hpp"
#include "msid_cancel.hpp"
#include "frf_doc.hpp"
#include "frf_file.hpp"
#include "msid_reference.hpp"
#include "periodicity.hpp"

#include "etfe.hpp"
#include "lpm.hpp"
#include "lpm_eiv.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <thread>

namespace msidjob {

using msidutil::fmt;
using cplx = std::complex<double>;

EstPlan::Method est_method(const std::string &name)
{
    if (name == "lpm") return EstPlan::Method::lpm;
    if (name == "etfe") return EstPlan::Method::etfe;
    throw UsageError(MSID_OPT("method") " must be periodic, lpm or etfe (got '" + name + "')");
}

// ---- the plan: what applies to which method, and its ranges ----

void check_est_plan(const EstPlan &p, double fs)
{
    const bool lpm = p.method == EstPlan::Method::lpm;
    auto only = [](const char *k, const char *m) {
        throw UsageError(msidutil::option_mark(k) + " applies to " MSID_OPT("method") " " + m + " only");
    };
    if (!lpm && p.order) only("order", "lpm");
    if (!lpm && p.window) only("window", "lpm");
    if (!lpm && (!p.reference.empty() || !p.reference_rows.empty())) only("reference", "lpm");
    if (lpm && p.period) only("period", "etfe");
    if (lpm && p.delta) only("delta", "etfe");
    if (lpm && p.gstar) only("gstar", "etfe");
    if (p.order && *p.order > 8) throw UsageError(MSID_OPT("order") " must be 0..8");
    if (p.window && *p.window == 0) throw UsageError(MSID_OPT("window") " must be at least 1");
    // 2W+1 bins of a record's spectrum: no record msid reads has more than 2^24 (and 2W+1 must not wrap)
    if (p.window && *p.window >= (1u << 23))
        throw UsageError(msidutil::fmt(MSID_OPT("window") " %u: a window of 2W+1 = %llu bins is more than any record's spectrum "
                                       "holds (at most 8388607)", *p.window, 2ull * *p.window + 1));
    if (p.delta && !(*p.delta > 0 && *p.delta < 1)) throw UsageError(MSID_OPT("delta") " must be in (0, 1)");
    if (p.gstar && !(*p.gstar >= 0)) throw UsageError(MSID_OPT("gstar") " must be >= 0");
    if (p.given.has("threads") ? p.threads == 0 || p.threads > 64 : p.threads > 64)
        throw UsageError(MSID_OPT("threads") " must be 1..64");
    if (p.given.has("fs") && !(fs > 0)) throw UsageError(MSID_OPT("fs") " must be positive");
    if (!lpm && !p.period) throw UsageError(MSID_OPT("method") " etfe needs " MSID_OPT("period") " M (samples per input period)");
    if (!p.band) return;
    const char *s = p.band_text.c_str();
    const double nyq = fs > 0 ? fs / 2 : 0.5;
    const char *unit = fs > 0 ? "Hz" : "cycles/sample";
    if (!(p.f1 >= 0) || !(p.f2 > p.f1)) throw UsageError(fmt(MSID_OPT("band") " %s: need 0 <= F1 < F2", s));
    if (p.f2 > nyq)
        throw UsageError(fmt(MSID_OPT("band") " %s: F2 = %g %s is above Nyquist (%g %s)%s", s, p.f2, unit, nyq, unit,
                             fs > 0 ? "" : "; without " MSID_OPT("fs") " the band is in cycles/sample"));
}

void check_reference_columns(const std::vector<std::string> &ref, const msidrec::ColumnMap &cols)
{
    for (size_t k = 0; k < ref.size() && cols.empty(); ++k)
        if (ref[k] != fmt("r%zu", k + 1) && ref[k] != fmt("R%zu", k + 1))
            throw UsageError(fmt(MSID_OPT("reference") " r%zu=%s names a column: name the inputs and outputs too, with " MSID_OPT("columns") " "
                                 "u1=NAME,...,y1=NAME,... (or call the reference columns r1.. and give " MSID_OPT("reference") " r1,..)",
                                 k + 1, ref[k].c_str()));
}

namespace {

// The indices lo..hi (within [1, hi_max]) of the grid points i * fscale / n inside the band, or a
// usage error naming the band; `what` names the grid ("DFT bin of the 4096-sample record").
std::pair<size_t, size_t> band_range(const EstPlan &p, size_t n, double fscale, size_t hi_max, const std::string &what)
{
    if (!p.band) return {1, hi_max};
    const size_t lo = std::max<size_t>(1, (size_t)std::ceil(p.f1 * n / fscale - 1e-9));
    const size_t hi = std::min<size_t>(hi_max, (size_t)std::floor(p.f2 * n / fscale + 1e-9));
    if (lo > hi) throw UsageError(fmt(MSID_OPT("band") " %s holds no %s", p.band_text.c_str(), what.c_str()));
    return {lo, hi};
}

unsigned thread_count(const EstPlan &p)
{
    return p.threads ? p.threads : std::max(1u, std::min(2u, std::thread::hardware_concurrency()));
}

// ---- the records ----

std::vector<msidest::RecordView> record_views(const std::vector<Record> &recs, const char *method)
{
    if (recs.empty()) throw Error("no records");
    const unsigned nu = recs[0].nu, ny = recs[0].ny;
    std::vector<msidest::RecordView> views;
    for (const auto &r : recs) {
        if (r.nu != nu || r.ny != ny)
            throw Error(fmt("'%s' has %u input(s) and %u output(s), '%s' has %u and %u", r.path.c_str(), r.nu, r.ny,
                            recs[0].path.c_str(), nu, ny));
        if (r.n_rows != recs[0].n_rows)
            throw Error(fmt(MSID_OPT("method") " %s needs records of equal length: '%s' has %zu samples, '%s' has %zu", method,
                            r.path.c_str(), r.n_rows, recs[0].path.c_str(), recs[0].n_rows));
        views.push_back({r.data(), r.n_rows, (size_t)(nu + ny)});
    }
    return views;
}

// Rows [r_1..r_nu, y_1..y_ny, u_1..u_nu] of record e for the LPM on references: from the file's
// reference columns, or from the caller's reference samples.
std::vector<double> reference_rows(const Record &r, const EstPlan &p, size_t e)
{
    if (!p.reference.empty()) return msidrec::rows_with_reference(r, p.reference);
    const size_t nu = r.nu, ny = r.ny, w = nu + ny, N = r.n_rows;
    std::vector<double> rows(N * (nu + w));
    const double *ref = p.reference_rows[e], *x = r.data();
    for (size_t t = 0; t < N; ++t) {
        double *o = &rows[t * (nu + w)];
        std::copy(ref + t * nu, ref + (t + 1) * nu, o);
        std::copy(x + t * w + nu, x + (t + 1) * w, o + nu);   // y
        std::copy(x + t * w, x + t * w + nu, o + nu + ny);    // u
    }
    return rows;
}

// ---- the document's parts ----

// Lines of the document built between two checkpoints: about a millisecond of work, so that Ctrl-C
// lands within a small share of a document of a million lines (seconds to build).
constexpr size_t DOC_CHUNK = 1024;

// Header of the document: record length N as the "period", every estimated bin a line.
Json est_header(FrfRequest &rq, size_t N, const std::vector<size_t> &bins, unsigned nu, unsigned ny, unsigned m,
                const char *method)
{
    rq.period = (uint32_t)N;
    rq.bins.clear();
    for (size_t k : bins) rq.bins.push_back((uint32_t)k);
    Json doc = frf_header(rq, nu, ny, m);
    doc["method"] = method;
    return doc;
}

// Per-output SNR (dB) of the output DFT at bin k over the noise estimate, summed over experiments.
std::vector<double> out_snr(const msidest::Spectra &S, size_t k, const cplx *noise, unsigned ny)
{
    std::vector<double> r;
    for (unsigned i = 0; i < ny; ++i) {
        double p = 0;
        for (unsigned e = 0; e < S.m; ++e) p += std::norm(S.Y(e, i)[k]);
        const double v = noise[i * ny + i].real() * S.m;
        r.push_back(v > 0 ? 10 * std::log10(p / v) : INFINITY);
    }
    return r;
}

Json experiments_json(const std::vector<Record> &recs, size_t period)
{
    Json ex = Json::array();
    for (const auto &r : recs) {
        msidfrf::Experiment x;
        x.source = r.path;
        x.samples = r.n_rows;
        x.periods_total = r.n_rows / period;
        x.periods_used = r.n_rows / period;
        x.transient_tested = false;
        x.leftover_samples = r.n_rows % period;
        ex.push_back(msidfrf::experiment(x));
    }
    return ex;
}

// The lines and the noise sum shared by every estimator: G (ny x nu), cov, noise (ny x ny) per line.
struct Lines {
    Json lines = Json::array();
    std::vector<cplx> noise_sum;
    size_t n = 0;
};

// ---- the estimators ----

// A singular local input matrix of the LPM: a periodic input (power on its excited lines only,
// none between them) is the usual cause; say so and point at the periodic estimator.
std::string lpm_singular_cause(const std::vector<Record> &recs, const std::string &what)
{
    std::string rep;
    uint32_t P = 0;
    try {
        P = find_period(recs, rep);
    } catch (const msidutil::Error &) {
        return what;
    }
    if (P == 0 || recs[0].n_rows / P < 2) return what;
    return fmt("'%s': the input is periodic with period %u samples (%zu whole periods): its power sits on the "
               "excited lines of that period and none lies between them, so the LPM cannot fit G there (%s). Use the "
               "default periodic estimator (drop --method lpm): msid frf --period %u --lines auto --experiment ...",
               recs[0].path.c_str(), P, recs[0].n_rows / P, what.c_str(), P);
}

// --method etfe --period M on an input that repeats with another period Q (found from the input):
// "; the input repeats every Q samples ...: --period Q", else "" (Q = M, or no period found).
std::string etfe_period_hint(const std::vector<Record> &recs, uint32_t M)
{
    std::string rep;
    uint32_t Q = 0;
    try {
        Q = find_period(recs, rep);
    } catch (const msidutil::Error &) {
        return "";
    }
    if (Q == 0 || Q == M || recs[0].n_rows / Q < 2) return "";
    return fmt("; the input of '%s' repeats every %u samples%s: use --period %u", recs[0].path.c_str(), Q,
               M % Q == 0 ? fmt(" (with --period %u only every %u-th line is excited)", M, M / Q).c_str() : "", Q);
}

msidest::LpmConfig lpm_config(const EstPlan &p, FrfRequest &rq, const std::vector<Record> &recs)
{
    const size_t N = recs[0].n_rows;
    msidest::LpmConfig c;
    if (p.order) c.order = *p.order;
    if (p.window) c.window = *p.window;
    c.threads = thread_count(p);
    const size_t Kmax = N >= 3 ? (N - 1) / 2 : 0;
    const double fscale = rq.fs > 0 ? rq.fs : 1.0;
    if (p.band)
        std::tie(c.k_lo, c.k_hi) = band_range(p, N, fscale, Kmax,
                                              fmt("DFT bin of the %zu-sample record (resolution %g %s)", N, fscale / N,
                                                  rq.fs > 0 ? "Hz" : "cycles/sample"));
    const size_t k_hi = c.k_hi ? c.k_hi : Kmax;
    check_document_memory(k_hi >= c.k_lo ? k_hi - c.k_lo + 1 : 0, recs[0].ny, recs[0].nu,
                          fmt("--method lpm on %zu samples", N),
                          "the LPM gives one line per DFT bin of the band: narrow it (--band F1:F2) or decimate the record");
    return c;
}

// The LPM with known inputs (Pintelon et al. 2010, Part I).
Json run_lpm(FrfRequest &rq, const std::vector<Record> &recs, const std::vector<msidest::RecordView> &views,
             const msidest::LpmConfig &c, Lines &L)
{
    const unsigned nu = recs[0].nu, ny = recs[0].ny, m = (unsigned)recs.size();
    const size_t N = recs[0].n_rows, g = (size_t)ny * nu;
    const auto S = msidest::record_spectra(views, nu, ny);
    const auto R = msidest::lpm(S, c);
    Json doc = est_header(rq, N, R.bins, nu, ny, m, "lpm");
    doc["lpm"] = {{"order", R.R},
                  {"window", R.W},
                  {"window_bins", 2 * R.W + 1},
                  {"dof", R.q},
                  {"band_bins", {R.bins.front(), R.bins.back()}},
                  {"reference", "Pintelon et al. 2010, MSSP 24, Part I"}};
    doc["experiments"] = experiments_json(recs, N);
    for (size_t l = 0; l < R.bins.size(); ++l) {
        if (l % DOC_CHUNK == DOC_CHUNK - 1) msidutil::checkpoint(msidutil::Step::document, DOC_CHUNK, "the FRF document");
        const cplx *nz = &R.noise[l * ny * ny];
        L.lines.push_back(est_line_json(line_position(rq, l), ny, nu, &R.G[l * g], &R.cov[l * g * g], R.q, nz,
                                        out_snr(S, R.bins[l], nz, ny)));
        for (size_t t = 0; t < (size_t)ny * ny; ++t) L.noise_sum[t] += nz[t];
    }
    L.n = R.bins.size();
    return doc;
}

// Noisy inputs or a closed loop: the LPM of z = [y; u] on the references r (lpm_eiv.hpp), then
// G = G_yr G_ur^-1 with its linearised covariance; C_e = [I, -G] C_z [I, -G]^H is the line's noise
// and the stacked C_z its `noise_z`.
Json run_lpm_reference(FrfRequest &rq, const std::vector<Record> &recs, const EstPlan &p,
                       const msidest::LpmConfig &c, Lines &L)
{
    const unsigned nu = recs[0].nu, ny = recs[0].ny, m = (unsigned)recs.size(), nz = nu + ny;
    const size_t N = recs[0].n_rows, g = (size_t)ny * nu;
    std::vector<std::vector<double>> rows;
    std::vector<msidest::RecordView> views;
    for (size_t e = 0; e < recs.size(); ++e) rows.push_back(reference_rows(recs[e], p, e));
    for (const auto &r : rows) views.push_back({r.data(), N, (size_t)(nu + nz)});
    const auto S = msidest::record_spectra(views, nu, nz);
    const auto E = msidest::lpm_eiv(S, ny, c);
    const auto &R = E.zr;
    Json doc = est_header(rq, N, R.bins, nu, ny, m, "lpm");
    Json cols = Json::array();
    for (size_t k = 0; k < nu; ++k)
        cols.push_back(p.reference.empty() ? fmt("r%zu", k + 1) : fmt("r%zu=%s", k + 1, p.reference[k].c_str()));
    doc["lpm"] = {{"order", R.R},
                  {"window", R.W},
                  {"window_bins", 2 * R.W + 1},
                  {"dof", R.q},
                  {"band_bins", {R.bins.front(), R.bins.back()}},
                  {"inputs", "noisy (reference)"},
                  {"reference_signals", cols},
                  {"reference", "Pintelon et al. 2010, MSSP 24, Part I/II: LPM of [y; u] on r, G = G_yr G_ur^-1"}};
    doc["experiments"] = experiments_json(recs, N);
    for (size_t l = 0; l < R.bins.size(); ++l) {
        if (l % DOC_CHUNK == DOC_CHUNK - 1) msidutil::checkpoint(msidutil::Step::document, DOC_CHUNK, "the FRF document");
        const cplx *ne = &E.noise[l * ny * ny];
        std::vector<double> snr;
        for (unsigned i = 0; i < ny; ++i) {
            double pw = 0;
            for (unsigned e = 0; e < m; ++e) pw += std::norm(S.Y(e, i)[R.bins[l]]);
            const double v = ne[i * ny + i].real() * m;
            snr.push_back(v > 0 ? 10 * std::log10(pw / v) : INFINITY);
        }
        Json e = est_line_json(line_position(rq, l), ny, nu, &E.G[l * g], &E.cov[l * g * g], R.q, ne, snr);
        e["noise_z"] = cplx_json(&R.noise[l * nz * nz], nz, nz);
        L.lines.push_back(std::move(e));
        for (size_t t = 0; t < (size_t)ny * ny; ++t) L.noise_sum[t] += ne[t];
    }
    L.n = R.bins.size();
    return doc;
}

// The ETFE's own checks, each naming the file: the length (whole periods), the input's exact
// periodicity (the periodic estimator's message first, then the ETFE's).
void check_etfe_records(const std::vector<Record> &recs, const std::vector<msidest::RecordView> &views, uint32_t M)
{
    for (const auto &r : recs)
        if (M < 2 || r.n_rows % M != 0 || r.n_rows / M < 2)
            throw Error(fmt("'%s' has %zu samples: the ETFE needs a whole number Np >= 2 of input periods of "
                            "M = %u samples (Tsiamis Assumption 3)%s",
                            r.path.c_str(), r.n_rows, M, etfe_period_hint(recs, M).c_str()));
    if (M >= MSID_MIN_PERIOD && M <= MSID_MAX_PERIOD) check_periodic_inputs(M, 0, {}, recs);
    for (size_t e = 0; e < views.size(); ++e) {
        try {
            msidest::check_periodic_input({views[e]}, recs[0].nu, M);
        } catch (const msidest::EstError &x) {
            const char *w = std::strstr(x.what(), ": ");   // "experiment 1: input u1 is not ..."
            throw Error("'" + recs[e].path + "': " + (w ? w + 2 : x.what()));
        }
    }
}

// The ETFE for inputs of period M with the bound of Tsiamis et al. 2024, Theorem 1.
Json run_etfe(FrfRequest &rq, const std::vector<Record> &recs, const std::vector<msidest::RecordView> &views,
              const EstPlan &p, Lines &L)
{
    const unsigned nu = recs[0].nu, ny = recs[0].ny, m = (unsigned)recs.size();
    const size_t N = recs[0].n_rows, g = (size_t)ny * nu;
    msidest::EtfeConfig c;
    c.M = *p.period;
    if (p.delta) c.delta = *p.delta;
    if (p.gstar) c.gstar = *p.gstar;
    check_etfe_records(recs, views, *p.period);
    c.du_max = msidest::max_input_norm(views, nu);
    const size_t lmax = (c.M - 1) / 2;
    if (lmax < 1) throw UsageError(MSID_OPT("period") " must be at least 3 samples");
    if (p.band)
        std::tie(c.l_lo, c.l_hi) =
            band_range(p, c.M, rq.fs > 0 ? rq.fs : 1.0, lmax, fmt("line of period %zu", c.M));
    const auto S = msidest::record_spectra(views, nu, ny);
    const auto R = msidest::etfe(S, c);
    Json doc = est_header(rq, N, R.bins, nu, ny, m, "etfe");
    doc["etfe"] = {{"input_period", R.M},
                   {"periods", R.Np},
                   {"dof", R.dof},
                   {"delta", c.delta},
                   {"gstar", c.gstar},
                   {"transient_term", c.gstar > 0},
                   {"input_bound", c.du_max},
                   {"log_term", R.log_term},
                   {"reference", "Tsiamis et al. 2024, Theorem 1 eq. (12), constants of App. B/D"}};
    doc["experiments"] = experiments_json(recs, c.M);
    for (size_t l = 0; l < R.bins.size(); ++l) {
        if (l % DOC_CHUNK == DOC_CHUNK - 1) msidutil::checkpoint(msidutil::Step::document, DOC_CHUNK, "the FRF document");
        const cplx *nz = &R.noise[l * ny * ny];
        Json e = est_line_json(line_position(rq, l), ny, nu, &R.G[l * g], &R.cov[l * g * g], R.dof, nz,
                               out_snr(S, R.bins[l], nz, ny));
        e["bound"] = R.bound[l];
        e["bound_noise"] = R.bound_noise[l];
        e["bound_transient"] = R.bound_transient[l];
        L.lines.push_back(std::move(e));
        for (size_t t = 0; t < (size_t)ny * ny; ++t) L.noise_sum[t] += nz[t];
    }
    L.n = R.bins.size();
    return doc;
}

// The estimator's message, with the cause named where the input explains it.
[[noreturn]] void rethrow_est(const msidest::EstError &e, const std::vector<Record> &recs, const EstPlan &p)
{
    if (p.method == EstPlan::Method::lpm && std::strstr(e.what(), "local input matrix is singular"))
        throw Error(lpm_singular_cause(recs, e.what()));
    if (p.method == EstPlan::Method::etfe && std::strstr(e.what(), "U U^H is singular")) {
        const std::string hint = etfe_period_hint(recs, *p.period);
        if (!hint.empty()) throw Error(std::string(e.what()) + hint);
    }
    throw Error(e.what());
}

}  // namespace

FrfOutcome estimate_frf_est(FrfRequest &rq, const std::vector<Record> &recs, const EstPlan &p)
{
    check_est_plan(p, rq.fs);
    const bool lpm = p.method == EstPlan::Method::lpm;
    const auto views = record_views(recs, lpm ? "lpm" : "etfe");
    if (!p.reference_rows.empty() && p.reference_rows.size() != recs.size())
        throw UsageError(fmt("reference: %zu reference record(s) for %zu record(s)", p.reference_rows.size(), recs.size()));
    names_from_records(rq, recs);
    const unsigned ny = recs[0].ny;
    Lines L;
    L.noise_sum.assign((size_t)ny * ny, cplx(0));
    FrfOutcome o;
    try {
        if (lpm) {
            const auto c = lpm_config(p, rq, recs);
            const bool ref = !p.reference.empty() || !p.reference_rows.empty();
            o.doc = ref ? run_lpm_reference(rq, recs, p, c, L) : run_lpm(rq, recs, views, c, L);
        } else {
            o.doc = run_etfe(rq, recs, views, p, L);
        }
    } catch (const msidest::EstError &e) {
        rethrow_est(e, recs, p);
    }
    const double N = (double)recs[0].n_rows;
    for (auto &x : L.noise_sum) x /= (double)L.n * N;
    Json &doc = o.doc;
    doc["noise_cov"] = cplx_json(L.noise_sum.data(), ny, ny);
    uint64_t used = 0;
    for (const auto &e : doc["experiments"]) used += e["periods_used"].get<uint64_t>();
    doc["periods_used"] = used;
    doc["periods_rejected"] = 0;
    doc["vec_convention"] = msidfrf::VEC_CONVENTION;
    doc["lines"] = std::move(L.lines);
    return o;
}

}  // namespace msidjob
