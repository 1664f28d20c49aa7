// msid_acquire: one measurement of a device over Modbus (TCP, RTU) or SocketCAN. Identify the
// device, plan from what it reports, upload the design as parameters, run every experiment through
// the FRF job (tools/frfjob) with progress and stop requests, and return the msid-frf/1 document of
// what was measured with its `acquisition` block. The command line (`msid measure`, `msid modbus|can
// measure`) and the Python extension (msid.measure) are thin callers. No command-line types; errors
// are msidacq::Error (device, link, protocol) and msidutil::UsageError (a request that cannot run).
// docs/measure.md, docs/modbus-registers.md, docs/can-protocol.md.
#pragma once
#include "msid_device_uri.hpp"
#include "msid_frf_job.hpp"
#include "msid_param_upload.hpp"

extern "C" {
#include "msid_daq/msid_modbus.h"
}

#include <cmath>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace msidacq {

// A device, link or protocol problem, one message naming the link. `code` is the command line's
// exit status (1; 128 + the signal for a stop that left no FRF).
struct Error : msidutil::Error {
    explicit Error(const std::string &m, int status = 1, msidutil::ErrorKind k = msidutil::ErrorKind::io)
        : msidutil::Error(m, status, k) {}
};
using msidutil::UsageError;
using msidjob::FrfRequest;
using msidjob::FrfOutcome;
using msidfmt::Json;

// What the acquisition knows at one moment.
struct ProgressState {
    uint32_t exp = 0, n_exp = 0;               // current experiment (1-based) of n_exp
    uint32_t periods = 0, periods_target = 0;  // complete periods acquired in this experiment, of the target
    uint64_t periods_total = 0;                // complete periods acquired in all experiments
    uint64_t rejected = 0;                     // periods rejected so far (gaps, non-finite, transient)
    uint64_t lost = 0;                         // samples lost (drops, overruns)
    uint64_t link_errors = 0;                  // bus errors / retried requests
    double snr_db = NAN;                       // running output SNR per period (dB), NaN before 2 periods
    double eta_s = NAN;                        // estimated seconds left, NaN when unknown
    // host-timed excitation (a described device): the tick loop's timing so far
    double lateness_p99_s = NAN;               // p99 of the ticks' lateness (s), NaN when the host does not tick
    uint64_t missed_ticks = 0;                 // ticks slept through
};

// What a measurement reports to its caller and asks of it while it runs, on the measuring thread.
// update() comes after every poll of the link (tens to hundreds a second): a sink draws at its own
// pace. stop() is asked as often; a non-zero answer ends the run after the complete periods, and
// names the reason in the file ("stopped by signal N").
struct Control {
    virtual ~Control() = default;
    virtual void update(const ProgressState &) {}
    virtual void note(const std::string &) {}      // an event of its own ("experiment 1/2 done")
    virtual void done() {}                         // the acquisition ended (the live line is finished)
    virtual int stop() { return 0; }               // 0, or the signal (or other reason number) asking to stop
};

// What to run, decided once the device has said how many inputs it has.
struct MeasurePlan {
    std::shared_ptr<const msidfmt::Design> D;   // shared: a caller may keep its own design object
    StreamFmt sf;
    FrfRequest rq;
    double timeout = 10.0;     // seconds without a new sample before giving up
};
// Fills the plan from the device's number of inputs; throws to refuse it (nothing was run yet).
using PlanFn = std::function<void(uint32_t device_inputs, MeasurePlan &)>;

struct MeasureResult {
    FrfOutcome o;              // msid-frf/1 with "complete", the counts and the `acquisition` block
    bool complete = true;      // false: stopped, the FRF of the complete periods
    int stop_reason = 0;       // Control::stop()'s answer when stopped
    std::string summary;       // one line: lines, size, experiments, link, samples, periods
    std::shared_ptr<const msidfmt::Design> D;   // the design that ran
    Json reference;            // the closed-loop preset: the FRF of the reference path (null: none), beside o.doc
};

// The checks of a plan that every caller shares: 2..MSID_PARAMS_MAX_PERIODS periods, skip leaves 2,
// a positive scale and timeout; with a rate and a DT design, rq.fs = the rate. `names` gives the
// request's words for messages ({"--periods", "--skip-periods"} or {"periods", "skip_periods"}).
// Throws UsageError.
void check_plan(MeasurePlan &P, const char *periods_name, const char *skip_name);

// With an integer encoding of the samples (`integer`): every input's largest sample (at most the sum
// of its lines' amplitudes) is at least half a step of the scale. Below, the input is sent as zeros,
// its lines are not excited, and the FRF was refused after the run as "the input matrix is singular".
// Throws UsageError naming --scale (before the device runs).
void check_input_resolution(const MeasurePlan &P, bool integer);

// ---- the links ---------------------------------------------------------------------

// A Modbus link and its stream format: from a device URI or from the options of `msid modbus measure`.
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

// An open Modbus connection (closed by its destructor).
struct MbLink {
    msid_modbus m{};
    bool open = false;
    MbLink() = default;
    MbLink(const MbLink &) = delete;
    MbLink &operator=(const MbLink &) = delete;
    ~MbLink() { close(); }
    void close()
    {
        if (open) msid_mb_close(&m.tr);
        open = false;
    }
};
// Open L to l. Throws Error naming the link when it cannot connect (a first TCP connection that is
// refused is tried again for MSID_MODBUS_CONNECT_WAIT_MS, 2 s: docs/modbus-registers.md).
void open_modbus_link(const ModbusLink &l, MbLink &L);

// A CAN link: from a device URI or from the options of `msid can measure`.
struct CanLink {
    std::string iface;
    uint32_t base = 0x200, window = 16, encoding = 0;   // MSID_CAN_ENC_S16
    bool fd = false;
    double bitrate = 0, data_bitrate = 0;               // bit/s; 0: a virtual bus (no load check)
    int rcvbuf = 0;                                     // socket receive buffer, bytes (0: the system's)
    std::string log;                                    // candump log of every frame ("" : none)
};
CanLink can_link_from_uri(const DeviceUri &dev);

// ---- the measurement ----------------------------------------------------------------

// Identify the device, plan, upload, run every experiment, and the FRF of what was measured.
// Throws Error (device, link) or what `plan` throws. On a stop request returns the FRF of the
// complete periods marked incomplete, or throws Error (code 128 + the reason) when some experiment
// has fewer than 2 usable periods: no FRF exists then.
MeasureResult measure_modbus(const ModbusLink &link, const PlanFn &plan, Control &ctl);
MeasureResult measure_can(const CanLink &link, const PlanFn &plan, Control &ctl);
// The session of the URI's protocol.
MeasureResult measure_device(const DeviceUri &dev, const PlanFn &plan, Control &ctl);

// Mark a document complete or not, with the counts of what was measured.
void mark_completeness(Json &doc, bool complete, uint32_t experiments_done, uint32_t experiments,
                       const std::string &reason);

}  // namespace msidacq
