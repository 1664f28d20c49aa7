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

}  // namespace

Imported read_frf_csv(const std::string &path)
{
    const std::string text = read_text(path);
    Meta meta;
    std::vector<std::string> header;
    size_t header_line = 0;
    std::vector<std::pair<size_t, std::vector<std::string>>> rows;
    size_t lineno = 0;
    for (size_t a = 0; a < text.size();) {
        size_t b = text.find('\n', a);
        if (b == std::string::npos) b = text.size();
        const std::string line = trim(text.substr(a, b - a));
        a = b + 1;
        ++lineno;
        if (line.empty()) continue;
        if (line[0] == '#') {
            if (header.empty()) take_meta(meta, path, lineno, line.substr(1));
            continue;
        }
        if (header.empty()) {
            header = split(line, ',');
            header_line = lineno;
            continue;
        }
        rows.emplace_back(lineno, split(line, ','));
    }
    if (header.empty()) throw Error("'" + path + "' has no header line (docs/frf-format.md, \"CSV\")");
    // the header: one frequency column, then G_OUT_IN_PART columns
    int fcol = -1;
    double fscale = 0;
    std::vector<std::string> outs, ins;
    std::map<std::pair<size_t, size_t>, PathCols> paths;
    int dofcol = -1;
    const bool dt = meta.domain == "dt";
    for (size_t c = 0; c < header.size(); ++c) {
        const std::string &h = header[c];
        if (h == "omega" || h == "freq_hz" || (h == "freq" && dt)) {
            // omega first, then freq_hz, then freq (msid export writes all three)
            const double s = h == "omega" ? 1.0 : h == "freq_hz" ? 2 * M_PI : 2 * M_PI / (meta.sample_time > 0 ? meta.sample_time : 1.0);
            const int rank = h == "omega" ? 3 : h == "freq_hz" ? 2 : 1;
            const int have = fcol < 0 ? 0 : header[(size_t)fcol] == "omega" ? 3 : header[(size_t)fcol] == "freq_hz" ? 2 : 1;
            if (rank > have) { fcol = (int)c; fscale = s; }
            continue;
        }
        if (h == "bin" || h == "freq") continue;
        if (h == "dof") { dofcol = (int)c; continue; }
        const std::vector<std::string> p = split(h, '_');
        if (p.size() != 4 || p[0] != "G" || p[1].empty() || p[2].empty() ||
            (p[3] != "re" && p[3] != "im" && p[3] != "sd" && p[3] != "coh"))
            throw Error(at_line(path, header_line, "column " + std::to_string(c + 1) + " '" + h +
                                                       "' is not a frequency (freq_hz, omega) nor G_OUT_IN_re|im|sd|coh "
                                                       "(names without '_')"));
        auto index = [](std::vector<std::string> &v, const std::string &n) {
            auto it = std::find(v.begin(), v.end(), n);
            if (it == v.end()) { v.push_back(n); return v.size() - 1; }
            return (size_t)(it - v.begin());
        };
        const size_t i = index(outs, p[1]), j = index(ins, p[2]);
        PathCols &pc = paths[{i, j}];
        int &slot = p[3] == "re" ? pc.re : p[3] == "im" ? pc.im : p[3] == "sd" ? pc.sd : pc.coh;
        if (slot >= 0) throw Error(at_line(path, header_line, "column '" + h + "' appears twice"));
        slot = (int)c;
    }
    if (fcol < 0)
        throw Error(at_line(path, header_line, std::string("no frequency column (freq_hz in Hz or omega in rad/s") +
                                                   (dt ? ", or freq in cycles/sample" : "") + ")"));
    if (outs.empty()) throw Error(at_line(path, header_line, "no G_OUT_IN_re / G_OUT_IN_im columns"));
    if (outs.size() > 16 || ins.size() > 16)
        throw Error(at_line(path, header_line, std::to_string(outs.size()) + " outputs x " + std::to_string(ins.size()) +
                                                   " inputs; msid takes 1..16 of each"));
    int with_sd = 0, with_coh = 0;
    for (size_t i = 0; i < outs.size(); ++i)
        for (size_t j = 0; j < ins.size(); ++j) {
            const std::string n = "G_" + outs[i] + "_" + ins[j];
            if (!paths.count({i, j}) || paths[{i, j}].re < 0 || paths[{i, j}].im < 0)
                throw Error(at_line(path, header_line, "no columns " + n + "_re and " + n + "_im: every output/input "
                                                           "pair needs both"));
            const PathCols &pc = paths[{i, j}];
            if (pc.sd >= 0 && pc.coh >= 0)
                throw Error(at_line(path, header_line, n + " has both _sd and _coh: give one of them"));
            with_sd += pc.sd >= 0;
            with_coh += pc.coh >= 0;
        }
    const int npaths = (int)(outs.size() * ins.size());
    if ((with_sd && with_sd != npaths) || (with_coh && with_coh != npaths))
        throw Error(at_line(path, header_line, "uncertainty columns (_sd or _coh) for some pairs only: give them for "
                                               "every pair or none"));
    if (with_coh && !(meta.averages > 0))
        throw Error(at_line(path, header_line, "coherence columns need the number of averages ('# averages: n')"));
    Imported im;
    im.path = path;
    im.format = "csv";
    im.ny = (uint32_t)outs.size();
    im.nu = (uint32_t)ins.size();
    im.ct = !dt;
    im.sample_time = dt ? meta.sample_time : 0.0;
    im.output_names = outs;
    im.input_names = ins;
    for (const auto &n : ins) im.input_units.push_back(meta.units.count(n) ? meta.units[n] : "");
    for (const auto &n : outs) im.output_units.push_back(meta.units.count(n) ? meta.units[n] : "");
    if (meta.units.empty()) im.input_units.clear(), im.output_units.clear();
    const size_t g = (size_t)im.ny * im.nu;
    for (const auto &row : rows) {
        const size_t ln = row.first;
        const std::vector<std::string> &v = row.second;
        if (v.size() != header.size())
            throw Error(at_line(path, ln, std::to_string(v.size()) + " columns, the header has " +
                                              std::to_string(header.size())));
        auto number = [&](int c) {
            const std::string &t = v[(size_t)c];
            const char *s = t.c_str();
            double x = 0;
            if (!take_number(s, s + t.size(), x) || *s)
                throw Error(at_line(path, ln, "column '" + header[(size_t)c] + "': '" + t + "' is not a number"));
            if (!std::isfinite(x))
                throw Error(at_line(path, ln, "column '" + header[(size_t)c] + "' is not finite (" + t + ")"));
            return x;
        };
        im.omega.push_back(number(fcol) * fscale);
        MatC G(im.ny, im.nu);
        MatC C = MatC::Zero((Eigen::Index)g, (Eigen::Index)g);
        for (size_t i = 0; i < outs.size(); ++i)
            for (size_t j = 0; j < ins.size(); ++j) {
                const PathCols &pc = paths[{i, j}];
                const cd x(number(pc.re), number(pc.im));
                G((Eigen::Index)i, (Eigen::Index)j) = x;
                const Eigen::Index a = (Eigen::Index)(i + im.ny * j);   // vec stacks columns
                if (pc.sd >= 0) {
                    const double sd = number(pc.sd);
                    if (!(sd > 0))
                        throw Error(at_line(path, ln, "column '" + header[(size_t)pc.sd] +
                                                          "': a standard deviation must be positive"));
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
        if (with_sd || with_coh) {
            im.cov.push_back(C);
            // the dof: an exported file's column, else "# dof:", else the averages (coherence), else
            // the sd are taken as known (a large dof: the chi-square law)
            const double dof = dofcol >= 0 ? number(dofcol) : meta.dof > 0 ? meta.dof : with_coh ? meta.averages : 1e9;
            if (!(dof >= 1)) throw Error(at_line(path, ln, "dof must be at least 1"));
            im.dof.push_back(dof);
        }
    }
    if (rows.empty()) throw Error("'" + path + "' has a header but no rows");
    im.info["uncertainty"] = with_sd ? "standard deviations" : with_coh ? "coherence" : "none";
    if (with_coh) im.info["averages"] = meta.averages;
    return im;
}

}  // namespace msidfrfimport
