// msid frf --method lpm|etfe: FRFs from arbitrary records (tools/est) -> msid-frf/1.
#include "commands.hpp"
#include "host_libs.hpp"
#include "frf_file.hpp"

#include "etfe.hpp"
#include "lpm.hpp"
#include "lpm_eiv.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>
#include <tuple>

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

struct Band {
    bool given = false;
    double f1 = 0, f2 = 0;
};

Band parse_band(const Args &a, double fs)
{
    Band b;
    if (!a.has("band")) return b;
    const std::string s = a.get("band");
    const auto c = s.find(':');
    if (c == std::string::npos) throw UsageError("--band must be F1:F2 (got '" + s + "')");
    b.given = true;
    b.f1 = parse_double(s.substr(0, c), "--band");
    b.f2 = parse_double(s.substr(c + 1), "--band");
    const double nyq = fs > 0 ? fs / 2 : 0.5;
    const char *unit = fs > 0 ? "Hz" : "cycles/sample";
    if (!(b.f1 >= 0) || !(b.f2 > b.f1))
        throw UsageError(fmt("--band %s: need 0 <= F1 < F2", s.c_str()));
    if (b.f2 > nyq)
        throw UsageError(fmt("--band %s: F2 = %g %s is above Nyquist (%g %s)%s", s.c_str(), b.f2, unit, nyq, unit,
                             fs > 0 ? "" : "; without --fs the band is in cycles/sample"));
    return b;
}

// The indices lo..hi (within [1, hi_max]) of the grid points i * fscale / n inside the band, or a
// usage error naming the band; `what` names the grid ("DFT bin of the 4096-sample record").
std::pair<size_t, size_t> band_range(const Band &b, const Args &a, size_t n, double fscale, size_t hi_max,
                                     const std::string &what)
{
    if (!b.given) return {1, hi_max};
    const size_t lo = std::max<size_t>(1, (size_t)std::ceil(b.f1 * n / fscale - 1e-9));
    const size_t hi = std::min<size_t>(hi_max, (size_t)std::floor(b.f2 * n / fscale + 1e-9));
    if (lo > hi) throw UsageError(fmt("--band %s holds no %s", a.get("band").c_str(), what.c_str()));
    return {lo, hi};
}

// Header of the document: record length N as the "period", every estimated bin a line.
Json est_header(FrfRequest &rq, size_t N, const std::vector<size_t> &bins, unsigned nu, unsigned ny, unsigned m,
                const char *method)
{
    rq.period = (uint32_t)N;
    for (size_t k : bins) rq.bins.push_back((uint32_t)k);
    Json doc = frf_header(rq, nu, ny, m);
    doc["method"] = method;
    return doc;
}

