// The FRF job shared by `msid frf`, `msid demo` and `msid bench`:
// records -> msid_meas (line DFT + period statistics) -> msid_frf -> msid-frf/1.
#pragma once
#include "csv_io.hpp"
#include "design_io.hpp"

namespace msidcli {

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
};

struct FrfOutcome {
    Json doc;                  // msid-frf/1
    std::vector<std::string> notes;      // warnings for stderr
    std::string dft_path;                // "stream" or "fft"
};

// Fill period/bins/folded/omega/sample_time from a design.
void request_from_design(FrfRequest &rq, const Design &d);

// Validate everything, run the core, build the document. Throws Error.
FrfOutcome run_frf(const FrfRequest &rq, const std::vector<Record> &recs);

// {"re": [[...]], "im": [[...]]} of a rows x cols complex matrix (row-major).
Json cmat_json(const msid_cplx *a, size_t rows, size_t cols);

}  // namespace msidcli
