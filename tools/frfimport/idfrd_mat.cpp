// An idfrd-shaped MATLAB .mat (ResponseData ny x nu x L complex, Frequency, Ts, ...): not read yet.
// msid's own v5 reader (tools/records/mat_v5.cpp) reads real 2-D matrices only; complex N-D arrays
// and cell arrays of char need it extended first (libmatio alone sizes buffers from unchecked fields).
#include "frf_import.hpp"

namespace msidfrfimport {

Imported read_idfrd_mat(const std::string &path)
{
    throw Error("'" + path + "': importing an idfrd-shaped .mat is not implemented yet (export it as CSV: "
                "docs/frf-format.md, \"CSV\")");
}

}  // namespace msidfrfimport
