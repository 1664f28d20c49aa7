// msid_frfjob: the FRF job of every host path (files, arrays from Python, msid measure):
// records -> msid_meas (line DFT + period statistics) -> msid_frf -> msid-frf/1.
// No command-line types: errors are msidjob::Error (bad records or request) and
// msidutil::UsageError (conflicting settings).
#pragma once
#include "msid_records.hpp"
#include "msid_design_file.hpp"
#include "msid_host_util.hpp"
#include "frf_text.hpp"
#include "msid_frf_result.hpp"

#include <functional>

namespace msidjob {

// A problem with the records or the request: one message naming the source.
struct Error : msidutil::Error {
    explicit Error(const std::string &m, msidutil::ErrorKind k = msidutil::ErrorKind::data)
        : msidutil::Error(m, 1, k) {}
};
using msidutil::UsageError;
using msidrec::Record;
using msidfmt::Design;
using msidfmt::Json;

}  // namespace msidjob

namespace msidjob {

struct FrfRequest {
    uint32_t period = 0;
    std::vector<uint32_t> bins;          // excited lines
    std::vector<uint8_t> folded;         // CT: line folded (empty for DT)
    std::vector<double> omega;           // CT: rad/s (empty for DT)
    double sample_time = 0.0;            // CT h, or 1/fs when fs is given
    double fs = 0.0;                     // Hz, 0 if not given
    std::vector<uint32_t> detect;        // non-excited lines to report
    uint32_t skip = 0;
    msid_transient_mode transient = MSID_TRANSIENT_FLAG;
    double alpha = 0.01;
    msid_dft_path path = MSID_DFT_AUTO;
    size_t block = 0;                    // rows per push (0: whole record)
    const Design *design = nullptr;      // optional
    // The signals' names and units for the document's header (msidfrf::Header); empty: from the
    // records' column names (names_from_records), or none when those are u1.., y1..
    std::vector<std::string> input_names, output_names, input_units, output_units;
    // check_periodic_inputs() (periodicity.hpp) already ran on the records (msid frf runs it
    // before --lines auto); else run_frf() runs it. FrfJob::finish() always runs
    // check_periodic_lines() on the core's period statistics (every host path).
    bool inputs_checked = false;
    // --lines auto found rq.bins (estimate_frf sets it): FrfJob::finish() also refuses the lines whose
    // neighbours among them leave the input too weak (screened_weak_lines, docs/statistics.md "Closed
    // loop"), listing every line it cannot use, for the caller to leave them out.
    bool screen_lines = false;
};

// The input SNR (of the period mean, dB) below which a line is too weakly excited for the FRF: the
// core's excitation test (lib/src/msid_frf.c) on the line itself, and with FrfRequest::screen_lines the
// median over its neighbours (P 2002, section 5: below it the ratio of the averaged spectra is biased and
// its covariance does not hold).
constexpr double MIN_INPUT_SNR_DB = 10.0;
// The neighbours of a line in that median: this many lines on either side, the line itself left out.
constexpr size_t SCREEN_NEIGHBOURS = 4;

// An estimator's result: the periodic job's typed result (`frf`), or the document of an estimator
// that builds one (--direct, --realisations, lpm, etfe; `doc` not null). tree() turns the typed
// result into its document, for a caller that edits or compares documents.
struct FrfOutcome {
    FrfResult frf;             // the periodic job (FrfJob::finish); empty when `doc` holds the result
    Json doc;                  // msid-frf/1 of the other estimators; null for the periodic job
    std::vector<std::string> notes;      // warnings for stderr
    std::string dft_path;                // "stream" or "fft"

