// The FRF of arbitrary records (msid frf --method lpm | etfe, msid.frf(method="lpm" | "etfe")):
// records -> tools/est (local polynomial method, ETFE with its finite-sample bound) -> msid-frf/1.
// Every check runs here, once, with the command line's messages; no command-line types.
#pragma once
#include "msid_frf_job.hpp"

#include <optional>

namespace msidjob {

struct EstPlan {
    enum class Method { lpm, etfe };
    Method method = Method::lpm;
    // Lines in [f1, f2]: Hz when the request has fs > 0, else cycles/sample (0 <= f1 < f2 <= Nyquist).
    // Not given: every line but DC. `band_text` is the band as the caller wrote it, for messages.
    bool band = false;
    double f1 = 0, f2 = 0;
    std::string band_text;
    // lpm: polynomial degree R (0..8, default 2), half-width W (>= 1, default the smallest W with
    // dof >= n_outputs + 4), and the reference signals of noisy inputs or a closed loop, one per input
    std::optional<uint32_t> order, window;
    std::vector<std::string> reference;   // the records' file columns (rows_with_reference)
    // or the reference samples themselves: one n_rows x n_inputs row-major array per record
    std::vector<const double *> reference_rows;
    // etfe: input period M in samples (required), failure probability delta in (0, 1) (default 0.05),
    // ||G||_* >= 0 (default 0: the transient term left out)
    std::optional<uint32_t> period;
    std::optional<double> delta, gstar;
    // threads over the bins (1..64; 0: up to 2). The bits do not depend on it.
    uint32_t threads = 0;
    // the options given, by their neutral names ("threads", "fs"): a given value out of range is refused
    GivenOptions given;
};

// "lpm" / "etfe" -> Method; UsageError "--method must be periodic, lpm or etfe (got 'x')" otherwise.
EstPlan::Method est_method(const std::string &name);

// The plan's own checks (what applies to which method, ranges, --fs given positive, the band below
// Nyquist of `fs`, 0 if not given), before any record is read; estimate_frf_est() runs them too.
// Throws UsageError naming the options neutrally (MSID_OPT).
void check_est_plan(const EstPlan &p, double fs);

// Reference columns named without a column map: only the files' own r1.. (or R1..) can be found
// (a record read without a map knows only u<k>, y<k>, r<k> and time). Throws UsageError otherwise.
void check_reference_columns(const std::vector<std::string> &reference, const msidrec::ColumnMap &cols);

// The msid-frf/1 document of the records' FRF by plan.method (header from rq: fs, names; its
// "period" is the record length N, every estimated bin a line). The records must have equal
// columns and length. Throws Error for the records (naming the file) and UsageError for the plan.
// The LPM gives one line per DFT bin of its band: a band whose document would not fit in memory
// is refused (check_document_memory).
FrfOutcome estimate_frf_est(FrfRequest &rq, const std::vector<Record> &recs, const EstPlan &plan);

}  // namespace msidjob
