// The tick loop's timing in the FRF file, and the bias it implies for a commanded input (timing_report.hpp).
#include "timing_report.hpp"

#include <algorithm>
#include <cmath>
#include <complex>

namespace msidacq {

using msidutil::fmt;

TickTiming tick_timing(const msid_hx &h, double cycle_hz)
{
    const msid_hx_timing &T = h.tim;
    TickTiming t;
    t.apply_mean = 1e-9 * T.apply.mean;
    t.apply_var = 1e-18 * (msid_tstats_sd(&T.apply) * msid_tstats_sd(&T.apply));
    t.sample_mean = 1e-9 * T.sample.mean;
    t.sample_var = 1e-18 * (msid_tstats_sd(&T.sample) * msid_tstats_sd(&T.sample));
    if (T.n_half) {
        t.half_write_sq = 1e-18 * T.half_write_sq / (double)T.n_half;
        t.half_read_sq = 1e-18 * T.half_read_sq / (double)T.n_half;
    }
    if (std::isfinite(cycle_hz) && cycle_hz > 0 && std::fabs(cycle_hz / h.cfg.tick.rate_hz - 1) > 0.01)
        t.cycle_s = 1.0 / cycle_hz;
    return t;
}

LineBias line_bias(const TickTiming &t, double w)
{
    LineBias b;
    // the instants' own spread plus the uniform uncertainty within each transaction
    const double var = t.apply_var + t.sample_var + (t.half_write_sq + t.half_read_sq) / 3.0 +
                       2.0 * t.cycle_s * t.cycle_s / 12.0;
    b.gain = std::exp(-0.5 * w * w * var);
    b.phase = w * (t.sample_mean - t.apply_mean);
    const double half = std::sqrt(t.half_write_sq) + std::sqrt(t.half_read_sq) + t.cycle_s;
    b.bound = std::abs(1.0 - b.gain * std::exp(std::complex<double>(0, b.phase))) + w * half;
    return b;
}

static Json quantiles_s(const msid_tstats &s)
{
    Json j;
    j["median"] = 1e-9 * msid_tstats_quantile(&s, 0.5);
    j["p99"] = 1e-9 * msid_tstats_quantile(&s, 0.99);
    j["max"] = s.n ? 1e-9 * (double)s.max : 0.0;
    j["mean"] = 1e-9 * s.mean;
    j["sd"] = 1e-9 * msid_tstats_sd(&s);
    j["count"] = s.n;
    return j;
}

Json timing_json(const msid_hx &h, double rate_hz, const std::string &exchange, double counter_nominal_hz)
{
    const msid_tick &k = h.tick;
    Json j;
    j["clock"] = h.cfg.follow_counter ? "device" : "host";
    j["rate_hz"] = rate_hz;
    // achieved: ticks run and missed over the tick clock's span (of the last experiment's clock), as measured
    // by the deadlines; the deadlines themselves never drift
    j["ticks"] = h.cnt.ticks;
    j["ticks_missed"] = k.missed;
    j["ticks_late"] = k.late;
    j["late_threshold_s"] = 1e-9 * (double)k.cfg.late_ns;
    j["measured_ticks"] = h.cnt.measured_ticks;
    j["measured_ticks_missed"] = h.cnt.missed;
    j["exchanges_failed"] = h.cnt.failed;
    j["exchanges_failed_outside_measured_periods"] = h.cnt.failed_other;
    j["rate_achieved_hz"] = rate_hz * (h.cnt.ticks + k.missed ? (double)h.cnt.ticks / (double)(h.cnt.ticks + k.missed)
                                                               : 1.0);
    j["lateness_s"] = quantiles_s(k.lateness);
    j["wake_lateness_s"] = quantiles_s(k.wake);   // the ticks the clock slept for: its own precision
    j["cpu_s"] = 1e-9 * (double)k.cpu_ns;          // the tick loop's thread, set-up and estimation left out
    j["cpu_per_tick_s"] = h.cnt.ticks ? 1e-9 * (double)k.cpu_ns / (double)h.cnt.ticks : 0.0;
    j["cpu_user_per_tick_s"] = h.cnt.ticks ? 1e-9 * (double)k.cpu_user_ns / (double)h.cnt.ticks : 0.0;
    j["round_trip_s"] = quantiles_s(h.tim.rtt);
    j["write_instant_s"] = quantiles_s(h.tim.apply);
    j["read_instant_s"] = quantiles_s(h.tim.sample);
    j["exchange"] = exchange;
    j["scheduling"] = k.sched;
    j["sched_fifo"] = k.fifo != 0;
    j["memory_locked"] = k.locked != 0;
    const double cr = msid_hx_counter_rate(&h);
    if (std::isfinite(cr) && counter_nominal_hz > 0) {
        j["device_clock_offset_ppm"] = (cr / counter_nominal_hz - 1.0) * 1e6;
        // a count read once a tick resolves the clock to about one count over the span of the reads
        const double span = h.tim.cs_n > 1 ? (double)h.tick.ticks / h.cfg.tick.rate_hz : 0;
        if (span > 0) j["device_clock_offset_resolution_ppm"] = 1e6 / (counter_nominal_hz * span);
        j["device_counter_rate_hz"] = cr;
        j["device_counter_nominal_hz"] = counter_nominal_hz;
        j["device_counter_steps"] = {{"0", h.cnt.counter_steps[0]}, {"1", h.cnt.counter_steps[1]},
                                     {"2", h.cnt.counter_steps[2]}, {"more", h.cnt.counter_steps[3]}};
    } else {
        j["device_clock_offset_ppm"] = nullptr;
    }
    if (h.cfg.index_by_counter || h.cfg.follow_counter) {
        j["samples_placed_by"] = "device counter";
        j["cycles_read_twice"] = h.cnt.cycles_read_twice;
        j["cycles_not_read"] = h.cnt.cycles_not_read;
        j["writes_straddled"] = h.cnt.writes_straddled;
        j["stale_anchors"] = h.cnt.stale_anchors;
    } else {
        j["samples_placed_by"] = "tick";
    }
    if (h.cfg.index_by_counter || h.cfg.follow_counter) j["phase_shifts"] = h.cnt.phase_shifts;
    if (h.cfg.follow_counter) {
        j["retimes"] = h.cnt.retimes;
        j["tick_period_followed_s"] = 1e-9 * h.tick.period_ns;
    }
    return j;
}

// The largest |G_ik| / sd(G_ik) of a line (0 without a covariance).
static double snr_of_line(const Json &ln)
{
    const Json &G = ln["G"], &C = ln["cov"];
    const size_t ny = G["re"].size(), nu = ny ? G["re"][0].size() : 0;
    double r = 0;
    for (size_t i = 0; i < ny; ++i)
        for (size_t q = 0; q < nu; ++q) {
            const double g = std::hypot(G["re"][i][q].get<double>(), G["im"][i][q].get<double>());
            const size_t k = q * ny + i;
            const double var = C["re"][k][k].is_number() ? C["re"][k][k].get<double>() : 0.0;
            if (var > 0) r = std::max(r, g / std::sqrt(var));
        }
    return r;
}

ClockBias clock_bias(const Json &doc, double eps, uint32_t periods, bool read_back)
{
    ClockBias c;
    for (const Json &ln : doc["lines"]) {
        const double bin = ln.value("bin", 0.0);
        // the excitation is periodic on the host's clock, the samples on the device's: line k slides by
        // 2 pi k eps rad per period; read back, input and output slide together and what remains is the
        // leakage between lines, about pi k eps
        const double bound = M_PI * std::fabs(eps) * bin * (read_back ? 1.0 : (double)periods);
        const double r = bound * snr_of_line(ln);
        if (r > 0.1) c.bins.push_back(bin);
        c.worst = std::max(c.worst, r);
    }
    return c;
}

std::string add_timing_bias(Json &doc, const TickTiming &t, double rate_hz, uint32_t period)
{
    std::vector<std::string> flagged;
    double worst = 0;
    for (Json &ln : doc["lines"]) {
        const double bin = ln.value("bin", 0.0);
        const double w = 2 * M_PI * bin * rate_hz / period;
        const LineBias b = line_bias(t, w);
        // the bias of each element against its standard deviation: |G| bound / sd
        const double ratio = b.bound * snr_of_line(ln);
        ln["timing_bias"] = {{"gain", b.gain}, {"phase_rad", b.phase}, {"bound", b.bound}, {"bound_over_sd", ratio}};
        if (ratio > 0.1) flagged.push_back(fmt("%g", bin));
        worst = std::max(worst, ratio);
    }
    if (flagged.empty()) return "";
    std::string list;
    const size_t show = std::min<size_t>(flagged.size(), 12);
    for (size_t i = 0; i < show; ++i) list += (i ? "," : "") + flagged[i];
    if (flagged.size() > show) list += fmt(",... (%zu in all)", flagged.size());
    return fmt("the commanded input's timing may bias %zu line(s) by more than a tenth of their standard deviation "
               "(bins %s; up to %.2g sd): read back the applied input (a measure channel with role = \"input\"), or "
               "lower the rate",
               flagged.size(), list.c_str(), worst);
}

}  // namespace msidacq
