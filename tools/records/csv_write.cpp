// The CSV writer: samples that read back bit for bit.
#include "records_detail.hpp"

#include <charconv>

namespace msidrec {

std::string format_csv(const std::vector<std::string> &header, const double *rows, size_t n, size_t cols)
{
    std::string s;
    for (size_t c = 0; c < header.size(); ++c) { if (c) s += ','; s += header[c]; }
    s += '\n';
    s.reserve(s.size() + n * cols * 24);
    char buf[64];
    for (size_t k = 0; k < n; ++k) {
        for (size_t c = 0; c < cols; ++c) {
            if (c) s += ',';
            auto res = std::to_chars(buf, buf + sizeof buf, rows[k * cols + c]);  // shortest round-trip
            s.append(buf, res.ptr);
        }
        s += '\n';
    }
    return s;
}

}  // namespace msidrec
