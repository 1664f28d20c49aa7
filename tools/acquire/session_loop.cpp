// What every protocol session shares (session_loop.hpp): the experiment loop with progress and
// stop requests, the FRF of what was measured, and the checks of a plan. The Modbus session is
// modbus_session.cpp, the CAN session can_session.cpp.
#include "session_loop.hpp"

#include <algorithm>
#include <cmath>
#include <csignal>
#include <ctime>

namespace msidacq {

using msidutil::fmt;

void mark_completeness(Json &doc, bool complete, uint32_t experiments_done, uint32_t experiments,
                       const std::string &reason)
{
    doc["complete"] = complete;
    doc["experiments_completed"] = experiments_done;
    doc["experiments_planned"] = experiments;
    if (!complete) doc["incomplete_reason"] = reason;
}

void check_plan(MeasurePlan &P, const char *periods_name, const char *skip_name)
{
    if (P.sf.periods < 2 || P.sf.periods > MSID_PARAMS_MAX_PERIODS)
        throw UsageError(fmt("%s must be 2..%u", periods_name, MSID_PARAMS_MAX_PERIODS));
    if ((uint64_t)P.rq.skip + 2 > P.sf.periods)   // 64-bit: a huge skip must not wrap
        throw UsageError(fmt("%s %u with %s %u leaves fewer than 2 periods", periods_name, P.sf.periods, skip_name,
                             P.rq.skip));
    if (!(P.sf.scale > 0 && std::isfinite(P.sf.scale))) throw UsageError("the scale must be positive");
    if (!(P.timeout > 0 && P.timeout <= 86400)) throw UsageError("the timeout must be positive (at most 86400 s)");
    if (P.sf.rate > 0 && !P.D->d.is_ct) P.rq.fs = P.sf.rate;
}

void check_input_resolution(const MeasurePlan &P, bool integer)
{
    if (!integer) return;
    const msid_design &d = P.D->d;
    for (uint32_t i = 0; i < d.n_inputs; ++i) {
        double peak = 0;
        for (uint32_t l = 0; l < d.n_lines; ++l) peak += std::fabs(d.amp[(size_t)i * d.n_lines + l]);
        if (peak < 0.5 * (double)P.sf.scale)
            throw UsageError(fmt(MSID_OPT("scale") " %g (the value of one step of the samples' integers) is more than twice the "
                                 "largest sample of input %u (at most %.3g): the input would be sent as zeros and its "
                                 "lines not excited; a scale of at most %.3g keeps 10 bits of it",
                                 (double)P.sf.scale, i + 1, peak, peak / 1024.0));
    }
}

MeasureResult measure_device(const DeviceUri &dev, const PlanFn &plan, Control &ctl)
{
    if (dev.kind == DeviceUri::CANOPEN)
        throw UsageError("a CANopen node (" + dev.text + ") runs no msid firmware: describe it and give " MSID_OPT("map") " "
                         "DEVICE.toml " MSID_OPT("rate") " HZ (docs/devices.md, CANopen drives)");
    return dev.kind == DeviceUri::CAN ? measure_can(can_link_from_uri(dev), plan, ctl)
                                      : measure_modbus(modbus_link_from_uri(dev), plan, ctl);
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

LoopResult run_experiments(ExperimentRunner &r, const msid_meas *ms, const MeasurePlan &P, Control &ctl)
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
        r.timing(s);
        s.snr_db = running_snr_db(msid_meas_stats(ms, e), nu, ny, (uint32_t)P.rq.bins.size());
        const uint64_t got = r.samples() + r.lost();
        const double el = now_s() - t_start;
        if (got > 0 && el > 0) s.eta_s = el * (double)(total - std::min(total, got)) / (double)got;
        return s;
    };
    LoopResult L;
    for (uint32_t e = 0; e < m; ++e) {
        if ((L.reason = ctl.stop()) != 0) { L.stopped = true; break; }
        ctl.update(state(e));
        const bool ended = r.run(e, P.sf.periods, [&] {
            ctl.update(state(e));
            return (L.reason = ctl.stop()) != 0;
        });
        ctl.update(state(e));
        if (!ended) { L.stopped = true; break; }
        ++L.done;
        ctl.note(fmt("experiment %u/%u done", e + 1, m));
    }
    ctl.done();
    return L;
}

MeasureResult finish_measure(msidjob::FrfJob &job, const MeasurePlan &P, const LoopResult &L, const std::string &src,
                             std::vector<std::string> notes)
{
    const uint32_t m = P.D->d.n_experiments;
    const msid_meas *ms = job.meas();
    std::vector<msidjob::ExpSource> sources;
    std::string short_of;
    uint64_t periods = 0;
    for (uint32_t e = 0; e < m; ++e) {
        const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(ms, e));
        sources.push_back({fmt("%s experiment %u", src.c_str(), e + 1), ms->samples[e], k.offered,
                           msid_meas_leftover(ms, e)});
        periods += k.offered;
        if (k.used < 2 && short_of.empty()) short_of = fmt("experiment %u has %u usable period(s)", e + 1, k.used);
    }
    const int sig = L.reason;
    const std::string why =
        L.stopped ? fmt("stopped by signal %d during experiment %u of %u", sig, std::min(L.done + 1, m), m) : "";
    if (L.stopped && !short_of.empty())
        throw Error(fmt("%s after %llu complete period(s): %s, and the FRF needs at least 2 of every experiment "
                        "(%u): no FRF exists",
                        why.c_str(), (unsigned long long)periods, short_of.c_str(), m),
                    128 + sig);
    if (L.stopped) notes.push_back(why + ": the FRF uses the complete periods acquired before the stop");
    MeasureResult R;
    R.o = job.finish(sources, notes);
    R.complete = !L.stopped;
    R.stop_reason = L.reason;
    mark_completeness(R.o.tail(), R.complete, L.done, m, why);
    return R;
}

void set_summary(MeasureResult &R, const MeasurePlan &P, uint32_t ny, uint32_t nu, uint32_t done,
                 const std::string &link, uint64_t samples, uint64_t lost)
{
    const uint32_t m = P.D->d.n_experiments;
    R.summary = fmt("%zu lines, %u x %u, %u%s experiment(s) over %s, %llu samples, %llu missing, "
                    "%llu periods used, %llu rejected%s",
                    P.rq.bins.size(), ny, nu, done, R.complete ? "" : fmt(" of %u", m).c_str(), link.c_str(),
                    (unsigned long long)samples, (unsigned long long)lost,
                    (unsigned long long)R.o.periods_used(),
                    (unsigned long long)R.o.periods_rejected(),
                    R.complete ? "" : " (INCOMPLETE: stopped)");
}

}  // namespace msidacq
