// msid frf --method lpm --reference r1=COL,...: the reference (command) signals of a
// record for the noisy-input / closed-loop LPM (tools/est/lpm_eiv.hpp).
#pragma once
#include "msid_records.hpp"

#include <string>
#include <vector>

namespace msidrec {

// Parse `r1=Cmd1,r2=Cmd2` (or `r1,r2`: the record's own columns r1, r2) into the
// source column names in order r1..rK; throws UsageError for a malformed item, a
// gap, or a target or column given twice.
std::vector<std::string> parse_reference(const std::string &spec);

// Rows [r_1..r_nr, y_1..y_ny, u_1..u_nu] (n_rows x (nr + ny + nu)) of `rec` (read from
// rec.path with the usual column map) and its reference columns `ref`, read from the
// same file. Throws Error naming the file and the missing column, or nr != nu.
std::vector<double> rows_with_reference(const Record &rec, const std::vector<std::string> &ref);

// The record's own reference columns: r1..r_nu (or R1..) among the file's columns
// (Record::file_columns), as named there; empty unless the file names all of them.
std::vector<std::string> own_reference_columns(const Record &rec);

}  // namespace msidrec
