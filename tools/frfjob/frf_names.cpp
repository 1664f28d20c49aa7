// The signals' names and units of an FRF document, from the records' column names: what the
// engineer called the channels (a CSV header, a .mat variable, --columns u1="Force [N]") goes
// into frf.json, and from there into models, plots, exports and python-control.
#include "frf_job_detail.hpp"

#include <cctype>

namespace msidjob {

// "u3" for (u, 3): the name a column gets when the file says nothing else.
static bool default_name(const std::string &s, char kind, size_t k)
{
    if (s == std::string(1, kind) + std::to_string(k)) return true;
    // a bare column number (a .npy matrix's columns are 1..C)
    return !s.empty() && s.find_first_not_of("0123456789") == std::string::npos;
}

// "Force [N]" -> ("Force", "N"); "Force (N)" likewise; "Force" -> ("Force", "").
static std::pair<std::string, std::string> split_unit(const std::string &s)
{
    const size_t n = s.size();
    if (n >= 3 && (s[n - 1] == ']' || s[n - 1] == ')')) {
        const char open = s[n - 1] == ']' ? '[' : '(';
        const size_t o = s.rfind(open);
        if (o != std::string::npos && o > 0 && o + 2 < n) {
            size_t e = o;
            while (e > 0 && std::isspace((unsigned char)s[e - 1])) --e;
            if (e > 0) return {s.substr(0, e), s.substr(o + 1, n - o - 2)};
        }
    }
    return {s, ""};
}

void names_from_records(FrfRequest &rq, const std::vector<Record> &recs)
{
    if (!rq.input_names.empty() || !rq.output_names.empty() || recs.empty()) return;
    const Record &r = recs[0];
    if (r.columns.size() != (size_t)r.nu + r.ny) return;
    bool named = false;
    for (uint32_t k = 0; k < r.nu + r.ny; ++k)
        named |= !default_name(r.columns[k], k < r.nu ? 'u' : 'y', k < r.nu ? k + 1 : k - r.nu + 1);
    if (!named) return;
    bool units = false;
    std::vector<std::string> names, unit;
    for (uint32_t k = 0; k < r.nu + r.ny; ++k) {
        const bool in = k < r.nu;
        const size_t idx = in ? k + 1 : k - r.nu + 1;
        const std::string &c = r.columns[k];
        auto nm = default_name(c, in ? 'u' : 'y', idx) ? std::make_pair(std::string(in ? "u" : "y") + std::to_string(idx), std::string())
                                                        : split_unit(c);
        units |= !nm.second.empty();
        names.push_back(nm.first);
        unit.push_back(nm.second);
    }
    rq.input_names.assign(names.begin(), names.begin() + r.nu);
    rq.output_names.assign(names.begin() + r.nu, names.end());
    if (units) {
        rq.input_units.assign(unit.begin(), unit.begin() + r.nu);
        rq.output_units.assign(unit.begin() + r.nu, unit.end());
    }
}

}  // namespace msidjob
