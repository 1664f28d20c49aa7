// Input periodicity: --period auto, --lines auto, and the diagnostics that
// name a non-periodic input or a wrong --period. See periodicity.hpp and
// docs/statistics.md ("Input periodicity").
#include "periodicity.hpp"
#include "frf_job_detail.hpp"
#include "msid_fftw_planner.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <map>
#include <numeric>
#include <exception>
#include <system_error>
#include <thread>

namespace msidjob {

namespace {

// A real-to-complex DFT of length n: buffers of its own, the process's shared plan of that length
// (msidutil::shared_real_plan: ESTIMATE, deterministic; planned once, not per check).
struct R2c {
    int n;
    double *in;
    fftw_complex *out;
    fftw_plan plan;
    explicit R2c(int n_) : n(n_)
    {
        in = fftw_alloc_real((size_t)n);
        out = fftw_alloc_complex((size_t)n / 2 + 1);
        plan = in && out ? msidutil::shared_real_plan((size_t)n, false) : nullptr;
        if (!plan) {
            fftw_free(in);
            fftw_free(out);
            throw Error("out of memory for an FFT of length " + std::to_string(n));
        }
    }
    ~R2c() { fftw_free(in); fftw_free(out); }
    R2c(const R2c &) = delete;
    R2c &operator=(const R2c &) = delete;
    void run() { fftw_execute_dft_r2c(plan, in, out); }
    std::complex<double> at(size_t k) const { return {out[k][0], out[k][1]}; }
};

// Samples used by the cheap checks: at least 4 periods, at least 2^14
// samples when the record has them, never more than the record.
size_t window_periods(const Record &r, uint32_t P, uint32_t skip)
{
    const size_t K = r.n_rows / P;
    const size_t avail = K > skip ? K - skip : 0;
    const size_t want = std::max<size_t>(4, ((size_t)1 << 14) / P + 1);
    return std::min(avail, want);
}

// Per-period input spectra at bins 1 .. ceil(P/2)-1 of channel j over periods
// first .. first+count-1: spec[p][k-1].
std::vector<std::vector<std::complex<double>>> period_spectra(const Record &r, uint32_t P, size_t first, size_t count,
                                                              uint32_t j, R2c &f)
{
    const size_t C = r.nu + r.ny, M = (P + 1) / 2 - 1;
    std::vector<std::vector<std::complex<double>>> s(count, std::vector<std::complex<double>>(M));
    for (size_t p = 0; p < count; ++p) {
        const double *x = r.data() + (first + p) * P * C + j;
        for (uint32_t n = 0; n < P; ++n) f.in[n] = x[(size_t)n * C];
        f.run();
        for (size_t k = 1; k <= M; ++k) s[p][k - 1] = f.at(k);
    }
    return s;
}

}  // namespace

// nonperiodic_fraction() over `count` periods of P starting at row `start`.
static double nonperiodic_fraction_at(const Record &r, uint32_t P, size_t start, size_t count)
{
    const size_t C = r.nu + r.ny;
    const double *x0 = r.data() + start * C;
    double num = 0, den = 0;
    std::vector<double> ubar(P);
    for (uint32_t j = 0; j < r.nu; ++j) {
        double mean = 0;
        std::fill(ubar.begin(), ubar.end(), 0.0);
        for (size_t p = 0; p < count; ++p) {
            const double *x = x0 + p * P * C + j;
            for (uint32_t n = 0; n < P; ++n) ubar[n] += x[(size_t)n * C];
        }
        for (uint32_t n = 0; n < P; ++n) { mean += ubar[n]; ubar[n] /= (double)count; }
        mean /= (double)count * P;
        // four partial sums each (samples n mod 4): the sums' add latency, not the loads, bounded
        // the loop with one; a fixed order, so the same samples give the same bits
        double nu4[4] = {0, 0, 0, 0}, de4[4] = {0, 0, 0, 0};
        for (size_t p = 0; p < count; ++p) {
            const double *x = x0 + p * P * C + j;
            uint32_t n = 0;
            for (; n + 4 <= P; n += 4)
                for (uint32_t q = 0; q < 4; ++q) {
                    const double v = x[(size_t)(n + q) * C], d = v - ubar[n + q], a = v - mean;
                    nu4[q] += d * d;
                    de4[q] += a * a;
                }
            for (; n < P; ++n) {
                const double v = x[(size_t)n * C], d = v - ubar[n], a = v - mean;
                nu4[n % 4] += d * d;
                de4[n % 4] += a * a;
            }
        }
        num += (nu4[0] + nu4[1]) + (nu4[2] + nu4[3]);
        den += (de4[0] + de4[1]) + (de4[2] + de4[3]);
    }
    return den > 0 ? num / den : 0.0;
}

double nonperiodic_fraction(const Record &r, uint32_t P, size_t first, size_t count)
{
    return nonperiodic_fraction_at(r, P, first * P, count);
}

double binomial_tail(size_t n, size_t k, double a)
{
    if (k == 0) return 1.0;
    if (k > n) return 0.0;
    // sum_{i >= k} C(n, i) a^i (1-a)^(n-i), terms in log space from i = k upwards
    const double la = std::log(a), lb = std::log1p(-a);
    double lt = std::lgamma((double)n + 1) - std::lgamma((double)k + 1) - std::lgamma((double)(n - k) + 1) +
                (double)k * la + (double)(n - k) * lb;
    double sum = 0;
    for (size_t i = k; i <= n; ++i) {
        sum += std::exp(lt);
        if (i < n) lt += std::log((double)(n - i) / (double)(i + 1)) + la - lb;
        if (lt < -745) break;
    }
    return std::min(1.0, sum);
}

// Tail of F(2, 2n): P(F > f) = (1 + f/n)^-n.
static double f2_tail(double f, double n) { return std::isinf(f) ? 0.0 : std::exp(-n * std::log1p(f / n)); }

// Adds one (bin, channel) pair: K |mean|^2 and the scatter sum |z - mean|^2 over K periods.
static void evidence_add(PeriodicEvidence &ev, double &num, double &den, double kmean2, double scatter, size_t K)
{
    if (!(kmean2 > 0) && !(scatter > 0)) return;   // silent channel at this bin
    ++ev.tested;
    num += scatter;
    den += scatter + kmean2;
    const double n = (double)(K - 1);
    const double F = scatter > 0 ? kmean2 / (scatter / n) : HUGE_VAL;
    const double pv = f2_tail(F, n);
    if (pv < PERIODIC_BIN_ALPHA) ++ev.shown;
    ev.min_p = std::min(ev.min_p, pv);
}

static void evidence_finish(PeriodicEvidence &ev, double num, double den)
{
    ev.eta = den > 0 ? num / den : 0.0;
    ev.p_value = binomial_tail(ev.tested, ev.shown, PERIODIC_BIN_ALPHA);
}

// The best period near P (|P' - P| <= 2) on the checking window (starting at
// the same sample, skip * P), or 0 if none is better than eta.
static uint32_t better_neighbour(const Record &r, uint32_t P, uint32_t skip, double eta, double &eta_best)
{
    uint32_t best = 0;
    eta_best = eta;
    const size_t start = (size_t)skip * P, rows = r.n_rows > start ? r.n_rows - start : 0;
    for (int d = -2; d <= 2; ++d) {
        if (d == 0 || (int64_t)P + d < (int64_t)MSID_MIN_PERIOD) continue;
        const uint32_t Q = (uint32_t)((int64_t)P + d);
        const size_t K = std::min(rows / Q, window_periods(r, P, skip));
        if (K < 2) continue;
        const double et = nonperiodic_fraction_at(r, Q, start, K);
        if (et < eta_best) { eta_best = et; best = Q; }
    }
    return best;
}

// Leakage of the inputs into non-excited bins and the phase drift per period
// at the strongest line, both with period P: the symptoms of a wrong period.
static std::string wrong_period_symptoms(const Record &r, uint32_t P, uint32_t skip, const std::vector<uint32_t> &bins)
{
    const size_t K = window_periods(r, P, skip);
    if (K < 2 || P < 4) return "";
    R2c f((int)P);
    std::vector<uint8_t> exc((P + 1) / 2, 0);
    for (uint32_t b : bins) if (b > 0 && b < exc.size()) exc[b] = 1;
    double leak = 0, tot = 0, best = -1, drift = 0;
    uint32_t kbest = 0;
    for (uint32_t j = 0; j < r.nu; ++j) {
        auto s = period_spectra(r, P, skip, K, j, f);
        for (size_t k = 1; k <= s[0].size(); ++k) {
            double pw = 0;
            for (size_t p = 0; p < K; ++p) pw += std::norm(s[p][k - 1]);
            tot += pw;
            if (!bins.empty() && !exc[k]) leak += pw;
            if (pw > best) {
                best = pw;
                kbest = (uint32_t)k;
                std::complex<double> acc = 0;
                for (size_t p = 0; p + 1 < K; ++p) acc += s[p + 1][k - 1] * std::conj(s[p][k - 1]);
                drift = std::arg(acc) * 180.0 / M_PI;
            }
        }
    }
    std::string out;
    if (!bins.empty() && tot > 0) out += fmt("%.0f%% of the input power leaks into non-excited bins and ", 100 * leak / tot);
    out += fmt("the input phase at bin %u drifts by %.1f degrees per period", kbest, drift);
    return out;
}

// The mean over the `count` period spectra s (period_spectra) at bin k, 1 <= k <= (P + 1) / 2 - 1.
static std::complex<double> period_mean(const std::vector<std::vector<std::complex<double>>> &s, size_t count, size_t k)
{
    std::complex<double> mu = 0;
    for (size_t p = 0; p < count; ++p) mu += s[p][k - 1];
    return mu / (double)count;
}

PeriodicEvidence periodic_evidence(const Record &r, uint32_t P, size_t first, size_t count,
                                   const std::vector<uint32_t> &bins)
{
    PeriodicEvidence ev;
    if (count < 2 || P < 4) return ev;
    R2c f((int)P);
    const size_t M = (P + 1) / 2 - 1;
    double num = 0, den = 0;
    for (uint32_t j = 0; j < r.nu; ++j) {
        const auto s = period_spectra(r, P, first, count, j, f);
        auto one = [&](size_t k) {   // bin k in 1..M
            const std::complex<double> mu = period_mean(s, count, k);
            double ss = 0;
            for (size_t p = 0; p < count; ++p) ss += std::norm(s[p][k - 1] - mu);
            evidence_add(ev, num, den, (double)count * std::norm(mu), ss, count);
        };
        if (bins.empty()) for (size_t k = 1; k <= M; ++k) one(k);
        else for (uint32_t b : bins) if (b >= 1 && b <= M) one(b);
    }
    evidence_finish(ev, num, den);
    return ev;
}

void check_periodic_lines(const msid_pstats *const *ps, uint32_t m, uint32_t nu, uint32_t P,
                          const std::vector<uint32_t> &bins, const std::vector<std::string> &sources)
{
    for (uint32_t e = 0; e < m; ++e) {
        const msid_pstats *s = ps[e];
        const size_t K = s->K, q = s->n_channels;
        if (K < 2) continue;   // finish() says so
        PeriodicEvidence ev;
        double num = 0, den = 0;
        for (uint32_t l = 0; l < s->n_lines; ++l) {
            const msid_cplx *mu = msid_pstats_mean(s, l), *m2 = msid_pstats_scatter(s, l);
            for (uint32_t j = 0; j < nu; ++j)
                evidence_add(ev, num, den, (double)K * (mu[j].re * mu[j].re + mu[j].im * mu[j].im),
                             m2[(size_t)j * q + j].re, K);
        }
        evidence_finish(ev, num, den);
        // (a non-finite eta: data beyond double range, which the FRF itself reports)
        if (ev.tested == 0 || !(ev.eta > NONPERIODIC_FRACTION) || ev.periodic()) continue;
        // With a history: does the strongest line rotate coherently from period to period?
        std::string why;
        const size_t H = s->nhist, n = (size_t)s->n_lines * q;
        if (H >= 3) {
            uint32_t lb = 0, jb = 0;
            double best = -1;
            for (uint32_t l = 0; l < s->n_lines; ++l)
                for (uint32_t j = 0; j < nu; ++j) {
                    double pw = 0;
                    for (size_t p = 0; p < H; ++p) {
                        const msid_cplx z = s->hist[p * n + (size_t)l * q + j];
                        pw += z.re * z.re + z.im * z.im;
                    }
                    if (pw > best) { best = pw; lb = l; jb = j; }
                }
            std::complex<double> acc = 0;
            double mag = 0;
            for (size_t p = 0; p + 1 < H; ++p) {
                const msid_cplx a = s->hist[p * n + (size_t)lb * q + jb], b = s->hist[(p + 1) * n + (size_t)lb * q + jb];
                const std::complex<double> za(a.re, a.im), zb(b.re, b.im);
                acc += zb * std::conj(za);
                mag += std::abs(za) * std::abs(zb);
            }
            const double coh = mag > 0 ? std::abs(acc) / mag : 0.0;
            if (coh > 0.9)
                why = fmt("; the input phase at bin %u turns by %.1f degrees per period, coherently (%.2f): the period "
                          "does not match the input (wrong period, or the generator's and the acquisition's sample "
                          "clocks differ)",
                          bins.at(lb), std::arg(acc) * 180.0 / M_PI, coh);
        }
        throw Error(fmt("'%s': the input is not periodic with period %u: at its %zu excited line/input pairs %.0f%% of "
                        "the input power changes from period to period over %zu periods, and only %zu pairs show a "
                        "period mean beyond its standard error (chance alone gives %.1f; p = %.2g)%s",
                        sources.at(e).c_str(), P, ev.tested, 100 * ev.eta, K, ev.shown,
                        PERIODIC_BIN_ALPHA * (double)ev.tested, ev.p_value,
                        why.empty() ? ". For a sweep, chirp, noise or operating data use msid frf --method lpm on the "
                                      "recorded samples"
                                    : (why + ". Check the period of the excitation and the sample rates").c_str()));
    }
}

// An input that repeats with period P but carries no periodic component at the given lines: the lines are
// wrong, not the input. Throws naming the bins that hold the input's power (find_lines over the whole
// record) when the lines show no stable period mean (the test check_periodic_lines applies later, here on
// at most 4 of the checking window's K periods: a few FFTs of P per input on every record, and a weak
// right line that 4 periods miss is found among the bins below, so it is never called wrong) and none of
// them is among the bins found; otherwise returns, and a partly wrong list is left to the later checks.
// The share of the inputs' period-mean power (over the first `count` periods from `first`, every bin
// between DC and Nyquist) that lies at `bins`: 1 when there is none at all, or no bin lies there.
static double lines_power_share(const Record &r, uint32_t P, size_t first, size_t count, const std::vector<uint32_t> &bins)
{
    R2c f((int)P);
    const size_t M = (P + 1) / 2 - 1;
    std::vector<uint8_t> given(M + 1, 0);
    for (uint32_t b : bins)
        if (b >= 1 && b <= M) given[b] = 1;
    if (std::find(given.begin(), given.end(), 1) == given.end()) return 1.0;   // the line checks name them
    double at = 0, all = 0;
    for (uint32_t j = 0; j < r.nu; ++j) {
        const auto s = period_spectra(r, P, first, count, j, f);
        for (size_t k = 1; k <= M; ++k) {
            const double pw = std::norm(period_mean(s, count, k));
            all += pw;
            if (given[k]) at += pw;
        }
    }
    return all > 0 ? at / all : 1.0;
}

// Do the lines miss the input (the first min(K, 4) periods after skip)? Then check_lines_hold_input
// searches the whole record for the bins that hold its power.
// `share`: the lines' share of the input's periodic power when that decided, else -1.
static bool lines_miss_input(const Record &r, uint32_t P, uint32_t skip, size_t K, const std::vector<uint32_t> &bins,
                             PeriodicEvidence &ev, double &share)
{
    const size_t K4 = std::min<size_t>(K, 4);
    ev = periodic_evidence(r, P, skip, K4, bins);
    share = -1;
    if (ev.tested > 0 && !ev.periodic()) return true;
    // A noise-free input (a simulated record) repeats bit for bit: at bins it does not excite its period
    // mean is exactly zero (nothing to test) or a rounding residue that repeats too (a period mean
    // beyond a zero scatter). The share of the input's power at the lines tells those apart (1e-20: far
    // below any real excitation's dynamic range, far above rounding's 1e-32).
    if (K4 < 2) return false;
    share = lines_power_share(r, P, skip, K4, bins);
    return !(share > 1e-20);
}

static void check_lines_hold_input(const Record &r, uint32_t P, uint32_t skip, size_t K, const std::vector<uint32_t> &bins)
{
    if (bins.empty()) return;
    PeriodicEvidence ev;
    double share;
    if (!lines_miss_input(r, P, skip, K, bins, ev, share)) return;
    std::vector<uint32_t> found;
    std::string rep;   // find_lines' description of its test: not repeated in the message
    try {
        found = find_lines(std::vector<Record>{r}, P, skip, rep);
    } catch (const Error &) {
        return;   // no periodic component anywhere: the non-periodic input message says so
    }
    for (uint32_t b : bins)
        if (std::binary_search(found.begin(), found.end(), b)) return;
    const std::string why =
        share >= 0 ? fmt("they hold %.2g of its periodic power (a noise-free record)", share)
                   : fmt("%zu of %zu line/input pairs show a period mean beyond its standard error (chance alone gives "
                         "%.1f)", ev.shown, ev.tested, PERIODIC_BIN_ALPHA * (double)ev.tested);
    throw Error(fmt("'%s': the input is periodic with period %u, but not at the given lines: %s, and the input's "
                    "periodic power is at bins %s (%zu bins, the " MSID_OPT("lines") " auto test). Give those lines (" MSID_OPT("lines") " %s, or "
                    MSID_OPT("lines") " auto)",
                    r.path.c_str(), P, why.c_str(), format_bins(found).c_str(), found.size(), format_bins(found).c_str()));
}

// Does period p of r hold a NaN or infinity in an input (a candump log's lost samples are NaN rows,
// read_record_candump; every other reader refuses non-finite cells)?
static bool period_lost(const Record &r, uint32_t P, size_t p)
{
    const size_t C = r.nu + r.ny;
    const double *x = r.data() + p * P * C;
    for (size_t n = 0; n < P; ++n)
        for (size_t j = 0; j < r.nu; ++j)
            if (!std::isfinite(x[n * C + j])) return true;
    return false;
}

// The records with their lost periods left out (whole periods back to back), for the input checks: the
// FRF job rejects and counts those periods, and the checks must not read NaN. Empty when no record lost
// a sample (the records are checked as they are). A record read without its NaN/Inf scan
// (Record::finite_unchecked: a .npy read in place) loses no period: a non-finite cell in it is an error
// that its reader's scan names, block by block as the job pushes it. It is not scanned here either, so
// that its pages are read once, by the job, and given back behind it.
static std::vector<Record> without_lost_periods(const std::vector<Record> &recs, uint32_t P)
{
    bool any = false;
    for (const Record &r : recs)
        for (size_t p = 0; !r.finite_unchecked && p < r.n_rows / P && !any; ++p) any = period_lost(r, P, p);
    std::vector<Record> out;
    if (!any) return out;
    for (const Record &r : recs) {
        Record c;
        c.path = r.path;
        c.nu = r.nu;
        c.ny = r.ny;
        c.columns = r.columns;
        const size_t C = r.nu + r.ny;
        for (size_t p = 0; p < r.n_rows / P; ++p)
            if (r.finite_unchecked || !period_lost(r, P, p)) c.rows.insert(c.rows.end(), r.data() + p * P * C, r.data() + (p + 1) * P * C);
        c.n_rows = c.rows.size() / C;
        out.push_back(std::move(c));
    }
    return out;
}

void check_periodic_inputs(uint32_t P, uint32_t skip, const std::vector<uint32_t> &bins, const std::vector<Record> &all)
{
    const std::vector<Record> kept = without_lost_periods(all, P);
    const std::vector<Record> &recs = kept.empty() ? all : kept;
    // The time-domain part of every record's check (the non-periodic fraction at P and at the
    // neighbours P +- 1, 2: samples only, no FFTW) for two or more records on two threads, record
    // e on thread e % 2; the verdicts below in file order, the same as one record after the other.
    struct Cheap {
        size_t K = 0;
        double eta = 0, eta_n = 0;
        uint32_t Q = 0;
    };
    std::vector<Cheap> ch(recs.size());
    std::exception_ptr err;
    auto cheap = [&](size_t e0) {
        for (size_t e = e0; e < recs.size(); e += 2) {
            const Record &r = recs[e];
            Cheap &c = ch[e];
            c.K = window_periods(r, P, skip);
            if (c.K < 2) continue;
            c.eta = nonperiodic_fraction(r, P, skip, c.K);
            c.Q = c.eta > 1e-9 ? better_neighbour(r, P, skip, c.eta, c.eta_n) : 0;
            if (c.Q && !(c.eta_n < 0.5 * c.eta)) c.Q = 0;
        }
    };
    std::thread th;
    if (recs.size() >= 2 && std::thread::hardware_concurrency() >= 2) {
        try {
            th = std::thread([&] {
                try {
                    cheap(1);
                } catch (...) {   // no memory for a period's mean
                    err = std::current_exception();
                }
            });
        } catch (const std::system_error &) {
        }
    }
    if (th.joinable()) {
        try {
            cheap(0);
        } catch (...) {
            th.join();
            throw;
        }
        th.join();
        if (err) std::rethrow_exception(err);
    } else {
        cheap(0);
        cheap(1);
    }
    for (size_t e = 0; e < recs.size(); ++e) {
        const Record &r = recs[e];
        const size_t K = ch[e].K;
        if (K < 2) continue;   // too short: run_frf says so
        const double eta = ch[e].eta;
        double eta_n = ch[e].eta_n;
        uint32_t Q = ch[e].Q;
        // A noisy input (errors-in-variables, input SNR at or below 0 dB) changes mostly by its noise:
        // periodic when its period mean is stable within its standard error at enough bins.
        // Far off? Search the whole record first: an input with another period Q whose lines are in part
        // commensurate with P (period 256, --period 320: every 4th line is periodic in 320 too) shows
        // stable period means there, as a noisy periodic input does, but repeats far better with Q.
        PeriodicEvidence ev;
        if (!Q && eta > NONPERIODIC_FRACTION) {
            std::vector<Record> one{r};
            std::string rep;
            try {
                const uint32_t Q2 = find_period(one, rep);
                if (Q2 != P) {
                    const size_t K2 = window_periods(r, Q2, 0);
                    const double e2 = K2 >= 2 ? nonperiodic_fraction(r, Q2, 0, K2) : 1.0;
                    if (e2 < 0.5 * eta) Q = Q2, eta_n = e2;
                }
            } catch (const msidutil::Error &) {
            }
        }
        if (!Q && eta > NONPERIODIC_FRACTION) {
            ev = periodic_evidence(r, P, skip, K, bins);
            if (ev.periodic()) continue;
        }
        if (Q) {
            // what the wrong period does to the estimate, when it shows (nothing to say: no clause)
            const std::string sym = wrong_period_symptoms(r, P, skip, bins);
            throw Error(fmt("'%s': " MSID_OPT("period") " %u does not fit the input: it repeats every %u samples (the part of the input "
                            "that changes from period to period is %.2g%% of its power with %u, %.2g%% with %u)%s. Use "
                            MSID_OPT("period") " %u",
                            r.path.c_str(), P, Q, 100 * eta_n, Q, 100 * eta, P,
                            sym.empty() ? "" : fmt("; with %u, %s", P, sym.c_str()).c_str(), Q));
        }
        if (eta > NONPERIODIC_FRACTION) {
            check_lines_hold_input(r, P, skip, K, bins);   // a noisy periodic input analysed at the wrong lines
            throw Error(fmt("'%s': the input is not periodic with period %u: %.0f%% of its power changes from period to "
                            "period (its spectrum differs between periods), %zu of %zu %s show a period mean beyond "
                            "its standard error (chance alone gives %.1f; a periodic input with noise shows many), and "
                            "it repeats with no other period either. For a sweep, chirp, noise or operating data use "
                            MSID_OPT("method") " lpm (any excitation)",
                            r.path.c_str(), P, 100 * eta, ev.shown, ev.tested,
                            bins.empty() ? "bin/input pairs" : "excited line/input pairs",
                            PERIODIC_BIN_ALPHA * (double)ev.tested));
        }
        check_lines_hold_input(r, P, skip, K, bins);
    }
}

size_t input_check_rows(uint32_t P, uint32_t skip)
{
    // window_periods() periods after the skipped ones, at P and at the neighbours up to P + 2, and a
    // period more
    const size_t want = std::max<size_t>(4, ((size_t)1 << 14) / P + 1);
    return ((size_t)skip + want + 1) * ((size_t)P + 2);
}

bool input_check_needs_whole(uint32_t P, uint32_t skip, const std::vector<uint32_t> &bins, const Record &r)
{
    const size_t K = window_periods(r, P, skip);
    if (K < 2) return false;
    const double eta = nonperiodic_fraction(r, P, skip, K);
    double eta_n = 0;
    uint32_t Q = eta > 1e-9 ? better_neighbour(r, P, skip, eta, eta_n) : 0;
    if (Q && !(eta_n < 0.5 * eta)) Q = 0;
    if (!Q && eta > NONPERIODIC_FRACTION) return true;   // the whole record is searched for its period
    if (Q || bins.empty()) return false;
    // check_lines_hold_input(): lines without the input's power are named from the whole record's
    PeriodicEvidence ev;
    double share;
    return lines_miss_input(r, P, skip, K, bins, ev, share);
}

// The inputs' autocorrelation over the first N rows of r at lags 0 .. N / 2, summed over the input
// channels: the power spectrum's inverse transform (length nf >= N + N / 2, so that the circular
// correlation has no wrap-around at those lags), in place in one buffer of nf + 2 doubles (and
// nf / 2 + 1 more for two or more inputs). Freed by the caller (fftw_free).
static double *input_autocorrelation(const Record &r, size_t N, size_t nf)
{
    const size_t C = r.nu + r.ny, nc = nf / 2 + 1;
    fftw_planner_ready();
    double *buf = fftw_alloc_real(2 * nc);
    if (!buf) throw Error(fmt("out of memory for " MSID_OPT("period") " auto's FFT of length %zu", nf));
    fftw_complex *spec = reinterpret_cast<fftw_complex *>(buf);
    // one plan at a time: a transform of this length has tens of MB of twiddle factors
    const fftw_plan fw = fftw_plan_dft_r2c_1d((int)nf, buf, spec, FFTW_ESTIMATE);
    std::vector<double> pw(r.nu > 1 ? nc : 0, 0.0);
    for (uint32_t j = 0; j < r.nu; ++j) {
        double mean = 0;
        for (size_t n = 0; n < N; ++n) mean += r.data()[n * C + j];
        mean /= (double)N;
        for (size_t n = 0; n < nf; ++n) buf[n] = n < N ? r.data()[n * C + j] - mean : 0.0;
        fftw_execute(fw);
        for (size_t k = 0; k < nc; ++k) {
            const double a = spec[k][0] * spec[k][0] + spec[k][1] * spec[k][1];
            if (r.nu > 1) pw[k] += a;
            else spec[k][0] = a, spec[k][1] = 0;
        }
    }
    fftw_destroy_plan(fw);
    if (r.nu > 1)
        for (size_t k = 0; k < nc; ++k) spec[k][0] = pw[k], spec[k][1] = 0;
    const fftw_plan bw = fftw_plan_dft_c2r_1d((int)nf, spec, buf, FFTW_ESTIMATE);   // ESTIMATE: spec kept
    fftw_execute(bw);
    fftw_destroy_plan(bw);
    return buf;
}

uint32_t find_period(const std::vector<Record> &recs, std::string &report, const char *signal)
{
    const Record &r = recs.at(0);
    // the search window: every step below reads only these rows, so a record streamed from its file
    // (whose first rows are all there is yet) and the record read whole find the same period
    const size_t N = std::min(r.n_rows, PERIOD_SEARCH_ROWS);
    if (N < 2 * MSID_MIN_PERIOD)
        throw Error(fmt("'%s': %zu samples are too few to find a period (" MSID_OPT("period") " auto)", r.path.c_str(), r.n_rows));
    for (size_t n = 0; n < N; ++n)   // lost samples (a candump log's NaN rows): no autocorrelation
        for (size_t j = 0; j < r.nu; ++j)
            if (!std::isfinite(r.data()[n * (r.nu + r.ny) + j]))
                throw Error(fmt("'%s' lost samples (row %zu): " MSID_OPT("period") " auto needs a record without; give " MSID_OPT("period"),
                                r.path.c_str(), n + 1));
    // The search reads lags up to N / 2 only, so N + N / 2 points hold them without wrap-around
    // (2 N would hold every lag): 2^k or 3 * 2^k, whichever is shorter, for a fast transform. At the
    // search's 2^21 rows that is 3 * 2^20 points, whose buffer and FFTW twiddles take about 20 MB less.
    size_t nf = 1;
    while (nf < N + N / 2) nf <<= 1;
    if (nf % 4 == 0 && nf / 4 * 3 >= N + N / 2) nf = nf / 4 * 3;
    // the (biased) autocorrelation
    const std::unique_ptr<double, void (*)(void *)> acbuf(input_autocorrelation(r, N, nf), fftw_free);
    const double *ac = acbuf.get();
    if (!(ac[0] > 0))
        throw Error(fmt("'%s': the %ss are constant: no period to find (" MSID_OPT("period") " auto)", r.path.c_str(), signal));
    // rho(tau): unbiased autocorrelation normalised by the variance
    auto rho = [&](size_t t) { return ac[t] / (double)(N - t) / (ac[0] / (double)N); };
    size_t t0 = 1;
    while (t0 <= N / 2 && rho(t0) >= 0.5) ++t0;   // past the main lobe
    const size_t lo = std::max<size_t>(t0, MSID_MIN_PERIOD), hi = N / 2;
    double rmax = -2;
    for (size_t t = lo; t <= hi; ++t) rmax = std::max(rmax, rho(t));
    uint32_t P = 0;
    if (rmax > 0) {
        size_t t = lo;
        while (t <= hi && rho(t) < 0.95 * rmax) ++t;
        while (t + 1 <= hi && rho(t + 1) >= rho(t)) ++t;   // climb to the local peak
        P = (uint32_t)std::min<size_t>(t, MSID_MAX_PERIOD);
    }
    double eta = 1.0;
    // Refine by the exact non-periodic fraction around the peak. A peak at a fraction of the
    // period (lines all multiples of 3 repeat almost every P/3 samples) is followed to its
    // multiples 2 P0, 3 P0, ... until one repeats (eta at most 0.1) or N/2 is reached. The
    // neighbours are compared by their noise-normalised share eta K/(K-1) (K repetitions in the N
    // rows): a record of exactly K periods holds only K - 1 of P + 1, and over fewer repetitions a
    // noisy input's eta is smaller ((K-1)/K of its noise share), which would prefer P + 1 to P where
    // the one-sample mismatch is small (an input of low frequencies).
    // The refinement walks: from the lag, to the best of its +-2 neighbours while that is better (at
    // most REFINE_MOVES moves), as the autocorrelation of a signal of low frequencies is flat around
    // its period and normalised per lag over windows of unequal power, so its peak can lie several
    // samples off the period.
    constexpr int REFINE_MOVES = 64;
    const uint32_t P0 = P;
    std::map<int64_t, std::pair<double, double>> seen;   // lag -> (eta, eta K/(K-1))
    auto share = [&](int64_t Q, double &e, double &e_norm) {
        if (Q < (int64_t)MSID_MIN_PERIOD || Q > (int64_t)MSID_MAX_PERIOD || (size_t)Q * 2 > N) return false;
        auto it = seen.find(Q);
        if (it == seen.end()) {
            const size_t K = N / (size_t)Q;
            const double x = nonperiodic_fraction(r, (uint32_t)Q, 0, K);
            it = seen.emplace(Q, std::make_pair(x, x * (double)K / (double)(K - 1))).first;
        }
        e = it->second.first;
        e_norm = it->second.second;
        return true;
    };
    for (uint32_t mult = 1; P0 && (size_t)P0 * mult * 2 <= N + 4; ++mult) {
        uint32_t bestP = 0;
        double best = 1.0;
        int64_t centre = (int64_t)P0 * mult;
        for (int move = 0; move < REFINE_MOVES; ++move) {
            int64_t at = -1;
            double e_at = 1.0, norm_at = HUGE_VAL, e, e_norm;
            for (int d = -2; d <= 2; ++d)
                if (share(centre + d, e, e_norm) && e_norm < norm_at) { at = centre + d; e_at = e; norm_at = e_norm; }
            if (at < 0) break;
            bestP = (uint32_t)at;
            best = e_at;
            if (at == centre) break;
            centre = at;
        }
        if (bestP && (mult == 1 || best < 0.5 * eta)) { eta = best; P = bestP; }   // clearly better only
        if (eta <= 0.1 || mult >= 16) break;
    }
    // A noisy input repeats at every multiple of its period with about the same autocorrelation,
    // so the peak may sit at a multiple k P. The smallest divisor P/k whose noise-normalised
    // non-periodic share eta K/(K-1) (K repetitions) is no larger than the peak's (within three
    // relative standard errors, 3/sqrt(N)) is the period: a divisor that is no period adds the
    // signal's mismatch.
    if (P && eta > 0.1) {
        auto norm = [&](uint32_t Q, double e) { const double K = (double)(N / Q); return e * K / (K - 1); };
        const double ref = norm(P, eta);
        for (uint32_t k = 16; k >= 2; --k) {
            if (P % k || P / k < MSID_MIN_PERIOD) continue;
            const uint32_t Q = P / k;
            const double e = nonperiodic_fraction(r, Q, 0, N / Q);
            if (norm(Q, e) <= ref * (1 + 3 / std::sqrt((double)N)) + 1e-12) { P = Q; eta = e; break; }
        }
    }
    // A non-periodic input gives E eta = (K-1)/K over K repetitions (1/2 for K = 2, where the best of
    // many candidate lags falls below 1/2 by chance): the threshold, 0.5 (K-1)/K, scales with it.
    const double level = P ? NONPERIODIC_FRACTION * (double)(N / P - 1) / (double)(N / P) : 0.0;
    bool noisy = false;
    if (P && eta > level) {   // a noisy periodic input: its period mean stands out of the noise
        const size_t K = std::min<size_t>(N / P, window_periods(r, P, 0));
        noisy = periodic_evidence(r, P, 0, K, {}).periodic();
    }
    if (!P || (eta > level && !noisy))
        throw Error(fmt("'%s': the %s does not repeat: no period with at least 2 repetitions leaves less than %.0f%% "
                        "of the %s power changing from period to period (half of what a non-periodic %s "
                        "gives)%s. Give " MSID_OPT("period") ", or for a sweep, chirp, noise or operating data use " MSID_OPT("method") " lpm",
                        r.path.c_str(), signal, 100 * (P ? level : NONPERIODIC_FRACTION), signal, signal,
                        P ? fmt(" (best: %u samples, %.0f%% changing)", P, 100 * eta).c_str() : ""));
    report = fmt("period %u samples (found from the %s's repetition: %.2g%% of the %s power changes from "
                 "period to period%s, %zu whole periods in %s'%s')",
                 P, signal, 100 * eta, signal, noisy ? ", mostly noise: its period mean stands out of it" : "", N / P,
                 N < PERIOD_SEARCH_ROWS ? "" : fmt("the first %zu rows of ", N).c_str(), r.path.c_str());
    return P;
}

struct LineScan::Impl {
    uint32_t P, nu;
    size_t M, K = 0;
    std::string source;
    R2c f;
    std::vector<std::complex<double>> mean;   // nu x M: the running period mean per input and bin
    std::vector<double> m2;                   // nu x M: the sum of |spectrum - mean|^2 so far
    Impl(uint32_t P_, uint32_t nu_, std::string src)
        : P(P_), nu(nu_), M((P_ + 1) / 2 - 1), source(std::move(src)), f((int)P_), mean((size_t)nu_ * M), m2((size_t)nu_ * M)
    {
    }
};

LineScan::LineScan(uint32_t P, uint32_t nu, std::string source) : p_(std::make_unique<Impl>(P, nu, std::move(source))) {}
LineScan::~LineScan() = default;
LineScan::LineScan(LineScan &&) noexcept = default;
LineScan &LineScan::operator=(LineScan &&) noexcept = default;
size_t LineScan::periods() const { return p_->K; }
const std::string &LineScan::source() const { return p_->source; }

void LineScan::push(const double *rows, size_t C)
{
    Impl &s = *p_;
    const double c = (double)++s.K;
    for (uint32_t j = 0; j < s.nu; ++j) {
        for (uint32_t n = 0; n < s.P; ++n) s.f.in[n] = rows[(size_t)n * C + j];
        s.f.run();
        std::complex<double> *mu = s.mean.data() + (size_t)j * s.M;
        double *m2 = s.m2.data() + (size_t)j * s.M;
        for (size_t k = 0; k < s.M; ++k) {
            const std::complex<double> x = s.f.at(k + 1), d = x - mu[k];
            mu[k] += d / c;
            const std::complex<double> e = x - mu[k];
            m2[k] += d.real() * e.real() + d.imag() * e.imag();
        }
    }
}

void check_lines_period(uint32_t P)
{
    if (P < 3) throw Error(fmt("period %u has no bins between DC and Nyquist for " MSID_OPT("lines") " auto", P));
}

std::vector<uint32_t> lines_from_scans(const std::vector<LineScan> &scans, uint32_t P, uint32_t skip,
                                       std::string &report, std::vector<double> *p_min)
{
    check_lines_period(P);
    const size_t M = (P + 1) / 2 - 1;
    size_t J = 0;
    for (const LineScan &sc : scans) J += sc.p_->nu;
    const double level = LINES_AUTO_ALPHA / ((double)M * (double)J);
    std::vector<uint8_t> exc(M + 1, 0);
    if (p_min) p_min->assign(M, 1.0);
    size_t Kmin = SIZE_MAX;
    for (const LineScan &sc : scans) {
        const LineScan::Impl &s = *sc.p_;
        if (s.K < 2)
            throw Error(fmt("'%s': " MSID_OPT("lines") " auto needs at least 2 whole periods of %u samples after skipping %u",
                            s.source.c_str(), P, skip));
        Kmin = std::min(Kmin, s.K);
        const double n = (double)(s.K - 1);
        for (uint32_t j = 0; j < s.nu; ++j) {
            const std::complex<double> *mu = s.mean.data() + (size_t)j * M;
            const double *m2 = s.m2.data() + (size_t)j * M;
            double mx = 0;
            for (size_t k = 0; k < M; ++k) mx = std::max(mx, std::norm(mu[k]));
            for (size_t k = 0; k < M; ++k) {
                const double a2 = std::norm(mu[k]), v = m2[k] / n;
                if (!(a2 > 1e-20 * mx)) continue;
                // P(F(2, 2(K-1)) > F) = (1 + F/(K-1))^-(K-1)
                const double F = v > 0 ? (double)s.K * a2 / v : HUGE_VAL;
                const double pv = std::isinf(F) ? 0.0 : std::exp(-n * std::log1p(F / n));
                if (pv < level) exc[k + 1] = 1;
                if (p_min) (*p_min)[k] = std::min((*p_min)[k], pv);
            }
        }
    }
    std::vector<uint32_t> bins;
    for (size_t k = 1; k <= M; ++k) if (exc[k]) bins.push_back((uint32_t)k);
    if (bins.empty())
        throw Error(fmt(MSID_OPT("lines") " auto: no bin of period %u carries a periodic input component (F test over %zu periods, "
                        "family-wise false-alarm probability %g): is the input periodic with this period?",
                        P, Kmin, LINES_AUTO_ALPHA));
    report = fmt("%zu excited bins of %zu (F test of the period mean against the period-to-period variation over %zu "
                 "periods, each bin at %.2g so that a record without excitation reports any bin with probability <= %g)",
                 bins.size(), M, Kmin, level, LINES_AUTO_ALPHA);
    return bins;
}

std::vector<uint32_t> find_lines(const std::vector<Record> &recs, uint32_t P, uint32_t skip, std::string &report,
                                 std::vector<double> *p_min)
{
    check_lines_period(P);
    std::vector<LineScan> scans;
    for (const auto &r : recs) {
        const size_t Kall = r.n_rows / P, C = r.nu + r.ny;
        scans.emplace_back(P, r.nu, r.path);
        if (Kall < (size_t)skip + 2) break;   // lines_from_scans names it
        for (size_t p = skip; p < Kall; ++p)
            if (!period_lost(r, P, p)) scans.back().push(r.data() + p * P * C, C);   // lost samples: rejected
    }
    return lines_from_scans(scans, P, skip, report, p_min);
}

UndecidedLines undecided_lines(const std::vector<uint32_t> &found, const std::vector<double> &p_min)
{
    UndecidedLines u;
    if (found.size() < 2) return u;
    uint32_t g = 0;
    for (size_t i = 1; i < found.size(); ++i) g = std::gcd(g, found[i] - found[0]);
    u.step = g;
    u.first = found.front();
    u.last = found.back();
    size_t next = 0;
    for (uint32_t k = u.first; k <= u.last; k += g) {
        while (next < found.size() && found[next] < k) ++next;
        if (next < found.size() && found[next] == k) continue;
        if (k - 1 < p_min.size() && p_min[k - 1] < UNDECIDED_ALPHA) u.bins.push_back(k);
        else ++u.silent;
    }
    return u;
}

std::string format_bins(const std::vector<uint32_t> &b)
{
    std::string s;
    for (size_t i = 0; i < b.size();) {
        size_t j = i + 1;
        if (j < b.size()) {
            const uint32_t st = b[j] - b[i];
            while (j + 1 < b.size() && b[j + 1] - b[j] == st) ++j;
            if (j - i >= 2) {   // a run of at least 3
                if (!s.empty()) s += ',';
                s += st == 1 ? fmt("%u:%u", b[i], b[j]) : fmt("%u:%u:%u", b[i], st, b[j]);
                i = j + 1;
                continue;
            }
        }
        if (!s.empty()) s += ',';
        s += std::to_string(b[i]);
        ++i;
    }
    return s;
}

}  // namespace msidjob
