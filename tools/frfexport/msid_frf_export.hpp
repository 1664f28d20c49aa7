// msid_frfexport: msid's files for other tools. An msid-frf/1 file as CSV (G, the standard deviation
// of each element, dof, frequencies: spreadsheets) or as a MATLAB .mat in the shape of idfrd
// (ResponseData, Frequency, Ts, CovarianceData scaled so that showConfidence's regions are the exact
// 95% regions, SD95, dof, names and units); an msid-model/1 file as the matrices ss and idss take
// (A, B, C, D, Ts, names, units). The files are read with the fitting tools' readers (shapes and
// finiteness checked) and written atomically: a failure leaves no file. docs/python.md "msid export".
// Errors: msidutil::Error (a file that cannot be exported), msidutil::IoError (cannot be written).
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>

namespace msidexport {

struct ExportSummary {
    size_t lines = 0;
    uint32_t ny = 0, nu = 0;
};

// A file whose "format" is msid-model/1 (anything else is taken as an FRF file).
bool is_model_file(const std::string &path);

// The FRF file `frf_path` to `out`; `known_input`: the known-input covariance (cov_known_input)
// instead of the errors-in-variables one. Every line needs that covariance.
ExportSummary export_frf_csv(const std::string &frf_path, const std::string &out, bool known_input);
ExportSummary export_frf_mat(const std::string &frf_path, const std::string &out, bool known_input);

// The model file `model_path` to `out` (.mat).
void export_model_mat(const std::string &model_path, const std::string &out);

}  // namespace msidexport
