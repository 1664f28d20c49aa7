// Strict CSV reading/writing of experiment records.
#pragma once
#include <string>
#include <vector>
#include <cstdint>

namespace msidcli {

// One experiment record: rows of [u_1..u_nu, y_1..y_ny], one per sample.
struct Record {
    std::string path;
    uint32_t nu = 0, ny = 0;
    size_t n_rows = 0;
    std::vector<double> rows;   // n_rows * (nu + ny)
};

// Read a CSV with a header row. Columns u1..u<nu> are inputs, y1..y<ny>
// outputs; a time column (t, time, n, sample, index) is allowed and ignored.
// Any other problem (missing/empty file, unknown or duplicate column, gaps in
// the numbering, ragged row, non-numeric cell, NaN/Inf) throws Error naming
// the file, line and column.
Record read_record_csv(const std::string &path);

// Format rows (n x cols) with a header; values printed to round-trip exactly.
std::string format_csv(const std::vector<std::string> &header, const double *rows, size_t n, size_t cols);

}  // namespace msidcli
