// `msid measure`: one measurement of a device named by a URI (docs/measure.md), shared by
// `msid demo`, `msid modbus measure` and `msid can measure`. One session per protocol (Modbus:
// measure_modbus.cpp over msid_mb_acq_run; CAN: cmd_can.cpp over msid_can_session) runs its
// experiments through one loop (run_experiments: progress, SIGINT/SIGTERM with every complete
// period kept) into one FRF path (finish_measure, write_measure_result). measure_session.cpp.
#pragma once
#include "device_uri.hpp"
#include "param_upload.hpp"
#include "host_libs.hpp"
#include "progress.hpp"

extern "C" {
#include "msid_daq/msid_modbus.h"
}

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

// ---- the protocol sessions (one per protocol, each over its daq session) ----------

// A Modbus link and its stream format: from a device URI (msid measure) or from the options of
// `msid modbus measure` (cmd_modbus.cpp).
struct ModbusLink {
    bool rtu = false;
    std::string host, device;  // TCP host / RTU serial device
    uint32_t port = 502, baud = 115200, data_bits = 8, stop_bits = 1, unit = 1;
    char parity = 'N';
    std::string name;          // "tcp:HOST:PORT" / "rtu:/dev/ttyX": messages and sources
    std::string uri;           // the device URI when given as one ("" : none)
    uint32_t response_ms = 200, byte_ms = 50, retries = 5, max_regs = 125;
    uint32_t encoding = 0, word_order = 0;   // MSID_MB_ENC_S16, ABCD
};
ModbusLink modbus_link_from_uri(const DeviceUri &dev);
// The options --tcp/--rtu, --baud, --parity, --data-bits, --stop-bits, --unit, timeouts, --retries,
// --max-regs, --encoding, --word-order of `msid modbus measure` (cmd_modbus.cpp; also --on-device).
ModbusLink modbus_link_options(const Args &a);
// An open Modbus connection (closed by its destructor).
struct MbLink {
    msid_modbus m{};
    bool open = false;
    ~MbLink() { close(); }
    void close()
    {
        if (open) msid_mb_close(&m.tr);
        open = false;
    }
};
// Open L to l (measure_modbus.cpp). Throws Error naming the link when it cannot connect.
void open_modbus_link(const ModbusLink &l, MbLink &L);

// A CAN link: from a device URI or from the options of `msid can measure` (cmd_can.cpp).
struct CanLink {
    std::string iface;
    uint32_t base = 0x200, window = 16, encoding = 0;   // MSID_CAN_ENC_S16
    bool fd = false;
    double bitrate = 0, data_bitrate = 0;               // 0: a virtual bus (no load check)
    int rcvbuf = 0;
    std::string log;                                    // candump log of every frame ("" : none)
};
CanLink can_link_from_uri(const DeviceUri &dev);

// The Modbus TCP/RTU session (measure_modbus.cpp) and the CAN session (cmd_can.cpp): identify the
// device, plan, upload, run every experiment through run_experiments, and finish_measure. Throws
// Error; on a stop request (measure_stop_requested) returns the FRF of the complete periods marked
// incomplete, or throws Error when some experiment has fewer than 2 usable periods (no FRF exists then).
MeasureResult measure_modbus(const ModbusLink &link, const PlanFn &plan, Progress &pg);
MeasureResult measure_can(const CanLink &link, const PlanFn &plan, Progress &pg);

// ---- what every protocol shares ----------------------------------------------------

// One protocol's experiment runner as the shared loop sees it.
struct ExperimentRunner {
    virtual ~ExperimentRunner() = default;
    // Run experiment e (K = periods), calling tick() after every poll; tick() returns true when a stop
    // was requested. Returns false when the experiment was stopped (its complete periods are kept in
    // the measurement), true when it ended. Throws Error.
    virtual bool run(uint32_t e, uint32_t periods, const std::function<bool()> &tick) = 0;
    virtual uint64_t samples() const = 0;       // samples received so far (all experiments)
    virtual uint64_t lost() const = 0;          // samples lost (drops, overruns)
    virtual uint64_t link_errors() const = 0;   // bus errors / retried requests
};

struct LoopResult {
    uint32_t done = 0;         // experiments completed
    bool stopped = false;      // a stop request ended the run
};
// Every experiment of the plan into msid_meas `ms` with live progress (experiment i/m, periods
// acquired and rejected, samples lost, link errors, running SNR, ETA) and stop requests honoured.
LoopResult run_experiments(ExperimentRunner &r, const msid_meas *ms, const MeasurePlan &P, Progress &pg);
// The FRF of what was measured: sources named "<src> experiment i", the protocol's notes, the stop
// note, "complete" and the counts (mark_completeness), and the summary line's common part.
MeasureResult finish_measure(FrfJob &job, const MeasurePlan &P, const LoopResult &L, const std::string &src,
                             std::vector<std::string> notes);

// The protocol commands' write path: OUTPUT gets the FRF (a complete run keeps the historic file,
// without the completeness keys), notes go to stderr as "msid <cmd>: note: ...", the summary to stdout.
// Returns the exit status: 0, or 128 + the signal when the run was stopped.
int write_measure_result(MeasureResult &R, const std::string &out, const std::string &cmd);

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

// Mark a document complete or not, with the counts of what was measured.
void mark_completeness(Json &doc, bool complete, uint32_t experiments_done, uint32_t experiments,
                       const std::string &reason);

}  // namespace msidcli
