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

// The reference columns of each record's file as the "inputs" of a record (with its first output,
// which a reader needs): what --lines auto tests when the file holds the excitation's reference.
static std::vector<Record> reference_records(const std::vector<Record> &recs, const std::vector<std::string> &ref)
{
    std::vector<Record> out;
    for (const Record &r : recs) {
        if (ref.size() != r.nu)
            throw UsageError(fmt("--reference names %zu column(s) for %u input(s): one reference per input",
                                 ref.size(), r.nu));
        msidrec::ColumnMap m;
        for (size_t k = 0; k < ref.size(); ++k) m.map.emplace_back(fmt("u%zu", k + 1), ref[k]);
        m.map.emplace_back("y1", r.columns.at(r.nu));
        Record rr = msidrec::read_experiment(r.path, m);
        if (rr.n_rows != r.n_rows)
            throw Error(fmt("'%s': the reference columns have %zu rows, the inputs and outputs %zu", r.path.c_str(),
                            rr.n_rows, r.n_rows));
        out.push_back(std::move(rr));
    }
    return out;
}

// Where the found lines leave bins of their grid undecided: said on the report and kept for the
// document (lines_auto) and a note.
static Json lines_auto_block(const FrfRequest &rq, const FrfPlan &plan, const UndecidedLines &u, std::string &text)
{
    Json j;
    std::string from = "the inputs";
    if (!plan.reference.empty()) {
        from = "the reference";
        for (size_t k = 0; k < plan.reference.size(); ++k) from += fmt(k ? ", r%zu=%s" : " r%zu=%s", k + 1, plan.reference[k].c_str());
    }
    j["from"] = from;
    j["test"] = fmt("F test of the period mean against the period-to-period variation, family-wise false alarm %g",
                    LINES_AUTO_ALPHA);
    j["found"] = rq.bins.size();
    if (u.step) j["grid"] = Json{{"step", u.step}, {"first", u.first}, {"last", u.last}};
    j["undecided_bins"] = u.bins;
    j["undecided_alpha"] = UNDECIDED_ALPHA;
    j["silent_grid_bins"] = u.silent;
    if (u.bins.empty()) return j;
    // runs of neighbouring grid bins, as frequency ranges when the rate is known (else as bins); a long
    // list is cut after its first runs: the file holds every bin
    constexpr size_t SHOWN = 12;
    std::vector<std::string> runs;
    for (size_t i = 0; i < u.bins.size();) {
        size_t e = i;
        while (e + 1 < u.bins.size() && u.bins[e + 1] - u.bins[e] == u.step) ++e;
        if (rq.fs > 0) {
            const double f0 = u.bins[i] * rq.fs / rq.period, f1 = u.bins[e] * rq.fs / rq.period;
            runs.push_back(e > i ? fmt("%.4g-%.4g Hz", f0, f1) : fmt("%.4g Hz", f0));
        } else {
            runs.push_back(e > i ? fmt("bins %u-%u", u.bins[i], u.bins[e]) : fmt("bin %u", u.bins[i]));
        }
        i = e + 1;
    }
    std::string where;
    for (size_t k = 0; k < std::min(runs.size(), SHOWN); ++k) where += (k ? ", " : "") + runs[k];
    if (runs.size() > SHOWN) where += fmt(" and %zu more ranges (every bin in the file's lines_auto.undecided_bins)", runs.size() - SHOWN);
    const std::string grid = u.step == 1 ? fmt("bins %u to %u", u.first, u.last)
                                         : fmt("bins %u to %u in steps of %u", u.first, u.last, u.step);
    text = fmt("%zu bin(s) of the excitation's grid (%s) show input power at %g but not at the family-wise level, and "
               "are left out: %s. The input is weak there over these periods (a force that drops at a resonance or "
               "near the mains), or holds periodic power beyond the excitation (a force with nonlinear distortion); "
               "give the bins with --lines, more periods, or the excitation's reference (--reference r1=COLUMN)",
               u.bins.size(), grid.c_str(), UNDECIDED_ALPHA, where.c_str());
    return j;
}

// Step 2: the lines, from the input (or the excitation's reference) when asked.
static void find_lines_if_asked(FrfRequest &rq, const std::vector<Record> &recs, const FrfPlan &plan, Json &lines_auto,
                                std::string &undecided)
{
    if (!plan.auto_lines) {
        if (!plan.reference.empty()) throw UsageError("--reference applies to --lines auto (and --method lpm)");
        return;
    }
    std::string rep;
    std::vector<double> p_min;
    if (plan.reference.empty()) {
        rq.bins = find_lines(recs, rq.period, rq.skip, rep, &p_min);
    } else {
        rq.bins = find_lines(reference_records(recs, plan.reference), rq.period, rq.skip, rep, &p_min);
    }
    lines_auto_found(rq, plan, rep, p_min, lines_auto, undecided);
}

void lines_auto_found(const FrfRequest &rq, const FrfPlan &plan, std::string rep, const std::vector<double> &p_min,
                      Json &block, std::string &undecided)
{
    if (!plan.reference.empty()) rep += " of the reference";
    if (plan.report) plan.report("--lines auto: " + rep + ":\n  " + format_bins(rq.bins) + "\n");
    block = lines_auto_block(rq, plan, undecided_lines(rq.bins, p_min), undecided);   // a note (estimate_frf)
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
    Json lines_auto;
    std::string undecided;
    names_from_records(rq, recs);
    try {
        check_inputs(rq, recs, plan);
        find_lines_if_asked(rq, recs, plan, lines_auto, undecided);
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
    if (!lines_auto.is_null()) o.doc["lines_auto"] = lines_auto;
    if (!undecided.empty()) o.notes.push_back("--lines auto: " + undecided);
    return o;
}

}  // namespace msidjob
