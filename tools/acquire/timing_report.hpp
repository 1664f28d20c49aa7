// What the tick loop's timing means for the FRF (inside msid_acquire): the `acquisition.timing` block, and for
// a commanded input the bias the measured timing implies per line. docs/devices.md, "Timing".
#pragma once
#include "msid_acquire.hpp"

extern "C" {
#include "msid_daq/msid_hx.h"
}

namespace msidacq {

// The instants the device was written and read, relative to each tick's deadline, from msid_hx's statistics.
struct TickTiming {
    double apply_mean = 0, apply_var = 0;     // s, s^2: write instants (middle of the write transaction)
    double sample_mean = 0, sample_var = 0;   // s, s^2: read instants
    double half_write_sq = 0, half_read_sq = 0;   // mean (transaction duration / 2)^2, s^2
    double cycle_s = 0;                       // the device's own cycle when known (0: none stated, or the tick's)
};
// cycle_hz: the device's cycle rate from its description (NAN: not stated).
TickTiming tick_timing(const msid_hx &h, double cycle_hz);

// The commanded input u[n] reaches the device at a_n and the output is sampled at s_n; against a device that
// applies and samples exactly at the deadlines the expected FRF is G exp(j w (s - a)) exp(-w^2 (var a + var s) / 2)
// (independent Gaussian instants). Each instant is known to within its transaction, whose uniform spread adds
// (d/2)^2 / 3 to its variance and whose half-width bounds the error of its mean. A device with a cycle of its own
// applies a write at its next cycle and answers a read with its last one: each instant moves by up to a cycle
// more, which adds cycle^2 / 12 to each variance and a cycle to the bound of the mean delay.
struct LineBias {
    double gain = 1;        // exp(-w^2 sigma^2 / 2)
    double phase = 0;       // rad: w (s_mean - a_mean)
    double bound = 0;       // relative: |1 - gain e^{j phase}| + w (mean half-widths)
};
LineBias line_bias(const TickTiming &t, double omega_rad_s);

// The `timing` block: rate asked and achieved, lateness and round trips (median, p99, max), missed and late
// ticks, unanswered exchanges, scheduling, the write and read instants, the device's clock from its counter.
Json timing_json(const msid_hx &h, double rate_hz, const std::string &exchange, double counter_nominal_hz);

// Per line `timing_bias` (gain, phase_rad, bound, bound_over_sd) into doc's lines for a commanded input, and
// the lines whose bound exceeds a tenth of their smallest standard deviation: one note naming them.
std::string add_timing_bias(Json &doc, const TickTiming &t, double rate_hz, uint32_t period);

// The bias a device clock offset eps (device rate / host rate - 1) implies when the host ticks on its own clock:
// the bins whose bound exceeds a tenth of their standard deviation, and the worst bound / sd.
struct ClockBias {
    std::vector<double> bins;
    double worst = 0;
};
ClockBias clock_bias(const Json &doc, double eps, uint32_t periods, bool read_back);

}  // namespace msidacq
