// The order of the FRF job's steps, the same for every caller (msid frf, the Python extension):
// the records' shapes, the period, the inputs' periodicity, the lines, the estimator, and the
// distortion level from the detection lines. Each check runs once, in this order, so that the
// first problem named is the same whoever asks.
#include "frf_job_detail.hpp"
#include "frf_bla.hpp"
#include "frf_distortion.hpp"
#include "periodicity.hpp"

#include <algorithm>
#include <iterator>

namespace msidjob {

// The reference columns of a record's file as the "inputs" of a record (with its first output, which a
// reader needs): what --lines auto and --period auto test when the file holds the excitation's reference.
static Record reference_record(const Record &r, const std::vector<std::string> &ref)
{
    if (ref.size() != r.nu)
        throw UsageError(fmt(MSID_OPT("reference") " names %zu column(s) for %u input(s): one reference per input", ref.size(), r.nu));
    msidrec::ColumnMap m;
    for (size_t k = 0; k < ref.size(); ++k) m.map.emplace_back(fmt("u%zu", k + 1), ref[k]);
    m.map.emplace_back("y1", r.columns.at(r.nu));
    Record rr = msidrec::read_experiment(r.path, m);
    if (rr.n_rows != r.n_rows)
        throw Error(fmt("'%s': the reference columns have %zu rows, the inputs and outputs %zu", r.path.c_str(),
                        rr.n_rows, r.n_rows));
    return rr;
}

static std::vector<Record> reference_records(const std::vector<Record> &recs, const std::vector<std::string> &ref)
{
    std::vector<Record> out;
    for (const Record &r : recs) out.push_back(reference_record(r, ref));
    return out;
}

void check_options(const FrfRequest &rq, const GivenOptions &g, const Design *design)
{
    if (g.has("fs")) {
        if (!(rq.fs > 0)) throw UsageError(MSID_OPT("fs") " must be positive");
        if (design && design->is_ct())
            throw UsageError(MSID_OPT("fs") " does not apply to a continuous-time design (it has a sample time)");
    }
    if (!(rq.alpha > 0 && rq.alpha < 1)) throw UsageError(MSID_OPT("alpha") " must be in (0, 1)");
    if (g.has("block") && rq.block == 0) throw UsageError(MSID_OPT("block") " must be positive");
}

void check_plan(const FrfRequest &rq, const FrfPlan &plan)
{
    const GivenOptions &g = plan.given;
    const bool design = g.has("design") || plan.design;
    const bool period = g.has("period") || plan.auto_period, lines = g.has("lines") || plan.auto_lines;
    if (design && (period || lines))
        throw UsageError("give either " MSID_OPT("design") " or " MSID_OPT("period") "/" MSID_OPT("lines") ", not both");
    // a request its caller filled (the period and lines set, none of them named as given) needs neither
    const bool filled = rq.period && !rq.bins.empty() && !period && !lines;
    if (!design && !(period && lines) && !filled)
        throw UsageError("give " MSID_OPT("design") ", or both " MSID_OPT("period") " and " MSID_OPT("lines"));
    if (plan.direct && (plan.auto_period || plan.auto_lines))
        throw UsageError(MSID_OPT("direct") " needs " MSID_OPT("design") " (no auto period/lines)");
    check_options(rq, g, plan.design);
    if (plan.direct) {
        if (!design) throw UsageError(MSID_OPT("direct") " needs " MSID_OPT("design") " (the input is the design's exact multisine)");
        for (const char *k : {"detect_lines", "dft", "block", "transient", "alpha"})
            if (g.has(k)) throw UsageError(msidutil::option_mark(k) + " does not apply to " MSID_OPT("direct"));
        if (plan.bla) throw UsageError(MSID_OPT("realisations") " does not apply to " MSID_OPT("direct"));
    }
}

// Step 1: the records' shapes, the period and the inputs (a record whose input is not periodic is
// named as such before its experiment count is, e.g. noise through several inputs).
static void check_inputs(FrfRequest &rq, const std::vector<Record> &recs, const FrfPlan &plan)
{
    const bool plain_checks = !plan.direct && !plan.bla;
    if (plain_checks) check_records(rq, recs, false);
    if (plan.auto_period) {   // from the excitation's reference when the lines come from it: exactly periodic
        std::string rep;
        const bool ref = plan.auto_lines && !plan.reference.empty() && !recs.empty();
        std::vector<Record> first;
        if (ref) first.push_back(reference_record(recs[0], plan.reference));
        rq.period = ref ? find_period(first, rep, "reference") : find_period(recs, rep);
        if (plan.report) plan.report("--period auto: " + rep + "\n");
    }
    if (!plan.direct && rq.period >= MSID_MIN_PERIOD && rq.period <= MSID_MAX_PERIOD)
        check_periodic_inputs(rq.period, rq.skip, rq.bins, recs);
    if (plain_checks) check_records(rq, recs);
    rq.inputs_checked = !plan.direct;
}

// `bins` (ascending) as runs of neighbours (joins(i): bins[i] continues the run of bins[i - 1]), as
// frequency ranges when the rate is known (else as bins); a long list is cut after its first runs:
// the file holds every bin (lines_auto.`member`).
static std::string bin_ranges(const FrfRequest &rq, const std::vector<uint32_t> &bins,
                              const std::function<bool(size_t)> &joins, const char *member)
{
    constexpr size_t SHOWN = 12;
    std::vector<std::string> runs;
    for (size_t i = 0; i < bins.size();) {
        size_t e = i;
        while (e + 1 < bins.size() && joins(e + 1)) ++e;
        if (rq.fs > 0) {
            const double f0 = bins[i] * rq.fs / rq.period, f1 = bins[e] * rq.fs / rq.period;
            runs.push_back(e > i ? fmt("%.4g-%.4g Hz", f0, f1) : fmt("%.4g Hz", f0));
        } else {
            runs.push_back(e > i ? fmt("bins %u-%u", bins[i], bins[e]) : fmt("bin %u", bins[i]));
        }
        i = e + 1;
    }
    std::string where;
    for (size_t k = 0; k < std::min(runs.size(), SHOWN); ++k) where += (k ? ", " : "") + runs[k];
    if (runs.size() > SHOWN)
        where += fmt(" and %zu more ranges (every bin in the file's lines_auto.%s)", runs.size() - SHOWN, member);
    return where;
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
    const std::string where = bin_ranges(rq, u.bins, [&](size_t i) { return u.bins[i] - u.bins[i - 1] == u.step; },
                                         "undecided_bins");
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
        if (!plan.reference.empty()) throw UsageError(MSID_OPT("reference") " applies to " MSID_OPT("lines") " auto (and " MSID_OPT("method") " lpm)");
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

FrfOutcome frf_without_unusable_lines(FrfRequest &rq, const FrfPlan &plan, DroppedLines &dropped,
                                      const std::function<FrfOutcome()> &run)
{
    // the first pass on every line found screens them (FrfRequest::screen_lines); the passes after it
    // leave out only what the core cannot use
    rq.screen_lines = plan.auto_lines && rq.omega.empty();
    struct Unscreen {
        FrfRequest &rq;
        ~Unscreen() { rq.screen_lines = false; }
    } unscreen{rq};
    for (;;) {   // each pass drops at least one line
        try {
            return run();
        } catch (const UnusableLines &u) {
            rq.screen_lines = false;
            if (!plan.auto_lines || !rq.omega.empty()) throw;   // given lines (a design's) are refused
            const size_t L = rq.bins.size();
            if (u.weak.size() + u.dependent.size() >= L)
                throw Error(fmt(MSID_OPT("lines") " auto: none of the %zu line(s) found leaves the FRF enough input (%s)", L, u.what()));
            std::vector<uint8_t> out(L, 0);
            for (uint32_t l : u.weak) {
                out[l] = 1;
                dropped.weak.push_back(rq.bins[l]);
            }
            for (uint32_t l : u.dependent) {
                out[l] = 1;
                dropped.dependent.push_back(rq.bins[l]);
            }
            std::vector<uint32_t> kept;
            for (size_t l = 0; l < L; ++l)
                if (!out[l]) kept.push_back(rq.bins[l]);
            rq.bins = std::move(kept);
        }
    }
}

void report_dropped_lines(const FrfRequest &rq, const FrfPlan &plan, const std::vector<uint32_t> &found,
                          const DroppedLines &d, Json &block, std::vector<std::string> &notes)
{
    if (d.empty()) return;
    std::vector<uint32_t> weak = d.weak, dep = d.dependent, all;
    std::sort(weak.begin(), weak.end());
    std::sort(dep.begin(), dep.end());
    std::merge(weak.begin(), weak.end(), dep.begin(), dep.end(), std::back_inserter(all));
    if (!block.is_null()) {
        block["unusable_bins"] = all;
        block["unusable_rule"] = "the FRF's excitation test: the weakest input direction at least 10 dB above the noise "
                                 "of the period means and above 1e-20 of the strongest line's power, the input matrix's "
                                 "condition number below 1e12";
    }
    // runs of lines that neighbour each other among the found ones
    std::vector<size_t> pos(found.empty() ? 0 : found.back() + 1, 0);
    for (size_t i = 0; i < found.size(); ++i) pos[found[i]] = i;
    auto ranges = [&](const std::vector<uint32_t> &b) {
        return bin_ranges(rq, b, [&](size_t i) { return pos[b[i]] == pos[b[i - 1]] + 1; }, "unusable_bins");
    };
    std::string text = fmt("--lines auto: %zu of the %zu line(s) found are left out of the FRF:", all.size(), found.size());
    if (!weak.empty())
        text += fmt(" the input is too weak at %s%s. There the weakest input direction is less than 10 dB above the "
                    "noise of its period mean (or below 1e-20 of the strongest line), where the ratio of the averaged "
                    "spectra is biased and its covariance does not hold%s; more periods, or more excitation there, "
                    "bring them back",
                    ranges(weak).c_str(), dep.empty() ? "" : fmt(" (%zu lines)", weak.size()).c_str(),
                    plan.reference.empty() ? ""
                                           : " (the reference excites them, but in closed loop the controller and the "
                                             "noise inside the loop, not the reference, set the plant's input)");
    if (!dep.empty())
        text += fmt("%s the experiments do not drive the inputs independently at %s%s", weak.empty() ? "" : ";",
                    ranges(dep).c_str(), weak.empty() ? "" : fmt(" (%zu lines)", dep.size()).c_str());
    notes.push_back(text);
}

// Step 4: one realisation with detection lines: the distortion level beside the noise.
void add_detection_distortion(FrfOutcome &o)
{
    const Json nl = detection_distortion(o.doc.is_null() ? detection_summary(o.frf) : o.doc);
    if (nl.is_null()) return;
    o.tail()["nonlinear_distortion"] = nl;
    if (nl["distortion_detected"].get<bool>())
        o.notes.push_back("the detection lines show nonlinear distortion (" +
                          (nl["nl_to_noise_db"].is_number() ? fmt("%.1f dB", nl["nl_to_noise_db"].get<double>())
                                                             : std::string("?")) +
                          " relative to the noise); cov holds the noise only: measure several realisations "
                          "(--realisations R) to include it");
}

FrfOutcome estimate_frf(FrfRequest &rq, const std::vector<Record> &recs, const FrfPlan &plan)
{
    check_plan(rq, plan);
    if (plan.direct && !plan.design) throw std::logic_error("estimate_frf: direct without the design (FrfPlan::design)");
    FrfOutcome o;
    Json lines_auto;
    std::string undecided;
    std::vector<uint32_t> found;
    DroppedLines dropped;
    names_from_records(rq, recs);
    try {
        check_inputs(rq, recs, plan);
        find_lines_if_asked(rq, recs, plan, lines_auto, undecided);
        // Step 3: the estimator
        found = rq.bins;
        o = plan.direct ? run_frf_direct(rq, *plan.design, recs)
            : plan.bla  ? run_frf_realisations(rq, recs, plan.realisations)
                        : frf_without_unusable_lines(rq, plan, dropped, [&] { return run_frf(rq, recs); });
    } catch (...) {
        // a record taken without its NaN/Inf scan (Record::finite_unchecked): the reader's message
        // comes first, as when the reader scanned, whatever the run found later (the first bad record)
        for (const Record &r : recs)
            if (r.finite_unchecked) check_finite(r, 0, r.n_rows);
        throw;
    }
    if (!plan.direct && !plan.bla) add_detection_distortion(o);
    report_dropped_lines(rq, plan, found, dropped, lines_auto, o.notes);
    if (!lines_auto.is_null()) o.tail()["lines_auto"] = lines_auto;
    if (!undecided.empty()) o.notes.push_back("--lines auto: " + undecided);
    return o;
}

}  // namespace msidjob
