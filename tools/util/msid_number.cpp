// Strict parsing of the numbers a request carries as text (an option value, a keyword given as a
// string), with the option named in every message: the command line and the libraries that take
// such text (the fit job's --order) say the same thing about the same value.
#include "msid_host_util.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <vector>

namespace msidutil {

std::string trim(const std::string &s)
{
    size_t a = 0, b = s.size();
    while (a < b && (s[a] == ' ' || s[a] == '\t')) ++a;
    while (b > a && (s[b - 1] == ' ' || s[b - 1] == '\t')) --b;
    return s.substr(a, b - a);
}

double parse_double(const std::string &s0, const std::string &what)
{
    std::string s = trim(s0);
    double v = 0;
    auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || r.ec != std::errc() || r.ptr != s.data() + s.size())
        throw UsageError(what + ": '" + s0 + "' is not a number");
    if (!std::isfinite(v)) throw UsageError(what + ": '" + s0 + "' is not finite");
    return v;
}

uint64_t parse_u64(const std::string &s0, const std::string &what)
{
    std::string s = trim(s0);
    uint64_t v = 0;
    auto r = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || r.ec != std::errc() || r.ptr != s.data() + s.size())
        throw UsageError(what + ": '" + s0 + "' is not a non-negative integer");
    return v;
}

uint32_t parse_u32(const std::string &s, const std::string &what)
{
    uint64_t v = parse_u64(s, what);
    if (v > 0xFFFFFFFFull) throw UsageError(what + ": '" + s + "' is too large");
    return (uint32_t)v;
}

uint32_t parse_enum(const std::string &v, const std::string &what, const std::vector<std::string> &names)
{
    for (size_t i = 0; i < names.size(); ++i)
        if (v == names[i]) return (uint32_t)i;
    std::string all;
    for (size_t i = 0; i < names.size(); ++i) all += (i ? (i + 1 == names.size() ? " or " : ", ") : "") + names[i];
    throw UsageError(what + " must be " + all + " (got '" + v + "')");
}

}  // namespace msidutil
