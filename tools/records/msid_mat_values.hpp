// msid_records: whole variables of a MATLAB v5 or v7.3 .mat file (an idfrd-shaped FRF: tools/frfimport),
// v5 read by msid's own reader (mat_v5.cpp), v7.3 through libmatio after check_mat_hdf5
// (mat_values_v73.cpp); every size checked against the file. Errors: msidrec::Error.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace msidrec {

// One variable of a MATLAB .mat file read whole: a numeric array of any rank, real or complex
// (column-major, as doubles), a char row, or a cell array of char rows. What an idfrd-shaped file
// holds (msid export --mat; tools/frfimport). Sizes checked against the file as the v5 reader does.
struct MatValue {
    enum Kind { Numeric, Char, Cells, Other };
    Kind kind = Other;
    std::string name;
    std::vector<uint64_t> dims;
    std::vector<double> re, im;         // Numeric; im empty when real
    std::string text;                   // Char (UTF-16 code units above 127 as '?')
    std::vector<std::string> cells;     // Cells of char rows, column-major
};
// The variables of `path` whose names are in `names` (others are skipped unread). A file that is not
// MATLAB v5 or v7.3 (v4) is one Error.
std::vector<MatValue> read_mat_values(const std::string &path, const std::vector<std::string> &names);

}  // namespace msidrec