// Per-output SNR (dB) of the output DFT at bin k over the noise estimate, summed over experiments.
std::vector<double> out_snr(const msidest::Spectra &S, size_t k, const std::complex<double> *noise)
{
    std::vector<double> r;
    for (unsigned i = 0; i < S.ny; ++i) {
        double p = 0;
        for (unsigned e = 0; e < S.m; ++e) p += std::norm(S.Y(e, i)[k]);
        const double v = noise[i * S.ny + i].real() * S.m;
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

// A singular local input matrix of the LPM: a periodic input (power on its
// excited lines only, none between them) is the usual cause; say so and point
// at the periodic estimator, else pass the LPM's message on.
std::string lpm_singular_cause(const std::vector<Record> &recs, const std::string &what)
{
    std::string rep;
    uint32_t P = 0;
    try {
        P = find_period(recs, rep);
    } catch (const Error &) {
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
static std::string etfe_period_hint(const std::vector<Record> &recs, uint32_t M)
{
    std::string rep;
    uint32_t Q = 0;
    try {
        Q = find_period(recs, rep);
    } catch (const Error &) {
        return "";
    }
    if (Q == 0 || Q == M || recs[0].n_rows / Q < 2) return "";
    return fmt("; the input of '%s' repeats every %u samples%s: use --period %u", recs[0].path.c_str(), Q,
               M % Q == 0 ? fmt(" (with --period %u only every %u-th line is excited)", M, M / Q).c_str() : "", Q);
}

// --method lpm --reference: the LPM of z = [y; u] on the references r (lpm_eiv.hpp). Fills the
// header, the lines (G, its linearised cov, C_e = [I, -G] C_z [I, -G]^H as the line's noise and
// the stacked C_z as `noise_z`) and the noise sum; returns the number of lines.
size_t lpm_reference(const std::vector<Record> &recs, const std::vector<std::string> &ref, const msidest::LpmConfig &c,
                     FrfRequest &rq, Json &doc, Json &lines, std::vector<std::complex<double>> &noise_sum)
{
    const unsigned nu = recs[0].nu, ny = recs[0].ny, m = (unsigned)recs.size(), nz = nu + ny;
    const size_t N = recs[0].n_rows;
    std::vector<std::vector<double>> rows;
    std::vector<msidest::RecordView> views;
    for (const auto &r : recs) rows.push_back(rows_with_reference(r, ref));
    for (const auto &r : rows) views.push_back({r.data(), N, (size_t)(nu + nz)});
    const auto S = msidest::record_spectra(views, nu, nz);
    const auto E = msidest::lpm_eiv(S, ny, c);
    const auto &R = E.zr;
    doc = est_header(rq, N, R.bins, nu, ny, m, "lpm");
    Json cols = Json::array();
    for (size_t k = 0; k < ref.size(); ++k) cols.push_back(fmt("r%zu=%s", k + 1, ref[k].c_str()));
    doc["lpm"] = {{"order", R.R},
                  {"window", R.W},
                  {"window_bins", 2 * R.W + 1},
                  {"dof", R.q},
                  {"band_bins", {R.bins.front(), R.bins.back()}},
                  {"inputs", "noisy (reference)"},
                  {"reference_signals", cols},
                  {"reference", "Pintelon et al. 2010, MSSP 24, Part I/II: LPM of [y; u] on r, G = G_yr G_ur^-1"}};
    doc["experiments"] = experiments_json(recs, N);
    const size_t g = (size_t)ny * nu;
    for (size_t l = 0; l < R.bins.size(); ++l) {
        const auto *nz_ = &E.noise[l * ny * ny];
        std::vector<double> snr;
        for (unsigned i = 0; i < ny; ++i) {
            double p = 0;
            for (unsigned e = 0; e < m; ++e) p += std::norm(S.Y(e, i)[R.bins[l]]);
            const double v = nz_[i * ny + i].real() * m;
            snr.push_back(v > 0 ? 10 * std::log10(p / v) : INFINITY);
        }
        Json e = est_line_json(line_position(rq, l), ny, nu, &E.G[l * g], &E.cov[l * g * g], R.q, nz_, snr);
        e["noise_z"] = cplx_json(&R.noise[l * nz * nz], nz, nz);
        lines.push_back(std::move(e));
        for (size_t t = 0; t < (size_t)ny * ny; ++t) noise_sum[t] += nz_[t];
    }
    return R.bins.size();
}

}  // namespace

int cmd_frf_est(int argc, char **argv)
{
    Args a(argc, argv, 2, HELP_EST, {"method", "order", "window", "band", "fs", "period", "delta", "gstar", "threads", "output", "columns", "reference"},
           {}, {"experiment"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "' (use --experiment)");
    const std::string method = a.get("method");
    const bool is_lpm = method == "lpm";
    for (const char *k : {"order", "window", "reference"})
        if (!is_lpm && a.has(k)) throw UsageError(std::string("--") + k + " applies to --method lpm only");
    for (const char *k : {"period", "delta", "gstar"})
        if (is_lpm && a.has(k)) throw UsageError(std::string("--") + k + " applies to --method etfe only");
    const std::string out = a.require("output");
    FrfRequest rq;
    rq.fs = a.f64("fs", 0.0);
    if (a.has("fs") && !(rq.fs > 0)) throw UsageError("--fs must be positive");
    const Band band = parse_band(a, rq.fs);
    const double fscale = rq.fs > 0 ? rq.fs : 1.0;
    unsigned threads = std::max(1u, std::min(2u, std::thread::hardware_concurrency()));
    threads = a.u32("threads", threads, 1, 64);
    if (a.all("experiment").empty()) throw UsageError("missing --experiment <file.csv>");

    std::vector<Record> recs;
    const ColumnMap cols = a.has("columns") ? parse_column_map(a.get("columns")) : ColumnMap{};
    const std::vector<std::string> ref = a.has("reference") ? parse_reference(a.get("reference")) : std::vector<std::string>{};
    for (size_t k = 0; k < ref.size() && cols.empty(); ++k)   // without a map, only u<k>, y<k>, r<k>, time are known
        if (ref[k] != fmt("r%zu", k + 1) && ref[k] != fmt("R%zu", k + 1))
            throw UsageError(fmt("--reference r%zu=%s names a column: name the inputs and outputs too, with --columns "
                                 "u1=NAME,...,y1=NAME,... (or call the reference columns r1.. and give --reference r1,..)",
                                 k + 1, ref[k].c_str()));
    for (const auto &p : a.all("experiment")) recs.push_back(read_experiment(p, cols));
    const unsigned nu = recs[0].nu, ny = recs[0].ny, m = (unsigned)recs.size();
    msidjob::names_from_records(rq, recs);
    std::vector<msidest::RecordView> views;
    for (const auto &r : recs) {
        if (r.nu != nu || r.ny != ny)
            throw Error(fmt("'%s' has %u input(s) and %u output(s), '%s' has %u and %u", r.path.c_str(), r.nu, r.ny,
                            recs[0].path.c_str(), nu, ny));
        if (r.n_rows != recs[0].n_rows)
            throw Error(fmt("--method %s needs records of equal length: '%s' has %zu samples, '%s' has %zu",
                            method.c_str(), r.path.c_str(), r.n_rows, recs[0].path.c_str(), recs[0].n_rows));
        views.push_back({r.rows.data(), r.n_rows, (size_t)(nu + ny)});
    }
    const size_t N = recs[0].n_rows;
    Json doc, lines = Json::array();
    std::vector<std::complex<double>> noise_mean((size_t)ny * ny);
    size_t nlines = 0;
    try {
        if (is_lpm) {
            msidest::LpmConfig c;
            c.order = a.u32("order", c.order, 0, 8);
            c.window = a.u32("window", c.window);
            if (a.has("window") && c.window == 0) throw UsageError("--window must be at least 1");
            c.threads = threads;
            const size_t Kmax = N >= 3 ? (N - 1) / 2 : 0;
            if (band.given)
                std::tie(c.k_lo, c.k_hi) = band_range(band, a, N, fscale, Kmax,
                                                      fmt("DFT bin of the %zu-sample record (resolution %g %s)", N,
                                                          fscale / N, rq.fs > 0 ? "Hz" : "cycles/sample"));
            const size_t k_hi = c.k_hi ? c.k_hi : Kmax;
            msidjob::check_document_memory(
                k_hi >= c.k_lo ? k_hi - c.k_lo + 1 : 0, ny, nu, fmt("--method lpm on %zu samples", N),
                "the LPM gives one line per DFT bin of the band: narrow it (--band F1:F2) or decimate the record");
            if (!ref.empty()) {   // noisy inputs / closed loop (lpm_reference below)
                nlines = lpm_reference(recs, ref, c, rq, doc, lines, noise_mean);
            } else {
            const auto S = msidest::record_spectra(views, nu, ny);
            const auto R = msidest::lpm(S, c);
            doc = est_header(rq, N, R.bins, nu, ny, m, "lpm");
            doc["lpm"] = {{"order", R.R},
                          {"window", R.W},
                          {"window_bins", 2 * R.W + 1},
                          {"dof", R.q},
                          {"band_bins", {R.bins.front(), R.bins.back()}},
                          {"reference", "Pintelon et al. 2010, MSSP 24, Part I"}};
            doc["experiments"] = experiments_json(recs, N);
            const size_t g = (size_t)ny * nu;
            for (size_t l = 0; l < R.bins.size(); ++l) {
                const auto *nz = &R.noise[l * ny * ny];
                lines.push_back(est_line_json(line_position(rq, l), ny, nu, &R.G[l * g], &R.cov[l * g * g], R.q, nz,
                                              out_snr(S, R.bins[l], nz)));
                for (size_t t = 0; t < (size_t)ny * ny; ++t) noise_mean[t] += nz[t];
            }
            nlines = R.bins.size();
            }
        } else if (method == "etfe") {
            if (!a.has("period")) throw UsageError("--method etfe needs --period M (samples per input period)");
            msidest::EtfeConfig c;
            c.M = a.u32("period", 0);
            c.delta = a.f64("delta", c.delta);
            if (!(c.delta > 0 && c.delta < 1)) throw UsageError("--delta must be in (0, 1)");
            c.gstar = a.f64("gstar", c.gstar);
            if (!(c.gstar >= 0)) throw UsageError("--gstar must be >= 0");
            // the files' own messages first: length, a wrong or absent period (named, as for the periodic
            // estimator), then the ETFE's exact periodicity, each naming the file
            for (const auto &r : recs)
                if (c.M < 2 || r.n_rows % c.M != 0 || r.n_rows / c.M < 2)
                    throw Error(fmt("'%s' has %zu samples: the ETFE needs a whole number Np >= 2 of input periods of "
                                    "M = %zu samples (Tsiamis Assumption 3)%s",
                                    r.path.c_str(), r.n_rows, c.M, etfe_period_hint(recs, (uint32_t)c.M).c_str()));
            if (c.M >= MSID_MIN_PERIOD && c.M <= MSID_MAX_PERIOD) check_periodic_inputs((uint32_t)c.M, 0, {}, recs);
            for (size_t e = 0; e < views.size(); ++e) {
                try {
                    msidest::check_periodic_input({views[e]}, nu, c.M);
                } catch (const msidest::EstError &x) {
                    const char *w = std::strstr(x.what(), ": ");   // "experiment 1: input u1 is not ..."
                    throw Error("'" + recs[e].path + "': " + (w ? w + 2 : x.what()));
                }
            }
            c.du_max = msidest::max_input_norm(views, nu);
            const size_t lmax = (c.M - 1) / 2;
            if (lmax < 1) throw UsageError("--period must be at least 3 samples");
            if (band.given)
                std::tie(c.l_lo, c.l_hi) = band_range(band, a, c.M, fscale, lmax, fmt("line of period %zu", c.M));
            const auto S = msidest::record_spectra(views, nu, ny);
            const auto R = msidest::etfe(S, c);
            doc = est_header(rq, N, R.bins, nu, ny, m, "etfe");
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
            const size_t g = (size_t)ny * nu;
            for (size_t l = 0; l < R.bins.size(); ++l) {
                const auto *nz = &R.noise[l * ny * ny];
                Json e = est_line_json(line_position(rq, l), ny, nu, &R.G[l * g], &R.cov[l * g * g], R.dof, nz,
                                       out_snr(S, R.bins[l], nz));
                e["bound"] = R.bound[l];
                e["bound_noise"] = R.bound_noise[l];
                e["bound_transient"] = R.bound_transient[l];
                lines.push_back(e);
                for (size_t t = 0; t < (size_t)ny * ny; ++t) noise_mean[t] += nz[t];
            }
            nlines = R.bins.size();
        } else {
            throw UsageError("--method must be periodic, lpm or etfe (got '" + method + "')");
        }
    } catch (const msidest::EstError &e) {
        if (is_lpm && std::strstr(e.what(), "local input matrix is singular")) throw Error(lpm_singular_cause(recs, e.what()));
        if (!is_lpm && std::strstr(e.what(), "U U^H is singular") && !etfe_period_hint(recs, a.u32("period", 0)).empty())
            throw Error(std::string(e.what()) + etfe_period_hint(recs, a.u32("period", 0)));
        throw Error(e.what());
    }
    for (auto &x : noise_mean) x /= (double)nlines * (double)N;
    doc["noise_cov"] = cplx_json(noise_mean.data(), ny, ny);
    doc["periods_used"] = 0;
    for (const auto &e : doc["experiments"]) doc["periods_used"] = doc["periods_used"].get<uint64_t>() + e["periods_used"].get<uint64_t>();
    doc["periods_rejected"] = 0;
    doc["vec_convention"] = msidfrf::VEC_CONVENTION;
    doc["lines"] = std::move(lines);
    write_json_file(out, doc);
    std::printf("wrote %s: %zu lines, %u output(s) x %u input(s), %u experiment(s), %zu samples each (%s)\n",
                out.c_str(), nlines, ny, nu, m, N, method.c_str());
    return 0;
}

}  // namespace msidcli
