// What every protocol session shares (inside msid_acquire): one protocol's experiment runner, the
// experiment loop with progress and stop requests, and the FRF of what was measured.
#pragma once
#include "msid_acquire.hpp"

namespace msidacq {

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
    virtual void timing(ProgressState &) const {}   // a host-timed runner's lateness and missed ticks
};

struct LoopResult {
    uint32_t done = 0;         // experiments completed
    bool stopped = false;      // a stop request ended the run
    int reason = 0;            // Control::stop()'s answer
};
// Every experiment of the plan into msid_meas `ms` with progress (experiment i/m, periods acquired
// and rejected, samples lost, link errors, running SNR, ETA) and stop requests honoured.
LoopResult run_experiments(ExperimentRunner &r, const msid_meas *ms, const MeasurePlan &P, Control &ctl);
// The FRF of what was measured: sources named "<src> experiment i", the protocol's notes, the stop
// note, "complete" and the counts (mark_completeness), and the summary line's common part.
MeasureResult finish_measure(msidjob::FrfJob &job, const MeasurePlan &P, const LoopResult &L, const std::string &src,
                             std::vector<std::string> notes);

// R.summary: "L lines, ny x nu, d[ of m] experiment(s) over LINK, N samples, N missing, N periods
// used, N rejected[ (INCOMPLETE: stopped)]".
void set_summary(MeasureResult &R, const MeasurePlan &P, uint32_t ny, uint32_t nu, uint32_t done,
                 const std::string &link, uint64_t samples, uint64_t lost);

}  // namespace msidacq
