#include "frf_io.hpp"

#include <cmath>

namespace msidcli {

// The first number in `j` that is NaN or infinite (JSON would write it as null), by its path; "" if none.
static std::string nonfinite_at(const Json &j, const std::string &at)
{
    if (j.is_number_float()) return std::isfinite(j.get<double>()) ? "" : (at.empty() ? "/" : at);
    if (j.is_object())
        for (auto it = j.begin(); it != j.end(); ++it) {
            std::string p = nonfinite_at(it.value(), at + "/" + it.key());
            if (!p.empty()) return p;
        }
    if (j.is_array())
        for (size_t i = 0; i < j.size(); ++i) {
            std::string p = nonfinite_at(j[i], at + "/" + std::to_string(i));
            if (!p.empty()) return p;
        }
    return "";
}

void write_json_file(const std::string &path, const Json &doc)
{
    // A result is never written with a silent null for NaN/Inf (it would fail the schema): one message, no file.
    const std::string bad = nonfinite_at(doc, "");
    if (!bad.empty())
        throw Error("'" + path + "' not written: the result is not finite at " + bad +
                    " (inputs beyond double precision's range, e.g. data scaled near 1e150 or a sample rate near 0)");
    std::string s = doc.dump(1);
    s += '\n';
    write_file_atomic(path, s);
}

}  // namespace msidcli
