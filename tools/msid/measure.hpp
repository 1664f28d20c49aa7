// `msid measure`, `msid modbus measure`, `msid can measure` and `msid demo`: the options of a
// measurement, its outputs and Ctrl-C, over the acquisition library (tools/acquire, msid_acquire.hpp),
// which runs the session of each protocol. docs/measure.md.
#pragma once
#include "host_libs.hpp"
#include "msid_acquire.hpp"
#include "msid_mapped.hpp"
#include "progress.hpp"
#include "stop_signal.hpp"

namespace msidcli {

// the acquisition (tools/acquire)
using msidacq::DeviceUri;
using msidacq::parse_device_uri;
using msidacq::StreamFmt;
using msidacq::DevDesign;
using msidacq::device_design;
using msidacq::same_coef;
using msidacq::config_from_design;
using msidacq::MeasurePlan;
using msidacq::PlanFn;
using msidacq::MeasureResult;
using msidacq::ModbusLink;
using msidacq::MbLink;
using msidacq::open_modbus_link;
using msidacq::modbus_link_from_uri;
using msidacq::CanLink;
using msidacq::can_link_from_uri;
using msidacq::measure_modbus;
using msidacq::measure_can;
using msidacq::measure_device;
using msidacq::mark_completeness;

// The options every `measure` command shares: --scale, --periods (2..100000, default the design's
// or 8) and --rate (whole Hz, 0: unpaced) into `sf`; the design's lines and --skip-periods/
// --detect-lines/--transient/--alpha into `rq` (a DT rate also sets rq.fs). --skip-periods must
// leave 2 periods. Throws UsageError (measure_options.cpp).
void parse_measure_options(const Args &a, const Design &D, StreamFmt &sf, FrfRequest &rq);
// The part of it without --scale and --rate (a described device's tick rate is --rate in any real Hz).
void parse_periods_and_estimate(const Args &a, const Design &D, StreamFmt &sf, FrfRequest &rq);

// The --tcp/--rtu, --baud, --parity, --data-bits, --stop-bits, --unit, timeouts, --retries,
// --max-regs, --encoding, --word-order of `msid modbus measure` (cmd_modbus.cpp; also --on-device).
ModbusLink modbus_link_options(const Args &a);

// The protocol commands' write path: OUTPUT gets the FRF (a complete run keeps the historic file,
// without the completeness keys), notes go to stderr as "msid <cmd>: note: ...", the summary to stdout.
// Returns the exit status: 0, or 128 + the signal when the run was stopped.
int write_measure_result(MeasureResult &R, const std::string &out, const std::string &cmd);

// One `msid measure` run (cmd_measure.cpp), also driven by `msid demo`.
struct MeasureOptions {
    const Args *args = nullptr;   // the command line (design and measurement options)
    DeviceUri dev;
    std::string map;              // --map FILE: a described device (msid-device/1), host-timed excitation
    double rate_hz = 0;           // --rate with --map (ticks per second)
    bool realtime = true;         // --no-realtime clears it
    std::string outdir;
    std::string fit, order;       // --fit subspace|ml, --order n|auto ("" : no fit)
    bool plots = true;
    bool quiet_fit = false;       // silence msid fit's table
    std::string command_line;     // as typed (shell-quoted), for the report
};
struct MeasureRun {
    MeasureResult m;
    std::string frf, model;       // paths written ("" : none)
    std::string fit_error;        // the fit failed (the FRF is kept)
    std::string fit_skipped;      // why --fit did not run (the run was stopped: the user asked to end)
    std::string plot_note;        // "wrote ..." or "plots skipped: why"
};
// The options and flags of `msid measure` (for Args).
const std::vector<std::string> &measure_keys();
// Check everything that can be checked before the device is touched. Throws UsageError.
MeasureOptions parse_measure_command(const Args &a);
// Measure, write OUTDIR/{design,frf}.json, fit, plot. Throws Error (nothing written then).
MeasureRun run_measure(const MeasureOptions &opt, Progress &pg);

}  // namespace msidcli
