// The order of the FRF job's steps, the same for every caller (msid frf, the Python extension):
// the records' shapes, the period, the inputs' periodicity, the lines, the estimator, and the
// distortion level from the detection lines. Each check runs once, in this order, so that the
// first problem named is the same whoever asks.
#include "frf_job_detail.hpp"
#include "frf_bla.hpp"
#include "frf_distortion.hpp"
#include "periodicity.hpp"

namespace msidjob {

// Step 1: the records' shapes, the period and the inputs (a record whose input is not periodic is
// named as such before its experiment count is, e.g. noise through several inputs).
static void check_inputs(FrfRequest &rq, const std::vector<Record> &recs, const FrfPlan &plan)
{
    const bool plain_checks = !plan.direct && !plan.bla;
    if (plain_checks) check_records(rq, recs, false);
    if (plan.auto_period) {
        std::string rep;
        rq.period = find_period(recs, rep);
        if (plan.report) plan.report("--period auto: " + rep + "\n");
    }
    if (!plan.direct && rq.period >= MSID_MIN_PERIOD && rq.period <= MSID_MAX_PERIOD)
        check_periodic_inputs(rq.period, rq.skip, rq.bins, recs);
    if (plain_checks) check_records(rq, recs);
    rq.inputs_checked = !plan.direct;
}

// Step 2: the lines, from the input when asked.
static void find_lines_if_asked(FrfRequest &rq, const std::vector<Record> &recs, const FrfPlan &plan)
{
    if (!plan.auto_lines) return;
    std::string rep;
    rq.bins = find_lines(recs, rq.period, rq.skip, rep);
    if (plan.report) plan.report("--lines auto: " + rep + ":\n  " + format_bins(rq.bins) + "\n");
}

// Step 4: one realisation with detection lines: the distortion level beside the noise.
void add_detection_distortion(FrfOutcome &o)
{
    const Json nl = detection_distortion(o.doc);
    if (nl.is_null()) return;
    o.doc["nonlinear_distortion"] = nl;
    if (nl["distortion_detected"].get<bool>())
        o.notes.push_back("the detection lines show nonlinear distortion (" +
                          (nl["nl_to_noise_db"].is_number() ? fmt("%.1f dB", nl["nl_to_noise_db"].get<double>())
                                                             : std::string("?")) +
                          " relative to the noise); cov holds the noise only: measure several realisations "
                          "(--realisations R) to include it");
}

FrfOutcome estimate_frf(FrfRequest &rq, const std::vector<Record> &recs, const FrfPlan &plan,
                        std::unique_ptr<FrfJob> *keep)
{
    if (plan.direct && (plan.auto_period || plan.auto_lines)) throw UsageError("--direct needs --design (no auto period/lines)");
    if (plan.direct && !plan.design) throw UsageError("--direct needs --design (the input is the design's exact multisine)");
    if (plan.direct && plan.bla) throw UsageError("--realisations does not apply to --direct");
    FrfOutcome o;
    names_from_records(rq, recs);
    try {
        check_inputs(rq, recs, plan);
        find_lines_if_asked(rq, recs, plan);
        // Step 3: the estimator
        rq.lines_as_text = rq.lines_as_text && !plan.direct && !plan.bla;
        o = plan.direct             ? run_frf_direct(rq, *plan.design, recs)
            : plan.bla             ? run_frf_realisations(rq, recs, plan.realisations)
                                    : run_frf(rq, recs, keep);
    } catch (...) {
        // a record taken without its NaN/Inf scan (Record::finite_unchecked): the reader's message
        // comes first, as when the reader scanned, whatever the run found later (the first bad record)
        for (const Record &r : recs)
            if (r.finite_unchecked) check_finite(r, 0, r.n_rows);
        throw;
    }
    if (!plan.direct && !plan.bla) add_detection_distortion(o);
    return o;
}

}  // namespace msidjob
