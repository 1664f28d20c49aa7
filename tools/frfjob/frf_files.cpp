// The FRF job on experiment files: CSV records streamed through the core block by block where the
// job allows it (estimate_frf_files in msid_frf_job.hpp), else the records read whole and
// estimate_frf(). Either way the same checks run in the same order on the same rows, and the core
// gives the same bits whatever block sizes are pushed (lib/: msid_meas), so the document is the
// same.
#include "frf_job_detail.hpp"
#include "msid_cancel.hpp"
#include "frf_distortion.hpp"
#include "msid_reference.hpp"
#include "periodicity.hpp"

#include <algorithm>
#include <cstring>
#include <exception>
#include <sys/stat.h>
#include <system_error>
#include <thread>

namespace msidjob {

namespace {

bool regular_file(const std::string &p)
{
    struct stat st;
    return ::stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

// One experiment file on the streaming path: its stream and its first rows.
struct Source {
    std::unique_ptr<msidrec::CsvStream> in;
    Record head;   // info() and the first input_check_rows() rows (the whole record when short)
};

// The rest of sources [0, n) read to their ends, in file order, the rows dropped: a problem in
// the files is named before any other (the first bad file in --experiment order), as when the
// records are read whole before anything else happens. Only on the way to an error.
void read_rest(std::vector<Source> &src, size_t n)
{
    msidrec::Samples scratch;
    for (size_t e = 0; e < n && e < src.size(); ++e) {
        msidrec::CsvStream *in = src[e].in.get();
        if (!in) continue;
        const size_t C = in->info().nu + in->info().ny;
        while (!in->at_end())
            in->next([&](size_t max_rows) {
                if (scratch.size() < max_rows * C) scratch.resize(max_rows * C);
                return scratch.data();
            });
    }
}

// Reads s's stream on until its head holds `want` rows (or the stream ends).
void read_head(Source &s, size_t want)
{
    const size_t C = s.head.nu + s.head.ny;
    if (!s.in->at_end() && want > s.head.n_rows) {
        // room for the rows asked (bounded by the file's size) at once: a vector grown block by block
        // would hold up to twice them, and both copies while it moves
        const uint64_t row_min = std::max<size_t>(2 * C, s.head.file_columns.size());
        const uint64_t fit = s.in->file_size() ? s.in->file_size() / row_min + 1 : want;
        s.head.rows.reserve((size_t)std::min<uint64_t>(want + s.in->max_block_rows(), fit) * C);
    }
    while (!s.in->at_end() && s.head.n_rows < want) {
        s.in->next([&](size_t max_rows) {
            s.head.rows.resize((s.head.n_rows + max_rows) * C);
            return s.head.rows.data() + s.head.n_rows * C;
        });
        s.head.n_rows = s.in->rows();
    }
    s.head.rows.resize(s.head.n_rows * C);
    s.head.general_lines = s.in->general_lines();
}

// Step 1: every file's header and first `want` rows, in file order (the first bad file is named first).
std::vector<Source> open_sources(const std::vector<std::string> &paths, const msidrec::ColumnMap &cols, size_t want)
{
    // one file: each block parsed by two threads; several: one file per lane thread (as read_experiments)
    const uint32_t m = (uint32_t)paths.size();
    const bool two = m >= 2 && std::thread::hardware_concurrency() >= 2;
    std::vector<Source> src(m);
    std::vector<uint8_t> failed(m, 0);
    try {
        on_lanes(m, two ? 2 : 1, [&](uint32_t, uint32_t e) {
            try {
                Source &s = src[e];
                s.in = std::make_unique<msidrec::CsvStream>(paths[e], cols, !two);
                s.head = s.in->info();
                read_head(s, want);
            } catch (...) {
                failed[e] = 1;
                throw;
            }
        });
    } catch (...) {
        // the first failing file in order: every file before it was opened; a problem further on in
        // one of them comes first
        const std::exception_ptr x = std::current_exception();
        const size_t first = (size_t)(std::find(failed.begin(), failed.end(), 1) - failed.begin());
        read_rest(src, first);
        std::rethrow_exception(x);
    }
    return src;
}

// Every head read on to `want` rows, in file order; a file that fails is closed (read_rest skips
// it) after the files before it were read to their ends (a problem further on in one of them comes
// first, as in open_sources).
void extend_heads(std::vector<Source> &src, size_t want)
{
    for (size_t e = 0; e < src.size(); ++e) {
        try {
            read_head(src[e], want);
        } catch (...) {
            src[e].in.reset();
            const std::exception_ptr x = std::current_exception();
            read_rest(src, e);
            std::rethrow_exception(x);
        }
    }
}

// --period auto on the streaming path: find_period() on the first PERIOD_SEARCH_ROWS rows of the first
// file (its inputs, or its reference columns when --lines auto takes the lines from them), as the whole
// record gives them, read by a stream of its own (freed before the FRF's pass).
// find_period reads only the inputs, so only they are kept: the stream parses the inputs and the first
// output (a record has an output), and each block's inputs are copied out of one block-sized buffer.
// A logger's many channels cost nothing here, and a SISO prefix takes half the memory.
uint32_t stream_find_period(const Record &info, const FrfPlan &plan)
{
    // from the excitation's reference when the lines come from it (as estimate_frf()): exactly periodic
    const bool ref = plan.auto_lines && !plan.reference.empty();
    if (ref && plan.reference.size() != info.nu)
        throw UsageError(fmt(MSID_OPT("reference") " names %zu column(s) for %u input(s): one reference per input",
                             plan.reference.size(), info.nu));
    msidrec::ColumnMap mc;
    for (uint32_t k = 0; k < info.nu; ++k)
        mc.map.emplace_back(fmt("u%u", k + 1), ref ? plan.reference[k] : info.columns.at(k));
    mc.map.emplace_back("y1", info.columns.at(info.nu));
    const size_t nu = info.nu, C = nu + 1;
    Record head;
    head.path = info.path;
    head.nu = info.nu;   // ny = 0: inputs only
    if (ref) head.columns = plan.reference;
    else head.columns.assign(info.columns.begin(), info.columns.begin() + info.nu);
    {   // the stream and its block closed before the search
        msidrec::CsvStream in(info.path, mc, true);
        // room for the rows searched (bounded by the file's size, as read_head)
        const uint64_t fit = in.file_size() ? in.file_size() / (2 * C) + 1 : PERIOD_SEARCH_ROWS;
        head.rows.reserve((size_t)std::min<uint64_t>(PERIOD_SEARCH_ROWS, fit) * nu);
        std::vector<double> block;
        while (!in.at_end() && head.n_rows < PERIOD_SEARCH_ROWS) {
            const size_t n = in.next([&](size_t max_rows) {
                block.resize(max_rows * C);
                return block.data();
            });
            const size_t take = std::min(n, PERIOD_SEARCH_ROWS - head.n_rows);
            for (size_t i = 0; i < take; ++i) head.rows.insert(head.rows.end(), &block[i * C], &block[i * C] + nu);
            head.n_rows += take;
        }
    }
    std::string rep;
    std::vector<Record> first;
    first.push_back(std::move(head));   // moved: an initializer list would copy the rows
    const uint32_t P = find_period(first, rep, ref ? "reference" : "input");
    if (plan.report) plan.report("--period auto: " + rep + "\n");
    return P;
}

// --lines auto on the streaming path: each file read once more by a stream of its own, from its first
// row (the FRF's streams stay where the input checks left them), the inputs' (or the reference
// columns') whole periods after the skipped ones through a LineScan; files on two lanes, each file's
// scan the same bits on either. `ref_rows[e]`: the rows the reference stream read (with a reference).
std::vector<LineScan> scan_lines(const FrfRequest &rq, const std::vector<std::string> &paths,
                                 const msidrec::ColumnMap &cols, const std::vector<Source> &src,
                                 const std::vector<std::string> &reference, std::vector<size_t> &ref_rows)
{
    const uint32_t m = (uint32_t)paths.size(), P = rq.period, nu = src.at(0).head.nu;
    check_lines_period(P);
    if (!reference.empty() && reference.size() != nu)
        throw UsageError(fmt(MSID_OPT("reference") " names %zu column(s) for %u input(s): one reference per input",
                             reference.size(), nu));
    std::vector<LineScan> scans;
    for (uint32_t e = 0; e < m; ++e) scans.emplace_back(P, nu, paths[e]);
    ref_rows.assign(m, 0);
    const uint32_t lanes = m >= 2 && std::thread::hardware_concurrency() >= 2 ? 2 : 1;
    on_lanes(m, lanes, [&](uint32_t, uint32_t e) {
        msidrec::ColumnMap mc = cols;
        if (!reference.empty()) {   // as reference_records(): r_k as input k, with the first output
            mc = msidrec::ColumnMap();
            for (size_t k = 0; k < reference.size(); ++k) mc.map.emplace_back(fmt("u%zu", k + 1), reference[k]);
            mc.map.emplace_back("y1", src[e].head.columns.at(nu));
        }
        msidrec::CsvStream in(paths[e], mc, lanes == 1);
        const size_t C = in.info().nu + in.info().ny;
        msidrec::Samples buf;
        size_t carry = 0, period = 0;   // rows held back (less than a period); periods seen
        while (!in.at_end()) {
            const size_t n = in.next([&](size_t max_rows) {
                if (buf.size() < (carry + max_rows) * C) buf.resize((carry + max_rows) * C);
                return buf.data() + carry * C;
            });
            const size_t rows = carry + n, w = rows / P;
            for (size_t p = 0; p < w; ++p, ++period)
                if (period >= rq.skip) scans[e].push(buf.data() + p * P * C, C);
            carry = rows - w * P;
            if (w && carry) std::memmove(buf.data(), buf.data() + w * P * C, carry * C * sizeof(double));
        }
        ref_rows[e] = in.rows();
    });
    return scans;
}

// The periods a record still being read may hold: a bound from the file's size (every row takes at
// least max(columns, 2 C) bytes). The core's history is the smaller of this and its cap (FrfJob).
uint64_t period_bound(const Source &s, const FrfRequest &rq)
{
    const Record &h = s.head;
    const uint64_t row_min = std::max<size_t>(2 * (h.nu + h.ny), h.file_columns.size());
    return std::min<uint64_t>((s.in->file_size() / row_min + 1) / rq.period + 1, MAX_RECORD_PERIODS);
}

// Step 2: the checks of the whole path on the first rows (they read no further: periodicity.hpp),
// and the period counts of the records read to their end (the lines checked when known, else after
// --lines auto). Returns the history the core needs, or 0 when the whole records are needed after all.
uint32_t check_sources(FrfRequest &rq, std::vector<Source> &src, bool lines_known)
{
    std::vector<Record> heads;
    for (Source &s : src) heads.push_back(std::move(s.head));
    struct Restore {   // the first rows go back to their sources, whatever is thrown
        std::vector<Record> &h;
        std::vector<Source> &s;
        ~Restore()
        {
            for (size_t e = 0; e < s.size(); ++e) s[e].head = std::move(h[e]);
        }
    } restore{heads, src};
    const uint32_t P = rq.period;
    names_from_records(rq, heads);
    check_records(rq, heads, false);
    for (size_t e = 0; e < src.size(); ++e)
        if (!src[e].in->at_end() && input_check_needs_whole(P, rq.skip, rq.bins, heads[e])) return 0;
    check_periodic_inputs(P, rq.skip, rq.bins, heads);
    rq.inputs_checked = true;
    check_records(rq, heads);
    if (lines_known) validate_lines(rq);
    uint64_t maxK = 0;
    for (size_t e = 0; e < src.size(); ++e) {
        const Record &r = heads[e];
        // a record read to its end: run_frf's checks; else a bound
        maxK = std::max(maxK, src[e].in->at_end() ? record_periods(r, rq) : period_bound(src[e], rq));
    }
    return (uint32_t)maxK;
}

// Pushes whole periods of `buf` (rows x C) to the core in pushes of at most `block` rows (0: all),
// a checkpoint after each push of at most 256 KiB (a caller's token may end a long file early);
// returns the rows pushed.
size_t push_periods(msid_meas &ms, const double *buf, size_t rows, size_t C, uint32_t P, size_t block,
                    const std::string &path)
{
    const size_t w = rows / P * P, cap = std::max<size_t>(1, ((size_t)256 << 10) / (8 * C));
    const size_t blk = std::min(block ? block : std::max<size_t>(w, 1), cap);
    for (size_t k = 0; k < w; k += blk) {
        const size_t n = std::min(blk, w - k);
        check(msid_meas_push(&ms, buf + k * C, n), "'" + path + "'");
        msidutil::checkpoint(msidutil::Step::rows, n, "the FRF job");
    }
    return w;
}

// Step 3: one experiment through the core: its first rows, then block by block to the file's end;
// the rows after the last whole period are held back (never pushed), as run_frf() does.
ExpSource measure_source(msid_meas &ms, uint32_t e, Source &s, const FrfRequest &rq)
{
    const Record &h = s.head;
    const uint32_t P = rq.period;
    const size_t C = h.nu + h.ny;
    const std::string &path = h.path;
    check(msid_meas_begin(&ms, e), "experiment " + std::to_string(e + 1));
    msidrec::Samples buf;
    size_t carry = h.n_rows, periods = 0;   // rows read, not yet pushed
    {
        const size_t w = push_periods(ms, h.data(), h.n_rows, C, P, rq.block, path);
        periods = w / P;
        carry -= w;
        buf.assign(h.data() + w * C, h.data() + h.n_rows * C);
        s.head.rows = msidrec::Samples();   // the first rows are no longer needed
    }
    while (!s.in->at_end()) {
        const size_t n = s.in->next([&](size_t max_rows) {
            if (buf.size() < (carry + max_rows) * C) {   // a new buffer: only the rows held back move
                msidrec::Samples more;
                more.resize((carry + max_rows + max_rows / 4) * C);
                std::copy(buf.data(), buf.data() + carry * C, more.data());
                buf.swap(more);
            }
            return buf.data() + carry * C;
        });
        const size_t w = push_periods(ms, buf.data(), carry + n, C, P, rq.block, path);
        periods += w / P;
        if (periods > MAX_RECORD_PERIODS) throw Error(fmt("'%s' holds too many periods", path.c_str()));
        carry = carry + n - w;
        if (w && carry) std::memmove(buf.data(), buf.data() + w * C, carry * C * sizeof(double));
    }
    check(msid_meas_end(&ms, nullptr), "'" + path + "'");
    const size_t rows = s.in->rows();
    s.in.reset();   // the file's window is unmapped now
    return {path, rows, rows / P, rows % P};
}

// The streaming path; false when the whole records are needed (nothing reported yet but what --period
// auto found: rq.period holds it). The steps run in estimate_frf()'s order: the files' shapes, the
// period, the input checks, the lines, the estimator, the distortion level.
bool stream_frf(FrfRequest &rq, const std::vector<std::string> &paths, const msidrec::ColumnMap &cols,
                FrfPlan &plan, FilesOutcome &out)
{
    std::vector<Source> src = open_sources(paths, cols, plan.auto_period ? 0 : input_check_rows(rq.period, rq.skip));
    uint32_t maxK;
    Json lines_auto;
    std::string undecided;
    std::vector<size_t> ref_rows;
    try {
        if (plan.auto_period) {
            std::vector<Record> infos;
            for (const Source &x : src) infos.push_back(x.in->info());
            check_records(rq, infos, false);
            if (plan.auto_lines && plan.reference.empty()) plan.reference = msidrec::own_reference_columns(infos[0]);
            rq.period = stream_find_period(src[0].in->info(), plan);
            plan.auto_period = false;   // found: the whole path, if it comes to that, takes it
            extend_heads(src, input_check_rows(rq.period, rq.skip));
        }
        maxK = check_sources(rq, src, !plan.auto_lines);
        if (maxK && plan.auto_lines) {
            if (plan.reference.empty()) plan.reference = msidrec::own_reference_columns(src[0].in->info());
            std::string rep;
            std::vector<double> p_min;
            const std::vector<LineScan> scans = scan_lines(rq, paths, cols, src, plan.reference, ref_rows);
            rq.bins = lines_from_scans(scans, rq.period, rq.skip, rep, &p_min);
            lines_auto_found(rq, plan, rep, p_min, lines_auto, undecided);
            validate_lines(rq);
        }
    } catch (...) {
        read_rest(src, src.size());   // a bad cell anywhere comes first
        throw;
    }
    if (maxK == 0) return false;
    const uint32_t m = (uint32_t)src.size(), nu = src[0].head.nu, ny = src[0].head.ny;
    // Two experiments at once on two lanes (threads), as run_frf(): each experiment's statistics the
    // same bits on either lane; an error is that of the first failing experiment in file order.
    const uint32_t lanes = m >= 2 && std::thread::hardware_concurrency() >= 2 ? 2 : 1;
    std::unique_ptr<FrfJob> jobp;
    const std::vector<uint32_t> found = rq.bins;
    DroppedLines dropped;
    bool again = false;
    auto run = [&] {
        // lines --lines auto found that the FRF cannot use were left out: the files once more, from their first row
        if (again) src = open_sources(paths, cols, 0);
        again = true;
        jobp = std::make_unique<FrfJob>(rq, nu, ny, m, maxK, maxK, lanes);
        std::vector<ExpSource> done(m);
        on_lanes(m, lanes, [&](uint32_t lane, uint32_t e) { done[e] = measure_source(*jobp->meas(lane), e, src[e], rq); });
        for (uint32_t e = 0; e < m && !ref_rows.empty() && !plan.reference.empty(); ++e)
            if (ref_rows[e] != done[e].samples)
                throw Error(fmt("'%s': the reference columns have %zu rows, the inputs and outputs %zu", paths[e].c_str(),
                                ref_rows[e], (size_t)done[e].samples));
        std::vector<std::string> notes;
        for (const ExpSource &x : done)
            if (x.leftover)
                notes.push_back(fmt("'%s': %llu samples after the last whole period are not used", x.source.c_str(),
                                    (unsigned long long)x.leftover));
        return jobp->finish(done, notes);
    };
    out.o = frf_without_unusable_lines(rq, plan, dropped, run);
    add_detection_distortion(out.o);
    report_dropped_lines(rq, plan, found, dropped, lines_auto, out.o.notes);
    if (!lines_auto.is_null()) out.o.tail()["lines_auto"] = lines_auto;
    if (!undecided.empty()) out.o.notes.push_back("--lines auto: " + undecided);
    out.nu = nu;
    out.ny = ny;
    out.m = m;
    out.streamed = true;
    return true;
}

}  // namespace

FilesOutcome estimate_frf_files(FrfRequest &rq, const std::vector<std::string> &paths, const msidrec::ColumnMap &cols,
                                FrfPlan plan)
{
    check_plan(rq, plan);   // before any file is opened
    FilesOutcome out;
    const bool plain = !plan.direct && !plan.bla && !plan.auto_period && !plan.auto_lines;
    // --reference without --lines auto is refused by estimate_frf()
    bool stream = !plan.direct && !plan.bla && !paths.empty() && (plan.auto_lines || plan.reference.empty()) &&
                  (plan.auto_period || (rq.period >= MSID_MIN_PERIOD && rq.period <= MSID_MAX_PERIOD));
    for (const auto &p : paths) stream = stream && msidrec::is_csv_path(p) && regular_file(p);
    if (stream && stream_frf(rq, paths, cols, plan, out)) return out;
    // the records whole: a .npy used in place, scanned for NaN/Inf block by block on the plain path
    out.recs = msidrec::read_experiments(paths, cols, true, plain);
    if (plan.auto_lines && plan.reference.empty()) plan.reference = msidrec::own_reference_columns(out.recs.at(0));
    out.o = estimate_frf(rq, out.recs, plan);
    out.nu = out.recs[0].nu;
    out.ny = out.recs[0].ny;
    out.m = (uint32_t)out.recs.size();
    return out;
}

}  // namespace msidjob
