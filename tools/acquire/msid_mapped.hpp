// Measuring a device that does not run msid's firmware (a PLC, a drive, an I/O module, an ECU), described by
// an msid-device/1 file (docs/devices.md): the host generates the excitation, writes it to the drive channels
// once per tick of its own clock, reads the measure channels in the same tick, and estimates the FRF from
// what it read (daq/'s msid_hx over the device's backend). Limits are checked before anything is written and
// the safe values are written on every way out. The FRF file's `acquisition` block says how the ticks ran
// (`timing`), and for a commanded input the bias that timing implies per line. docs/devices.md.
#pragma once
#include "msid_acquire.hpp"

extern "C" {
#include "msid_daq/msid_devdesc.h"
}

namespace msidacq {

// How the tick loop runs, beside the plan (design, periods, FRF request).
struct MappedOptions {
    double rate_hz = 0;        // ticks per second (required, > 0)
    bool realtime = true;      // SCHED_FIFO and locked memory where permitted
    double timeout = 5.0;      // seconds without an answer before giving up
    std::string desc_path;     // the description's file, for the acquisition block
};

// A description read and checked (msid_devdesc_load), or UsageError naming the file, line and key.
msid_devdesc load_description(const std::string &path);

// Which description channel feeds each FRF signal, and the FRF's names and units.
struct ChannelPlan {
    std::vector<int> input_of;      // per drive channel: the measure channel reading it back, -1: commanded
    std::vector<uint32_t> outputs;  // measure channels with role output, in order
    int counter = -1;               // the counter channel
    bool read_back = false;         // every drive channel is read back
    std::vector<std::string> input_names, input_units, output_names, output_units;
};
ChannelPlan channel_plan(const msid_devdesc &d);

// One measurement of a described device at dev (modbus-tcp://, modbus-rtu://). `plan` gets the number of
// drive channels and fills the design (one input per drive channel), the periods and the FRF request.
// Throws Error (device, link: the safe values were written where the link allowed) or UsageError (nothing
// was written but the safe values).
MeasureResult measure_mapped(const DeviceUri &dev, const msid_devdesc &desc, const MappedOptions &o,
                             const PlanFn &plan, Control &ctl);

// The closed-loop preset: from the periodic FRF of one reference r to the signals z (msid-frf/1), the plant
// from z_u to the others through the reference, G = G_yr G_ur^-1 with its linearised covariance (an msid-frf/1
// document of one input; its `reference` block says how it was made). ref: one input (the reference), n >= 2
// outputs z, each line's G (n x 1) and cov (n x n, Cov vec(G_zr)), optionally cov_known_input and noise_cov
// (n x n); u: the index of the plant's input among z. Throws Error naming the bin for a line where G_ur = 0 or
// so small that the plant or its covariance would not be finite.
Json plant_through_reference(const Json &ref, uint32_t u);

// `msid device check`: read every channel once, write nothing but the safe values, and report what the
// device answered against the description: one line per channel and the problems found.
struct CheckResult {
    std::vector<std::string> lines;   // what to print
    uint32_t problems = 0;            // channels whose value is out of place (non-finite, outside a drive's range)
};
CheckResult check_device(const DeviceUri &dev, const msid_devdesc &desc);

}  // namespace msidacq