    // The document (built from `frf` once, which is then left empty).
    Json &tree();
    // The members a caller appends after the result's own (lines_auto, a session's acquisition block):
    // frf.tail, or the document.
    Json &tail() { return doc.is_null() ? frf.tail : doc; }
    uint64_t periods_used() const;
    uint64_t periods_rejected() const;
};

// The msid-frf/1 file of an outcome: write_frf_file() of its typed result, or its document
// (msidfmt::write_json_file).
void write_outcome(const std::string &path, const FrfOutcome &o, bool durable = true);

// The signals' names and units from the records' column names (the file's, or those --columns
// mapped), when the request has none: a name "Force [N]" (or "Force (N)") is the signal Force in
// unit N. Nothing is set when every column is u<k>/y<k> or a bare column number (.npy).
void names_from_records(FrfRequest &rq, const std::vector<Record> &recs);

// Fill period/bins/folded/omega/sample_time from a design.
void request_from_design(FrfRequest &rq, const Design &d);
// The same from a core design (no file behind it).
void request_from_core_design(FrfRequest &rq, const msid_design &d);

// The records agree with each other and the request (same columns, m >= nu,
// the design's inputs and experiments). Throws Error. `count` false: all but the number of
// experiments (m >= nu, the design's), for a caller that checks the inputs' periodicity first.
void check_records(const FrfRequest &rq, const std::vector<Record> &recs, bool count = true);

// Validate everything, run the core, give the typed result. Throws Error.
FrfOutcome run_frf(const FrfRequest &rq, const std::vector<Record> &recs);

// The options a caller gave, by their neutral names (MSID_OPT, msid_options.hpp: "detect_lines",
// "alpha"): the rules between options (check_plan, check_est_plan) refuse what does not apply however
// the front end took them (a flag, a keyword), and name it in the front end's words.
struct GivenOptions {
    std::vector<std::string> names;
    void add(const char *id) { names.emplace_back(id); }
    bool has(const char *id) const
    {
        for (const std::string &n : names)
            if (n == id) return true;
        return false;
    }
};

// How estimate_frf() runs the job: what to find from the input, which estimator.
struct FrfPlan {
    bool auto_period = false;          // find the period from the inputs' repetition (rq.period ignored)
    bool auto_lines = false;           // find the excited bins from the input spectrum (rq.bins ignored)
    bool direct = false;               // the direct time-domain LS estimator (needs `design`)
    bool bla = false;                  // the best linear approximation over `realisations` blocks
    uint32_t realisations = 0;         // R (with bla; R < 2 is refused)
    const Design *design = nullptr;    // the design behind rq, if any
    // --lines auto (and with it --period auto) from the excitation's reference instead of the inputs: the
    // columns r1..r_nu of each record's file (names as in the file; one per input), read with the
    // record's first output
    std::vector<std::string> reference;
    // what was found (--period auto, --lines auto), one line or two, as it is found
    std::function<void(const std::string &)> report;
    // the options given ("design", "period", "lines", "fs", "detect_lines", "transient", "alpha", "dft",
    // "block", "realisations", "direct", "reference"): the rules between them (check_plan)
    GivenOptions given;
};

// The request's own rules, every front end's (msid frf, msid.frf): the design or the period and lines,
// what --direct takes (a design, no --realisations, none of the periodic path's options), and the
// ranges of --fs, --block and --alpha. Its messages name the options neutrally (MSID_OPT). estimate_frf()
// and estimate_frf_files() run it first; a front end calls it only to refuse before it reads anything.
// Throws UsageError.
void check_plan(const FrfRequest &rq, const FrfPlan &plan);
// Its part for the estimating options alone (--fs given positive and not with a continuous-time
// `design`, --alpha in (0, 1), --block given positive), for the paths without a plan (a measurement).
void check_options(const FrfRequest &rq, const GivenOptions &given, const Design *design = nullptr);

// The whole FRF job on records, every step once and in one order: the records' shapes, the
// period (plan.auto_period), the inputs' periodicity, the lines (plan.auto_lines), the estimator
// (periodic, realisations' BLA or direct), and for one realisation with detection lines the
// nonlinear distortion level (o.doc["nonlinear_distortion"], a note). Throws msidutil::Error
// (msidjob::Error, msidrec::Error, UsageError) with one message.
FrfOutcome estimate_frf(FrfRequest &rq, const std::vector<Record> &recs, const FrfPlan &plan);

// The FRF job on experiment files (msid frf): what estimate_frf() gives on the records the files
// hold. Regular CSV files on the periodic path (one realisation, not --direct) pass through the core
// block by block (CsvStream): memory is one block per file, the first input_check_rows() rows of each
// (the input checks), and the core's per-period statistics (the transient test's history: L x
// (nu + ny) complex values per period, none with --transient off), never the samples; the document is
// the same bits as from the records read whole. --period auto reads the first PERIOD_SEARCH_ROWS rows
// of the first file's inputs (its reference columns when --lines auto takes the lines from them) by a
// stream of its own; --lines auto passes every file once more through
// a LineScan first (its inputs, or the reference columns: plan.reference, else the files' own r1..
// columns when they name one per input). Everything else (.npy/.npz/.mat, a pipe, --realisations,
// --direct), and a record whose input check needs the whole record (an input that is not periodic
// with the period: its period is searched for), is read whole first. Throws as estimate_frf() and
// read_experiments().
struct FilesOutcome {
    FrfOutcome o;
    uint32_t nu = 0, ny = 0, m = 0;
    bool streamed = false;          // the records passed through the core block by block
    std::vector<Record> recs;       // the records read whole (empty when streamed)
};
FilesOutcome estimate_frf_files(FrfRequest &rq, const std::vector<std::string> &paths, const msidrec::ColumnMap &cols,
                                FrfPlan plan);

// What the document reports about where each experiment came from.
struct ExpSource {
    std::string source;        // file name, or e.g. "can:vcan0 experiment 1"
    uint64_t samples = 0;      // samples received or declared missing
    uint64_t periods_total = 0;
    uint64_t leftover = 0;     // samples after the last whole period (not used)
};

// The FRF job in two halves, for sources that feed msid_meas themselves (the
// CAN decoder): the constructor sets the core up (validated request, line DFT
// path, measurement), the caller pushes samples into meas(), and finish()
// checks the period counts, solves the FRF and builds the one msid-frf/1
// document. `history` is the per-experiment period capacity of the transient
// test; `periods` the expected periods per experiment (it enables the test).
// `lanes` (1 or 2) measurement objects, each with its own FFTW plan: experiment
// e is measured on lane e % lanes, so two threads can measure experiments at
// once; every experiment's statistics are the same bits on either lane.
class FrfJob {
public:
    FrfJob(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m, uint32_t periods, uint32_t history,
           uint32_t lanes = 1);
    ~FrfJob();
    FrfJob(const FrfJob &) = delete;
    FrfJob &operator=(const FrfJob &) = delete;
    msid_meas *meas(uint32_t lane = 0);
    uint32_t lanes() const;
    bool streaming() const;   // the line DFT path is the streaming one (a rotation per line per sample)
    FrfOutcome finish(const std::vector<ExpSource> &src, std::vector<std::string> notes = {});

private:
    struct Impl;
    std::unique_ptr<Impl> p_;
};

// The direct time-domain LS FRF (needs a design; records need not be whole periods).
FrfOutcome run_frf_direct(const FrfRequest &rq, const Design &D, const std::vector<Record> &recs);

// The msid-frf/1 header fields (format .. fs_hz) and a line's position fields
// (bin, freq, omega, folded, freq_hz, real) of a request: msidfrf::header() and
// msidfrf::position() (tools/frffile, the one writer of the format).
Json frf_header(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m);
Json line_position(const FrfRequest &rq, size_t l);

// {"re": [[...]], "im": [[...]]} of a rows x cols complex matrix (row-major).
Json cmat_json(const msid_cplx *a, size_t rows, size_t cols);

}  // namespace msidjob
