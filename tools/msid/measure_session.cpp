// What every protocol session of `msid measure` shares (measure.hpp): stop requests, the
// experiment loop with live progress, the FRF of what was measured, and the protocol commands'
// write path. The Modbus session is measure_modbus.cpp, the CAN session cmd_can.cpp.
#include "measure.hpp"
#include "host_libs.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>

namespace msidcli {

// ---- stop requests -------------------------------------------------------------

static volatile sig_atomic_t g_stop_signal = 0;

static void on_stop_signal(int sig) { g_stop_signal = sig; }

StopOnSignal::StopOnSignal()
{
    g_stop_signal = 0;
    struct sigaction sa{};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;   // no SA_RESTART: a sleep or a blocking read returns at once
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
}

StopOnSignal::~StopOnSignal()
{
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
}

bool measure_stop_requested() { return g_stop_signal != 0; }
int measure_stop_signal() { return (int)g_stop_signal; }

void mark_completeness(Json &doc, bool complete, uint32_t experiments_done, uint32_t experiments,
                       const std::string &reason)
{
    doc["complete"] = complete;
    doc["experiments_completed"] = experiments_done;
    doc["experiments_planned"] = experiments;
    if (!complete) doc["incomplete_reason"] = reason;
}

// ---- the experiment loop -----------------------------------------------------------

static double now_s()
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

// Mean over excited lines and outputs of the per-period output SNR |mean Y|^2 / var Y (dB).
static double running_snr_db(const msid_pstats *ps, uint32_t nu, uint32_t ny, uint32_t L)
{
    if (!ps) return NAN;
    const uint32_t K = msid_pstats_count(ps), q = nu + ny;
    if (K < 2) return NAN;
    double sum = 0;
    uint32_t n = 0;
    for (uint32_t l = 0; l < L; ++l) {
        const msid_cplx *mu = msid_pstats_mean(ps, l), *S = msid_pstats_scatter(ps, l);
        for (uint32_t i = nu; i < q; ++i) {
            const double var = S[(size_t)i * q + i].re / (K - 1), p = mu[i].re * mu[i].re + mu[i].im * mu[i].im;
            if (var > 0 && p > 0) { sum += 10 * std::log10(p / var); ++n; }
        }
    }
    return n ? sum / n : NAN;
}

LoopResult run_experiments(ExperimentRunner &r, const msid_meas *ms, const MeasurePlan &P, Progress &pg)
{
    const msid_design &d = P.D->d;
    const uint32_t m = d.n_experiments, nu = d.n_inputs, ny = ms->n_outputs;
    const uint64_t total = (uint64_t)P.sf.periods * d.period * m;
    const double t_start = now_s();
    auto state = [&](uint32_t e) {
        ProgressState s;
        s.exp = e + 1;
        s.n_exp = m;
        s.periods_target = P.sf.periods;
        for (uint32_t x = 0; x <= e && x < m; ++x) {
            const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(ms, x));
            if (x == e) s.periods = k.offered;
            s.periods_total += k.offered;
            s.rejected += k.gap + k.nonfinite + k.transient_dropped;
        }
        s.lost = r.lost();
        s.link_errors = r.link_errors();
        s.snr_db = running_snr_db(msid_meas_stats(ms, e), nu, ny, (uint32_t)P.rq.bins.size());
        const uint64_t got = r.samples() + r.lost();
        const double el = now_s() - t_start;
        if (got > 0 && el > 0) s.eta_s = el * (double)(total - std::min(total, got)) / (double)got;
        return s;
    };
    LoopResult L;
    for (uint32_t e = 0; e < m; ++e) {
        if (measure_stop_requested()) { L.stopped = true; break; }
        pg.update(state(e));
        const bool ended = r.run(e, P.sf.periods, [&] {
            pg.update(state(e));
            return measure_stop_requested();
        });
        pg.update(state(e));
        if (!ended) { L.stopped = true; break; }
        ++L.done;
        pg.note(fmt("experiment %u/%u done", e + 1, m));
    }
    pg.done();
    return L;
}

MeasureResult finish_measure(FrfJob &job, const MeasurePlan &P, const LoopResult &L, const std::string &src,
                             std::vector<std::string> notes)
{
    const uint32_t m = P.D->d.n_experiments;
    const msid_meas *ms = job.meas();
    std::vector<ExpSource> sources;
    std::string short_of;
    uint64_t periods = 0;
    for (uint32_t e = 0; e < m; ++e) {
        const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(ms, e));
        sources.push_back({fmt("%s experiment %u", src.c_str(), e + 1), ms->samples[e], k.offered,
                           msid_meas_leftover(ms, e)});
        periods += k.offered;
        if (k.used < 2 && short_of.empty()) short_of = fmt("experiment %u has %u usable period(s)", e + 1, k.used);
    }
    const int sig = measure_stop_signal() ? measure_stop_signal() : SIGINT;
    const std::string why =
        L.stopped ? fmt("stopped by signal %d during experiment %u of %u", sig, std::min(L.done + 1, m), m) : "";
    if (L.stopped && !short_of.empty())
        throw Error(fmt("%s after %llu complete period(s): %s, and the FRF needs at least 2 of every experiment "
                        "(%u): nothing written",
                        why.c_str(), (unsigned long long)periods, short_of.c_str(), m),
                    128 + sig);
    if (L.stopped) notes.push_back(why + ": the FRF uses the complete periods acquired before the stop");
    MeasureResult R;
    R.o = job.finish(sources, notes);
    R.complete = !L.stopped;
    mark_completeness(R.o.doc, R.complete, L.done, m, why);
    return R;
}

int write_measure_result(MeasureResult &R, const std::string &out, const std::string &cmd)
{
    Json doc = R.o.doc;
    if (R.complete)
        for (const char *k : {"complete", "experiments_completed", "experiments_planned"}) doc.erase(k);
    write_json_file(out, doc);
    for (const auto &n : R.o.notes) std::fprintf(stderr, "msid %s: note: %s\n", cmd.c_str(), n.c_str());
    std::printf("wrote %s: %s\n", out.c_str(), R.summary.c_str());
    if (R.complete) return 0;
    std::fprintf(stderr, "msid %s: interrupted: %s is the FRF of the complete periods (\"complete\": false)\n",
                 cmd.c_str(), out.c_str());
    return 128 + (measure_stop_signal() ? measure_stop_signal() : SIGINT);
}

}  // namespace msidcli
