// msid_records: whole variables of a MATLAB v5 .mat file (an idfrd-shaped FRF: tools/frfimport), read
// by msid's own v5 reader (mat_v5.cpp), every size checked against the file. Errors: msidrec::Error.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace msidrec {

// One variable of a MATLAB v5 .mat file read whole: a numeric array of any rank, real or complex
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
// MATLAB v5 (v4, v7.3) is one Error: this reader is msid's own, every size checked.
std::vector<MatValue> read_mat_values(const std::string &path, const std::vector<std::string> &names);

}  // namespace msidrec
