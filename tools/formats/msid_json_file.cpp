// JSON documents on disk: read with the file named in every error, checked accessors, and the
// atomic writer (no partial file, no NaN or Inf written).
#include "msid_json_file.hpp"
#include "frf_file.hpp"

#include <cmath>

namespace msidfmt {

using msidutil::write_file_atomic;

Json read_json_file(const std::string &path)
{
    try {
        return msidfrf::read_json(path);
    } catch (const msidfrf::IoError &e) {   // missing, unreadable, a directory
        throw Error(e.what(), msidutil::ErrorKind::io);
    } catch (const msidfrf::Error &e) {
        throw Error(e.what(), msidutil::ErrorKind::data);
    }
}

const Json &jget(const Json &o, const std::string &key, const std::string &file)
{
    if (!o.is_object()) throw Error("'" + file + "': expected a JSON object");
    auto it = o.find(key);
    if (it == o.end()) throw Error("'" + file + "': missing '" + key + "'");
    return *it;
}

uint64_t juint(const Json &o, const std::string &key, const std::string &file)
{
    const Json &v = jget(o, key, file);
    if (!v.is_number_unsigned() && !(v.is_number_integer() && v.get<int64_t>() >= 0))
        throw Error("'" + file + "': '" + key + "' must be a non-negative integer");
    return v.get<uint64_t>();
}

uint32_t juint32(const Json &o, const std::string &key, const std::string &file)
{
    const uint64_t v = juint(o, key, file);
    if (v > 0xFFFFFFFFull) throw Error("'" + file + "': '" + key + "' = " + std::to_string(v) + " is out of range");
    return (uint32_t)v;
}

double jnum(const Json &v, const std::string &what, const std::string &file)
{
    if (!v.is_number()) throw Error("'" + file + "': " + what + " must be a number");
    double x = v.get<double>();
    if (!std::isfinite(x)) throw Error("'" + file + "': " + what + " is not finite");
    return x;
}

std::string nonfinite_at(const Json &j, const std::string &at)
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

void write_json_file(const std::string &path, const Json &doc, bool durable)
{
    // A result is never written with a silent null for NaN/Inf (it would fail the schema): one message, no file.
    // The text is nlohmann's dump(1) layout with std::to_chars' shortest round-trip numbers (msidfrf::dump).
    std::string s;
    s.reserve(1 << 16);
    try {
        msidfrf::dump(doc, 1, s, true);
    } catch (const msidfrf::NonFinite &) {
        throw Error("'" + path + "' not written: the result is not finite at " + nonfinite_at(doc, "") +
                    " (inputs beyond double precision's range, e.g. data scaled near 1e150 or a sample rate near 0)");
    }
    s += '\n';
    write_file_atomic(path, s, durable);
}

}  // namespace msidfmt
