// What the FRF job's sources share inside msid_frfjob (not installed).
#pragma once
#include "msid_frf_job.hpp"
#include "msid_fftw_planner.hpp"
#include "msid_host_util.hpp"

#include <functional>

namespace msidjob {

using msidutil::check;
using msidutil::fmt;
using msidutil::Mem;
using msidutil::fftw_planner_ready;
using msidutil::fftw_warmup_start;

// The period and the lines (and detection lines) of a request are valid: throws Error.
void validate_lines(const FrfRequest &rq);
// The whole periods of a record: throws Error when fewer than `min_used` (2 for a covariance from the
// periods; 1 for a realisation of the BLA's total covariance) are left after rq.skip, or more than
// MAX_RECORD_PERIODS.
uint64_t record_periods(const Record &r, const FrfRequest &rq, uint32_t min_used = 2);
// Every sample of recs (whole periods; experiment e is recs[e]) through job's measurement lanes
// (on_lanes), each record's NaN/Inf scan where the reader left it (Record::finite_unchecked).
void measure_records(FrfJob &job, const FrfRequest &rq, const std::vector<Record> &recs);
// Experiments 0 .. m-1 on `lanes` (1 or 2) threads, experiment e on lane e % lanes by one(lane, e);
// a lane stops at its first failing experiment. Rethrows the error of the first failing experiment in
// file order: every experiment before it ran to its end on one lane or the other.
void on_lanes(uint32_t m, uint32_t lanes, const std::function<void(uint32_t lane, uint32_t e)> &one);
// --lines auto's outcome, however rq.bins were found (find_lines on records read whole, or
// lines_from_scans on files streamed; `rep` that function's report): the report line through
// plan.report, the document's lines_auto block, and the note on grid bins left undecided (empty when
// none).
void lines_auto_found(const FrfRequest &rq, const FrfPlan &plan, std::string rep, const std::vector<double> &p_min,
                      Json &block, std::string &undecided);
// FrfJob::finish() when the core's FRF cannot use some of the lines: the Error of the first such line,
// as always (its message unchanged), with every such line as an index into rq.bins, for a caller that
// found the lines itself (--lines auto) and leaves these out instead (frf_without_unusable_lines).
struct UnusableLines : Error {
    explicit UnusableLines(const std::string &m) : Error(m) {}
    std::vector<uint32_t> weak;        // the weakest input direction too close to its noise or to nothing
                                       // (the core's excitation test, MSID_LINE_UNEXCITED)
    std::vector<uint32_t> dependent;   // the input matrix singular: the experiments do not drive the inputs
                                       // independently there (MSID_LINE_SINGULAR)
};
// The bins --lines auto found that the FRF could not use, by reason (frf_without_unusable_lines).
struct DroppedLines {
    std::vector<uint32_t> weak, dependent;
    bool empty() const { return weak.empty() && dependent.empty(); }
};
// The periodic FRF on rq by `run`; with --lines auto (plan.auto_lines) a line the FRF cannot use
// (UnusableLines) is left out and `run` runs again on the lines left (the FRF is then the one the
// kept lines given with --lines give), until every line is used. The dropped bins go to `dropped`;
// UnusableLines is rethrown when no line is left, or without --lines auto (given lines are refused).
FrfOutcome frf_without_unusable_lines(FrfRequest &rq, const FrfPlan &plan, DroppedLines &dropped,
                                      const std::function<FrfOutcome()> &run);
// The lines frf_without_unusable_lines() dropped, in the document's lines_auto block
// (unusable_bins, unusable_rule) and as one note (none when nothing was dropped). `found`: the bins
// --lines auto found, for the ranges the note names.
void report_dropped_lines(const FrfRequest &rq, const FrfPlan &plan, const std::vector<uint32_t> &found,
                          const DroppedLines &dropped, Json &lines_auto, std::vector<std::string> &notes);
// The members of r's document that detection_distortion() (nl_verdict.hpp) reads: n_experiments,
// n_outputs, the experiments' periods_used and the detection lines.
Json detection_summary(const FrfResult &r);
// The transient test's history per experiment (16 bytes x lines x channels per period) holds at
// most this: the periods after it are used untested (msid_pstats beyond_history).
constexpr double HISTORY_BYTES = 32.0 * 1024 * 1024;
// The periods a record may hold (the core's period counters and history, 24 bits).
constexpr uint64_t MAX_RECORD_PERIODS = 0xFFFFFFu;

}  // namespace msidjob
