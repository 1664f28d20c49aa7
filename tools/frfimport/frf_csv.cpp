// An FRF as CSV (docs/frf-format.md, "CSV"): '#' lines are comments, "# key: value" ones metadata
// (domain, sample_time, dof, averages, units); the first other line is the header, one column of
// frequencies (freq_hz, omega in rad/s, or freq in cycles/sample for dt) and per output OUT and input
// IN the columns G_OUT_IN_re, G_OUT_IN_im and optionally G_OUT_IN_sd (standard deviation of the complex
// value, sqrt E|Ghat - G|^2) or G_OUT_IN_coh (magnitude-squared coherence, with "# averages: n"). The
// columns bin, freq_hz/freq (beside another frequency column) and dof of `msid export --csv` are read
// as that command writes them, so an exported file comes back.
#include "frf_import.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <map>

namespace msidfrfimport {

namespace {

std::string trim(const std::string &v)
{
    const size_t a = v.find_first_not_of(" \t\r"), b = v.find_last_not_of(" \t\r");
    return a == std::string::npos ? "" : v.substr(a, b - a + 1);
}

std::vector<std::string> split(const std::string &line, char sep)
{
    std::vector<std::string> out;
    size_t a = 0;
    for (;;) {
        const size_t b = line.find(sep, a);
        out.push_back(trim(line.substr(a, b == std::string::npos ? std::string::npos : b - a)));
        if (b == std::string::npos) return out;
        a = b + 1;
    }
}

struct Meta {
    std::string domain = "ct";
    double sample_time = 0, dof = 0, averages = 0;
    std::map<std::string, std::string> units;
};

double positive(const std::string &path, size_t line, const std::string &key, const std::string &v)
{
    const char *s = v.c_str();
    double x = 0;
    if (!take_number(s, s + v.size(), x) || *s || !std::isfinite(x) || !(x > 0))
        throw Error(at_line(path, line, "'" + key + "' must be a positive number (got '" + v + "')"));
    return x;
}

void take_meta(Meta &m, const std::string &path, size_t line, const std::string &body)
{
    const size_t colon = body.find(':');
    if (colon == std::string::npos) return;   // a comment
    std::string key = trim(body.substr(0, colon));
    const std::string v = trim(body.substr(colon + 1));
    for (auto &c : key) c = (char)std::tolower((unsigned char)c);
    if (key == "domain") {
        if (v != "ct" && v != "dt") throw Error(at_line(path, line, "domain must be ct or dt (got '" + v + "')"));
        m.domain = v;
    } else if (key == "sample_time") {
        m.sample_time = positive(path, line, key, v);
    } else if (key == "dof") {
        m.dof = positive(path, line, key, v);
    } else if (key == "averages") {
        m.averages = positive(path, line, key, v);
    } else if (key == "units") {
        for (const std::string &kv : split(v, ',')) {
            const size_t eq = kv.find('=');
            if (eq == std::string::npos)
                throw Error(at_line(path, line, "units are name=unit pairs separated by commas (got '" + kv + "')"));
            m.units[trim(kv.substr(0, eq))] = trim(kv.substr(eq + 1));
        }
    }
}

// Where each part of a path's value is: column indices of re, im, sd, coh (-1: absent).
struct PathCols {
    int re = -1, im = -1, sd = -1, coh = -1;
};

// The file's lines sorted: the metadata of the '#' lines before the header, the header's cells and
// line number, and every later non-comment line's cells with its line number (checked later, so that
// an error names the line).
struct CsvLines {
    Meta meta;
    std::vector<std::string> header;
    size_t header_line = 0;
    std::vector<std::pair<size_t, std::vector<std::string>>> rows;
};

CsvLines csv_lines(const std::string &path, const std::string &text)
{
    CsvLines L;
    size_t lineno = 0;
    for (size_t a = 0; a < text.size();) {
        size_t b = text.find('\n', a);
        if (b == std::string::npos) b = text.size();
        const std::string line = trim(text.substr(a, b - a));
        a = b + 1;
        ++lineno;
        if (line.empty()) continue;
        if (line[0] == '#') {
            if (L.header.empty()) take_meta(L.meta, path, lineno, line.substr(1));
            continue;
        }
        if (L.header.empty()) {
            L.header = split(line, ',');
            L.header_line = lineno;
            continue;
        }
        L.rows.emplace_back(lineno, split(line, ','));
    }
    if (L.header.empty()) throw Error("'" + path + "' has no header line (docs/frf-format.md, \"CSV\")");
    return L;
}

// What the header's columns hold: the frequency column and its scale to rad/s (or rad/sample), the
// outputs' and inputs' names in their order of appearance, each path's columns, the dof column (-1:
// none), and whether every path has a standard deviation or a coherence column (all or none).
struct CsvColumns {
    int fcol = -1;
    double fscale = 0;
    std::vector<std::string> outs, ins;
    std::map<std::pair<size_t, size_t>, PathCols> paths;
    int dofcol = -1;
    bool with_sd = false, with_coh = false;
};

// The header's columns: one frequency column (omega first, then freq_hz, then freq: msid export
// writes all three), the columns msid export adds (bin, a second frequency, dof), then
// G_OUT_IN_PART columns, each once.
CsvColumns header_columns(const std::string &path, const CsvLines &L)
{
    const std::vector<std::string> &header = L.header;
    const bool dt = L.meta.domain == "dt";
    CsvColumns cols;
    for (size_t c = 0; c < header.size(); ++c) {
        const std::string &h = header[c];
        if (h == "omega" || h == "freq_hz" || (h == "freq" && dt)) {
            const double s = h == "omega" ? 1.0 : h == "freq_hz" ? 2 * M_PI : 2 * M_PI / (L.meta.sample_time > 0 ? L.meta.sample_time : 1.0);
            const int rank = h == "omega" ? 3 : h == "freq_hz" ? 2 : 1;
            const int have = cols.fcol < 0 ? 0 : header[(size_t)cols.fcol] == "omega" ? 3 : header[(size_t)cols.fcol] == "freq_hz" ? 2 : 1;
            if (rank > have) { cols.fcol = (int)c; cols.fscale = s; }
            continue;
        }
        if (h == "bin" || h == "freq") continue;
        if (h == "dof") { cols.dofcol = (int)c; continue; }
        const std::vector<std::string> p = split(h, '_');
        if (p.size() != 4 || p[0] != "G" || p[1].empty() || p[2].empty() ||
            (p[3] != "re" && p[3] != "im" && p[3] != "sd" && p[3] != "coh"))
            throw Error(at_line(path, L.header_line, "column " + std::to_string(c + 1) + " '" + h +
                                                         "' is not a frequency (freq_hz, omega) nor G_OUT_IN_re|im|sd|coh "
                                                         "(names without '_')"));
        auto index = [](std::vector<std::string> &v, const std::string &n) {
            auto it = std::find(v.begin(), v.end(), n);
            if (it == v.end()) { v.push_back(n); return v.size() - 1; }
            return (size_t)(it - v.begin());
        };
        const size_t i = index(cols.outs, p[1]), j = index(cols.ins, p[2]);
        PathCols &pc = cols.paths[{i, j}];
        int &slot = p[3] == "re" ? pc.re : p[3] == "im" ? pc.im : p[3] == "sd" ? pc.sd : pc.coh;
        if (slot >= 0) throw Error(at_line(path, L.header_line, "column '" + h + "' appears twice"));
        slot = (int)c;
    }
    if (cols.fcol < 0)
        throw Error(at_line(path, L.header_line, std::string("no frequency column (freq_hz in Hz or omega in rad/s") +
                                                     (dt ? ", or freq in cycles/sample" : "") + ")"));
    if (cols.outs.empty()) throw Error(at_line(path, L.header_line, "no G_OUT_IN_re / G_OUT_IN_im columns"));
    if (cols.outs.size() > 16 || cols.ins.size() > 16)
        throw Error(at_line(path, L.header_line, std::to_string(cols.outs.size()) + " outputs x " +
                                                     std::to_string(cols.ins.size()) + " inputs; msid takes 1..16 of each"));
    return cols;
}

// Every output/input pair has its _re and _im columns and at most one of _sd and _coh, and either
// every pair has the same kind of uncertainty or none has; coherence needs the averages.
void check_paths(const std::string &path, const CsvLines &L, CsvColumns &cols)
{
    int with_sd = 0, with_coh = 0;
    for (size_t i = 0; i < cols.outs.size(); ++i)
        for (size_t j = 0; j < cols.ins.size(); ++j) {
            const std::string n = "G_" + cols.outs[i] + "_" + cols.ins[j];
            if (!cols.paths.count({i, j}) || cols.paths[{i, j}].re < 0 || cols.paths[{i, j}].im < 0)
                throw Error(at_line(path, L.header_line, "no columns " + n + "_re and " + n + "_im: every output/input "
                                                             "pair needs both"));
            const PathCols &pc = cols.paths[{i, j}];
            if (pc.sd >= 0 && pc.coh >= 0)
                throw Error(at_line(path, L.header_line, n + " has both _sd and _coh: give one of them"));
            with_sd += pc.sd >= 0;
            with_coh += pc.coh >= 0;
        }
    const int npaths = (int)(cols.outs.size() * cols.ins.size());
    if ((with_sd && with_sd != npaths) || (with_coh && with_coh != npaths))
        throw Error(at_line(path, L.header_line, "uncertainty columns (_sd or _coh) for some pairs only: give them for "
                                                 "every pair or none"));
    if (with_coh && !(L.meta.averages > 0))
        throw Error(at_line(path, L.header_line, "coherence columns need the number of averages ('# averages: n')"));
    cols.with_sd = with_sd != 0;
    cols.with_coh = with_coh != 0;
}

// The FRF's frame before its lines: sizes, domain, the channels' names and (given any) units.
Imported imported_frame(const std::string &path, const CsvLines &L, const CsvColumns &cols)
{
    const bool dt = L.meta.domain == "dt";
    Imported im;
    im.path = path;
    im.format = "csv";
    im.ny = (uint32_t)cols.outs.size();
    im.nu = (uint32_t)cols.ins.size();
    im.ct = !dt;
    im.sample_time = dt ? L.meta.sample_time : 0.0;
    im.output_names = cols.outs;
    im.input_names = cols.ins;
    const std::map<std::string, std::string> &units = L.meta.units;
    for (const auto &n : cols.ins) im.input_units.push_back(units.count(n) ? units.at(n) : "");
    for (const auto &n : cols.outs) im.output_units.push_back(units.count(n) ? units.at(n) : "");
    if (units.empty()) im.input_units.clear(), im.output_units.clear();
    return im;
}

// One row's line: its frequency, G and (with uncertainty columns) the diagonal covariance of vec G
// from the standard deviations or, by Bendat & Piersol (9.73), the coherence, and its dof. Every
// cell a finite number, named by line and column where it is not.
void take_row(Imported &im, const std::string &path, const CsvLines &L, const CsvColumns &cols, size_t ln,
              const std::vector<std::string> &v)
{
    const std::vector<std::string> &header = L.header;
    const Meta &meta = L.meta;
    if (v.size() != header.size())
        throw Error(at_line(path, ln, std::to_string(v.size()) + " columns, the header has " + std::to_string(header.size())));
    auto number = [&](int c) {
        const std::string &t = v[(size_t)c];
        const char *s = t.c_str();
        double x = 0;
        if (!take_number(s, s + t.size(), x) || *s)
            throw Error(at_line(path, ln, "column '" + header[(size_t)c] + "': '" + t + "' is not a number"));
        if (!std::isfinite(x)) throw Error(at_line(path, ln, "column '" + header[(size_t)c] + "' is not finite (" + t + ")"));
        return x;
    };
    const size_t g = (size_t)im.ny * im.nu;
    im.omega.push_back(number(cols.fcol) * cols.fscale);
    MatC G(im.ny, im.nu);
    MatC C = MatC::Zero((Eigen::Index)g, (Eigen::Index)g);
    for (size_t i = 0; i < cols.outs.size(); ++i)
        for (size_t j = 0; j < cols.ins.size(); ++j) {
            const PathCols &pc = cols.paths.at({i, j});
            const cd x(number(pc.re), number(pc.im));
            G((Eigen::Index)i, (Eigen::Index)j) = x;
            const Eigen::Index a = (Eigen::Index)(i + im.ny * j);   // vec stacks columns
            if (pc.sd >= 0) {
                const double sd = number(pc.sd);
                if (!(sd > 0))
                    throw Error(at_line(path, ln, "column '" + header[(size_t)pc.sd] + "': a standard deviation must be positive"));
                C(a, a) = sd * sd;
            }
            if (pc.coh >= 0) {
                // Bendat & Piersol (9.73): the complex variance of an H1 estimate from n averages,
                // E|Ghat - G|^2 = (1 - coh) / (coh n) |G|^2 (magnitude and phase errors alike)
                const double coh = number(pc.coh);
                if (!(coh > 0 && coh < 1))
                    throw Error(at_line(path, ln, "column '" + header[(size_t)pc.coh] +
                                                      "': a coherence must lie in (0, 1) (1 gives no noise level)"));
                C(a, a) = (1 - coh) / (coh * meta.averages) * std::norm(x);
                if (!(C(a, a).real() > 0))
                    throw Error(at_line(path, ln, "G is zero where the coherence sets its variance: no noise level"));
            }
        }
    im.G.push_back(G);
    if (cols.with_sd || cols.with_coh) {
        im.cov.push_back(C);
        // the dof: an exported file's column, else "# dof:", else the averages (coherence), else
        // the sd are taken as known (a large dof: the chi-square law)
        const double dof = cols.dofcol >= 0 ? number(cols.dofcol) : meta.dof > 0 ? meta.dof : cols.with_coh ? meta.averages : 1e9;
        if (!(dof >= 1)) throw Error(at_line(path, ln, "dof must be at least 1"));
        im.dof.push_back(dof);
    }
}

}  // namespace

Imported read_frf_csv(const std::string &path)
{
    const CsvLines L = csv_lines(path, read_text(path));
    CsvColumns cols = header_columns(path, L);
    check_paths(path, L, cols);
    Imported im = imported_frame(path, L, cols);
    for (const auto &row : L.rows) take_row(im, path, L, cols, row.first, row.second);
    if (L.rows.empty()) throw Error("'" + path + "' has a header but no rows");
    im.info["uncertainty"] = cols.with_sd ? "standard deviations" : cols.with_coh ? "coherence" : "none";
    if (cols.with_coh) im.info["averages"] = L.meta.averages;
    return im;
}

}  // namespace msidfrfimport
