// msid_fitjob: `msid fit` as library calls. An FRF (msid-frf/1, read by tools/frffile) or time
// records (tools/records) and one request in, one msid-model/1 document out, with every step of
// the fit in one order here: the command line and the Python extension fill a request, call
// once and write or return the document. No command-line types. docs/fitting.md describes the
// methods and options; docs/model-format.md the document.
#pragma once
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "frf_data.hpp"
#include "frf_file.hpp"
#include "model_io.hpp"
#include "msid_host_error.hpp"
#include "msid_records.hpp"
#include "multi.hpp"

namespace msidfitjob {

using Json = nlohmann::ordered_json;
using msidfrf::FrfData;
using msidrec::Record;

// A fit that cannot be done with these data (exit status 1; Python ValueError). A bad request is
// msidutil::UsageError (exit status 2). The messages are msid fit's.
struct Error : msidutil::Error {
    std::string before;   // what msid prints on stdout before the message (the table of an order scan)
    explicit Error(const std::string &m, std::string b = std::string())
        : msidutil::Error(m, 1, msidutil::ErrorKind::data), before(std::move(b)) {}
};

// Every option of `msid fit --method subspace|lmfd|ml`. Text fields hold the option's value as
// given ("" = not given: the method's default); the document's settings echo them.
struct FitRequest {
    std::string method;                    // subspace | lmfd | ml
    std::string order;                     // n | auto | a:b | a:step:b; "": ml auto, subspace its singular values
    std::optional<uint32_t> nd, nn;        // LMFD degrees (lmfd, ml --param lmfd)
    std::string domain;                    // dt | ct; "": the FRF's
    std::string weight;   // cov | known-input | none; "": cov, or none for an FRF without any covariance
    std::optional<double> noise_var;       // known white output noise variance per sample
    std::optional<uint32_t> r;             // subspace block rows
    bool stable = false;                   // subspace: also reflect unstable poles in the r scan
    bool allow_unstable = false;           // no stability constraint
    bool no_d = false;                     // no direct term (= feedthrough "no")
    std::vector<std::string> pins;         // LMFD entries fixed, "N0=0", ...
    std::string start;                     // ml: subspace | sk (--param lmfd), a model file (--param poles)
    std::optional<uint32_t> max_iter;
    std::optional<double> delta, beta;     // ml --param lmfd bounds, in (0, 1] and (0, 1)
    std::string feedthrough;               // auto | yes | no; "": auto
    std::string param;                     // ml: poles | lmfd; "": poles, lmfd for DT with several inputs
    std::string refine;                    // subspace: ml | none | N steps; "": ml
    std::optional<uint32_t> weight_smooth; // pooled weights over 2H+1 lines
};

// --method cissim: discrete-cISSIM from periodic time records.
struct CissimRequest {
    uint32_t period = 0;                   // samples
    std::vector<uint32_t> lines;           // excited bins, below period / 2
    std::optional<uint32_t> order, max_order, block_rows, lags;
    uint32_t skip_periods = 1;
    bool reduced = false, no_d = false, no_covariance = false, unweighted = false, allow_unstable = false;
    std::string isp = "auto";              // auto | direct | fft
    std::string refine = "ml";             // ml | none
};

// --method multi: maximum likelihood from records of any lengths.
struct MultiRequest {
    std::string order;                     // n | auto | a:b (required)
    std::string order_rule;                // mdl | aic; "": mdl
    std::vector<double> noise_ar;          // c1..cp of the output noise's AR model (empty: white or estimated)
    std::optional<uint32_t> noise_ar_order;
    std::optional<double> input_noise_ratio;
    std::optional<double> fs;              // Hz
    std::string feedthrough = "no";        // no | yes
    std::string start = "auto";            // auto | kung | prony | sm
    std::optional<uint32_t> max_iter;
    std::string columns;                   // the column map the records were read with (echoed in settings)
};

// What a fit gives back: the model document and what msid prints of it. `notes` are the remarks
// on the data or the result ("note: ...", "warning: ..."), also passed to the Report callback as
// they arise. A caller that writes the document to `path` prints
//   before, head + path + tail, after
// and, unless `converged`, the warning not_converged + path + " marked "converged": false ...".
struct FitOutcome {
    Json model;
    std::vector<std::string> notes;
    bool converged = true;
    std::string before, head = "wrote ", tail, after;
    std::string not_converged;
};

using Report = std::function<void(const std::string &note)>;

// subspace | lmfd | ml on an FRF; an order scan (auto, a:b) fits every order and keeps one.
FitOutcome fit_frf(const FrfData &f, const FitRequest &rq, const Report &report = {});

// The order of ml is chosen (auto) when the request names none: no order, no LMFD degrees and no
// model to start from.
bool order_is_scan(const FitRequest &rq);

// cissim on records of `period` samples per period. check_cissim() refuses a bad request before
// any record is read (fit_cissim checks it again).
void check_cissim(const CissimRequest &rq);
FitOutcome fit_cissim(const std::vector<Record> &recs, const CissimRequest &rq, const Report &report = {});

// multi on records (u columns optional: free responses), noise-only records for --noise-ar-order.
// check_multi() refuses a bad request (with noise records or not) before any record is read.
void check_multi(const MultiRequest &rq, bool noise_records);
FitOutcome fit_multi(const std::vector<Record> &recs, const std::vector<Record> &noise_recs, const MultiRequest &rq,
                     const Report &report = {});

// `msid validate MODEL FRF`: the weighted residual cost of the model on the FRF against its law, a
// p-value, per-line normalised residuals, the verdict at 5% and, when the FRF carries it, the noise
// level against the nonlinear distortion level (docs/fitting.md, "Validation").
struct ValidateRequest {
    // cov | known-input | none; unset: known-input for a model fitted with it, else cov, and unit
    // weights only for an FRF without any covariance
    std::optional<msidfit::Weight> weight;
    std::string lpm_lines = "independent";   // independent | all (LPM files)
};
struct ValidateOutcome {
    Json report;                     // the msid-validation/1 document (msid validate -o)
    std::vector<std::string> text;   // what msid validate prints, one line each
    bool consistent = false;         // p-value >= 0.05
    bool has_verdict = true;         // false: an FRF without covariance (no noise scale, no p-value)
};
// The FRF's document (frf_doc, from which f was parsed) carries what the FRF data do not hold: its
// nonlinear-distortion block and detection lines. Throws FitError (the data cannot validate the model)
// or UsageError (lpm_lines).
ValidateOutcome validate_frf(const msidfit::ModelFile &mf, const FrfData &f, const Json &frf_doc,
                             const ValidateRequest &rq = {});
// A free-response model (no inputs, msid fit --method multi) has no FRF: FitError naming the way it is
// validated (on records). validate_frf checks it first; a caller may before it reads the FRF.
void check_model_has_frf(const msidfit::ModelFile &mf);

// `msid validate MODEL --experiment ...`: a model of --method multi (model_doc, named `name`) on time
// records, `lags` (>= 1) lags in the whiteness test. The report is msid-validation/1 with kind
// "records". On the model's own records only the whiteness test counts: `own` says whether they are
// (unset: records named as the model's sources, in order, are).
ValidateOutcome validate_records(const Json &model_doc, const std::string &name, const std::vector<Record> &recs,
                                 int lags = 10, std::optional<bool> own = std::nullopt);
// The model check validate_records() starts with (a multi model with a usable multi section), for a
// caller that reads the records after it.
void check_multi_model(const Json &model_doc, const std::string &name);

// `msid modes MODEL`: natural frequencies, damping ratios and residues of the model's pole pairs
// with standard deviations (a multi model: its shared poles). report: msid-modes/1 (msid modes -o);
// text: what msid modes prints.
struct ModesOutcome {
    Json report;
    std::string text;
};
ModesOutcome modes_of(const Json &model_doc, const std::string &name);

// The records of a multi fit or its validation as its u, y matrices (the same channels in every one).
std::vector<msidfit::MultiRecord> multi_records(const std::vector<Record> &recs);

}  // namespace msidfitjob
