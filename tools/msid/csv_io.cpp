#include "csv_io.hpp"
#include "cli_util.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace msidcli {

static std::string slurp(const std::string &path)
{
    FILE *f = std::fopen(path.c_str(), "rb");
    if (!f) throw Error("cannot open '" + path + "': " + std::strerror(errno));
    std::string s;
    char buf[1 << 16];
    size_t k;
    while ((k = std::fread(buf, 1, sizeof buf, f)) > 0) s.append(buf, k);
    bool bad = std::ferror(f);
    std::fclose(f);
    if (bad) throw Error("cannot read '" + path + "'");
    return s;
}

static std::string trim(std::string_view v)
{
    size_t a = 0, b = v.size();
    while (a < b && (v[a] == ' ' || v[a] == '\t')) ++a;
    while (b > a && (v[b - 1] == ' ' || v[b - 1] == '\t')) --b;
    return std::string(v.substr(a, b - a));
}

Record read_record_csv(const std::string &path)
{
    const std::string text = slurp(path);
    Record r;
    r.path = path;
    size_t pos = 0, lineno = 0;
    auto next_line = [&](std::string_view &line) -> bool {
        if (pos >= text.size()) return false;
        size_t e = text.find('\n', pos);
        if (e == std::string::npos) e = text.size();
        line = std::string_view(text).substr(pos, e - pos);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        pos = e + 1;
        ++lineno;
        return true;
    };
    if (text.size() >= 3 && (unsigned char)text[0] == 0xEF && (unsigned char)text[1] == 0xBB &&
        (unsigned char)text[2] == 0xBF)
        pos = 3;   /* UTF-8 byte order mark, as some spreadsheet exports write */
    std::string_view line;
    if (!next_line(line) || trim(line).empty())
        throw Error("'" + path + "' is empty: expected a header row with columns u1.. and y1..");

    // Header: map each cell to a destination column, or -1 (ignored time column).
    std::vector<std::string> names;
    {
        size_t a = 0;
        for (;;) {
            size_t b = line.find(',', a);
            names.push_back(trim(line.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a)));
            if (b == std::string_view::npos) break;
            a = b + 1;
        }
    }
    std::vector<int> kind(names.size(), -1);   // 0 = u, 1 = y, -1 = ignored
    std::vector<uint32_t> num(names.size(), 0);
    uint32_t maxu = 0, maxy = 0;
    for (size_t c = 0; c < names.size(); ++c) {
        std::string n = names[c];
        for (auto &ch : n) ch = (char)std::tolower((unsigned char)ch);
        if (n == "t" || n == "time" || n == "n" || n == "sample" || n == "index") continue;
        uint64_t k = 0;
        auto res = n.size() >= 2 ? std::from_chars(n.data() + 1, n.data() + n.size(), k) : std::from_chars_result{n.data(), std::errc::invalid_argument};
        if ((n[0] != 'u' && n[0] != 'y') || res.ec != std::errc() || res.ptr != n.data() + n.size() || k == 0 || k > 64)
            throw Error(fmt("'%s' line 1: column '%s' is not u<k>, y<k> or a time column (t, time, n, sample, index)",
                            path.c_str(), names[c].c_str()));
        kind[c] = n[0] == 'u' ? 0 : 1;
        num[c] = (uint32_t)k;
        for (size_t j = 0; j < c; ++j)
            if (kind[j] == kind[c] && num[j] == num[c])
                throw Error(fmt("'%s' line 1: column '%s' appears twice", path.c_str(), names[c].c_str()));
        if (kind[c] == 0 && k > maxu) maxu = (uint32_t)k;
        if (kind[c] == 1 && k > maxy) maxy = (uint32_t)k;
    }
    uint32_t cu = 0, cy = 0;
    for (size_t c = 0; c < names.size(); ++c) { if (kind[c] == 0) ++cu; if (kind[c] == 1) ++cy; }
    if (cu == 0) throw Error("'" + path + "' has no input columns (u1, u2, ...)");
    if (cy == 0) throw Error("'" + path + "' has no output columns (y1, y2, ...)");
    if (cu != maxu) throw Error(fmt("'%s': input columns must be u1..u%u without gaps", path.c_str(), maxu));
    if (cy != maxy) throw Error(fmt("'%s': output columns must be y1..y%u without gaps", path.c_str(), maxy));
    if (cu > MSID_MAX_INPUTS) throw Error(fmt("'%s': %u inputs, at most %u are supported", path.c_str(), cu, MSID_MAX_INPUTS));
    if (cy > MSID_MAX_OUTPUTS) throw Error(fmt("'%s': %u outputs, at most %u are supported", path.c_str(), cy, MSID_MAX_OUTPUTS));
    r.nu = cu;
    r.ny = cy;
    const size_t C = cu + cy;
    std::vector<size_t> dest(names.size(), SIZE_MAX);
    for (size_t c = 0; c < names.size(); ++c)
        if (kind[c] >= 0) dest[c] = kind[c] == 0 ? num[c] - 1 : cu + num[c] - 1;

    r.rows.reserve(text.size() / (C * 8 + 1) * C + C);
    size_t blank_at = 0;
    while (next_line(line)) {
        if (trim(line).empty()) { if (!blank_at) blank_at = lineno; continue; }
        if (blank_at)
            throw Error(fmt("'%s' line %zu: empty line inside the data", path.c_str(), blank_at));
        const size_t base = r.rows.size();
        r.rows.resize(base + C);
        size_t a = 0, c = 0;
        for (;;) {
            size_t b = line.find(',', a);
            std::string_view cell = line.substr(a, b == std::string_view::npos ? std::string_view::npos : b - a);
            if (c >= names.size())
                throw Error(fmt("'%s' line %zu: ragged row, more than the %zu cells of the header",
                                path.c_str(), lineno, names.size()));
            if (kind[c] >= 0) {
                size_t s0 = 0, s1 = cell.size();
                while (s0 < s1 && (cell[s0] == ' ' || cell[s0] == '\t')) ++s0;
                while (s1 > s0 && (cell[s1 - 1] == ' ' || cell[s1 - 1] == '\t')) --s1;
                const char *p0 = cell.data() + s0, *p1 = cell.data() + s1;
                if (s0 < s1 && *p0 == '+') ++p0;
                double v = 0;
                auto res = std::from_chars(p0, p1, v);
                if (s0 == s1 || res.ec != std::errc() || res.ptr != p1)
                    throw Error(fmt("'%s' line %zu, column %s: '%s' is not a number", path.c_str(), lineno,
                                    names[c].c_str(), std::string(cell).c_str()));
                if (!std::isfinite(v))
                    throw Error(fmt("'%s' line %zu, column %s: NaN or Inf is not allowed", path.c_str(), lineno,
                                    names[c].c_str()));
                r.rows[base + dest[c]] = v;
            }
            ++c;
            if (b == std::string_view::npos) break;
            a = b + 1;
        }
        if (c != names.size())
            throw Error(fmt("'%s' line %zu: ragged row, %zu cells where the header has %zu", path.c_str(), lineno, c,
                            names.size()));
        r.n_rows++;
    }
    if (r.n_rows == 0) throw Error("'" + path + "' has a header but no samples");
    return r;
}

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

}  // namespace msidcli
