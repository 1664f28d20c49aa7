// The column mapping shared by every reader: `--columns u1=Force,...`, and which file column
// feeds each input and output.
#include "records_detail.hpp"

#include <cctype>
#include <charconv>
#include <system_error>
#include <cstring>

namespace msidrec {

// ---------------------------------------------------------------- columns ---

bool is_time_name(const std::string &name)
{
    std::string n = name;
    for (auto &ch : n) ch = (char)std::tolower((unsigned char)ch);
    return n == "t" || n == "time" || n == "n" || n == "sample" || n == "index";
}

// "u3" -> (0, 3), "Y12" -> (1, 12); (-1, 0) if not of that form (k in 1..64).
static std::pair<int, uint32_t> uy_name(const std::string &s)
{
    if (s.size() < 2 || s.size() > 3) return {-1, 0};
    const char c = (char)std::tolower((unsigned char)s[0]);
    if (c != 'u' && c != 'y') return {-1, 0};
    uint32_t k = 0;
    auto res = std::from_chars(s.data() + 1, s.data() + s.size(), k);
    if (res.ec != std::errc() || res.ptr != s.data() + s.size() || k == 0 || k > 64 || s[1] == '0') return {-1, 0};
    return {c == 'u' ? 0 : 1, k};
}

std::string trim(std::string_view v)
{
    size_t a = 0, b = v.size();
    while (a < b && (v[a] == ' ' || v[a] == '\t')) ++a;
    while (b > a && (v[b - 1] == ' ' || v[b - 1] == '\t')) --b;
    return std::string(v.substr(a, b - a));
}

ColumnMap parse_column_map(const std::string &spec, bool inputs_optional)
{
    ColumnMap m;
    m.inputs_optional = inputs_optional;
    // Items at the commas outside double quotes; a piece without '=' continues the name before it, so
    // a column name may hold a comma: u1=Force, N,y1="Acc, m/s^2" maps 'Force, N' and 'Acc, m/s^2'
    std::vector<std::string> items;
    {
        std::string cur;
        bool quoted = false;
        auto flush = [&] {
            if (!items.empty() && cur.find('=') == std::string::npos && !trim(cur).empty()) items.back() += "," + cur;
            else items.push_back(cur);
            cur.clear();
        };
        for (char ch : spec) {
            if (ch == '"') quoted = !quoted;
            if (ch == ',' && !quoted) flush();
            else cur += ch;
        }
        flush();
    }
    for (size_t it = 0; it < items.size(); ++it) {
        const std::string item = trim(items[it]);
        const size_t eq = item.find('=');
        if (eq == std::string::npos || trim(item.substr(0, eq)).empty() || trim(item.substr(eq + 1)).empty())
            throw ColumnSpecError(MSID_OPT("columns") ": '" + item + "' is not <u<k>|y<k>>=<column name>");
        std::string dst = trim(item.substr(0, eq)), src = trim(item.substr(eq + 1));
        if (src.size() >= 2 && src.front() == '"' && src.back() == '"') src = src.substr(1, src.size() - 2);
        if (uy_name(dst).first < 0)
            throw ColumnSpecError(MSID_OPT("columns") ": '" + dst + "' is not u<k> or y<k> (k = 1..64)");
        for (auto &ch : dst) ch = (char)std::tolower((unsigned char)ch);
        for (const auto &e : m.map) {
            if (e.first == dst) throw ColumnSpecError(MSID_OPT("columns") ": " + dst + " is mapped twice");
            if (e.second == src) throw ColumnSpecError(MSID_OPT("columns") ": column '" + src + "' is mapped twice");
        }
        m.map.emplace_back(dst, src);
    }
    uint32_t maxu = 0, maxy = 0, cu = 0, cy = 0;
    for (const auto &e : m.map) {
        auto [kind, k] = uy_name(e.first);
        (kind == 0 ? cu : cy)++;
        uint32_t &mx = kind == 0 ? maxu : maxy;
        mx = std::max(mx, k);
    }
    if ((cu == 0 && !inputs_optional) || cy == 0) throw ColumnSpecError(MSID_OPT("columns") " must map at least u1 and y1");
    if (cu != maxu) throw ColumnSpecError(fmt(MSID_OPT("columns") ": inputs must be u1..u%u without gaps", maxu));
    if (cy != maxy) throw ColumnSpecError(fmt(MSID_OPT("columns") ": outputs must be y1..y%u without gaps", maxy));
    return m;
}

static std::string list_names(const std::vector<std::string> &names)
{
    std::string s;
    size_t shown = 0;
    for (const auto &n : names) {
        if (n.empty()) continue;
        if (shown == 12) { s += ", ..."; break; }
        if (shown++) s += ", ";
        s += "'" + n + "'";
    }
    return s.empty() ? "no named columns" : s;
}

std::vector<size_t> resolve_columns(const std::string &path, const std::vector<std::string> &names,
                                    const ColumnMap &cols, bool strict, uint32_t &nu, uint32_t &ny)
{
    std::vector<std::pair<std::string, size_t>> dst;   // ("u1", index into names)
    if (!cols.empty()) {
        for (const auto &[d, s] : cols.map) {
            size_t hit = SIZE_MAX, nhit = 0;
            for (size_t i = 0; i < names.size(); ++i)
                if (names[i] == s) { if (hit == SIZE_MAX) hit = i; ++nhit; }
            if (nhit == 0) {   // case-insensitive, if unique
                for (size_t i = 0; i < names.size(); ++i)
                    if (names[i].size() == s.size() &&
                        std::equal(s.begin(), s.end(), names[i].begin(), [](char x, char y) {
                            return std::tolower((unsigned char)x) == std::tolower((unsigned char)y);
                        })) { if (hit == SIZE_MAX) hit = i; ++nhit; }
            }
            if (nhit == 0)
                throw Error(fmt("'%s': no column '%s' (for %s); the file has %s", path.c_str(), s.c_str(), d.c_str(),
                                list_names(names).c_str()));
            if (nhit > 1) throw Error(fmt("'%s': column '%s' appears twice", path.c_str(), s.c_str()));
            dst.emplace_back(d, hit);
        }
    } else {
        for (size_t i = 0; i < names.size(); ++i) {
            auto [kind, k] = uy_name(names[i]);
            if (kind < 0) {
                // r<k>: reference signals, read only by msid frf --method lpm --reference
                const bool ref = names[i].size() >= 2 && (names[i][0] == 'r' || names[i][0] == 'R') &&
                                 uy_name("u" + names[i].substr(1)).first == 0;
                if (names[i].empty() || is_time_name(names[i]) || ref || !strict) continue;
                throw Error(fmt("'%s' line 1: column '%s' is not u<k>, y<k> or a time column (t, time, n, sample, "
                                "index); map named columns with " MSID_OPT("columns") " u1=NAME,y1=NAME",
                                path.c_str(), names[i].c_str()));
            }
            std::string d = fmt("%c%u", kind == 0 ? 'u' : 'y', k);
            for (const auto &e : dst)
                if (e.first == d) throw Error(fmt("'%s' line 1: column '%s' appears twice", path.c_str(), names[i].c_str()));
            dst.emplace_back(d, i);
        }
    }
    uint32_t cu = 0, cy = 0, maxu = 0, maxy = 0;
    for (const auto &e : dst) {
        auto [kind, k] = uy_name(e.first);
        if (kind == 0) { ++cu; maxu = std::max(maxu, k); } else { ++cy; maxy = std::max(maxy, k); }
    }
    if (cu == 0 && !cols.inputs_optional)
        throw Error(fmt("'%s' has no input columns (u1, u2, ...): it has %s; map them with " MSID_OPT("columns") " u1=NAME,y1=NAME",
                        path.c_str(), list_names(names).c_str()));
    if (cy == 0)
        throw Error(fmt("'%s' has no output columns (y1, y2, ...): it has %s; map them with " MSID_OPT("columns") " u1=NAME,y1=NAME",
                        path.c_str(), list_names(names).c_str()));
    if (cu != maxu) throw Error(fmt("'%s': input columns must be u1..u%u without gaps", path.c_str(), maxu));
    if (cy != maxy) throw Error(fmt("'%s': output columns must be y1..y%u without gaps", path.c_str(), maxy));
    if (cu > MSID_MAX_INPUTS) throw Error(fmt("'%s': %u inputs, at most %u are supported", path.c_str(), cu, MSID_MAX_INPUTS));
    if (cy > MSID_MAX_OUTPUTS) throw Error(fmt("'%s': %u outputs, at most %u are supported", path.c_str(), cy, MSID_MAX_OUTPUTS));
    nu = cu;
    ny = cy;
    std::vector<size_t> src(cu + cy);
    for (const auto &e : dst) {
        auto [kind, k] = uy_name(e.first);
        src[kind == 0 ? k - 1 : cu + k - 1] = e.second;
    }
    return src;
}

}  // namespace msidrec
