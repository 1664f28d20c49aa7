// `msid measure`: one measurement of a device named by a URI (docs/measure.md), shared by
// `msid demo`. The protocol sessions (Modbus here, CAN through `msid can measure`) fill one
// msid-frf/1 document; SIGINT/SIGTERM stop them cleanly with every complete period kept.
#pragma once
#include "device_uri.hpp"
#include "param_upload.hpp"
#include "progress.hpp"

#include <csignal>
#include <functional>

namespace msidcli {

// What to run, decided once the device has said how many inputs it has.
struct MeasurePlan {
    std::unique_ptr<Design> D;
    StreamFmt sf;
    FrfRequest rq;
    double timeout = 10.0;     // seconds without a new sample before giving up
};
using PlanFn = std::function<void(uint32_t device_inputs, MeasurePlan &)>;

struct MeasureResult {
    FrfOutcome o;              // msid-frf/1 with "complete" and the `acquisition` block
    bool complete = true;      // false: stopped by a signal, the FRF of the complete periods
    std::string summary;       // one line for stdout
    std::unique_ptr<Design> D; // the design that ran
};

// The Modbus TCP/RTU session: header, upload, every experiment, FRF. Throws Error; on a stop
// request (measure_stop_requested) returns the FRF of the complete periods marked incomplete,
// or throws Error when some experiment has fewer than 2 usable periods (no FRF exists then).
MeasureResult measure_modbus(const DeviceUri &dev, const PlanFn &plan, Progress &pg);

// Stop requests: SIGINT and SIGTERM set a flag the sessions poll (installed for the scope).
class StopOnSignal {
public:
    StopOnSignal();
    ~StopOnSignal();
    StopOnSignal(const StopOnSignal &) = delete;
    StopOnSignal &operator=(const StopOnSignal &) = delete;
private:
    struct sigaction old_int_{}, old_term_{};
};
bool measure_stop_requested();
int measure_stop_signal();     // the signal that asked (0: none)

// One `msid measure` run (cmd_measure.cpp), also driven by `msid demo`.
struct MeasureOptions {
    const Args *args = nullptr;   // the command line (design and measurement options)
    DeviceUri dev;
    std::string outdir;
    std::string fit, order;       // --fit subspace|ml, --order n|auto ("" : no fit)
    bool plots = true;
    bool quiet_fit = false;       // silence msid fit's table
};
struct MeasureRun {
    MeasureResult m;
    std::string frf, model;       // paths written ("" : none)
    std::string fit_error;        // the fit failed (the FRF is kept)
    std::string plot_note;        // "wrote ..." or "plots skipped: why"
};
// The options and flags of `msid measure` (for Args).
const std::vector<std::string> &measure_keys();
// Check everything that can be checked before the device is touched. Throws UsageError.
MeasureOptions parse_measure_command(const Args &a);
// Measure, write OUTDIR/{design,frf}.json, fit, plot. Throws Error (nothing written then).
MeasureRun run_measure(const MeasureOptions &opt, Progress &pg);

// Mark a document complete or not, with the counts of what was measured.
void mark_completeness(Json &doc, bool complete, uint32_t experiments_done, uint32_t experiments,
                       const std::string &reason);

}  // namespace msidcli
