// What the readers of other tools' FRFs share: the format of a file, its text, numbers, and the one
// conversion of an Imported FRF to an msid-frf/1 document (docs/frf-format.md, "FRFs from other tools").
#include "frf_import.hpp"

extern "C" {
#include "msid/msid.h"   // MSID_VERSION
}

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <numeric>
#include <sstream>
#include <sys/stat.h>

namespace msidfrfimport {

namespace {

std::string lower(std::string s)
{
    for (auto &c : s) c = (char)std::tolower((unsigned char)c);
    return s;
}

std::string extension(const std::string &path)
{
    const size_t slash = path.find_last_of('/'), dot = path.rfind('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    return lower(path.substr(dot + 1));
}

// .s1p .. .s99p (Touchstone v1's file names carry the port count), .ts (Touchstone 2.x)
bool touchstone_extension(const std::string &ext)
{
    if (ext == "ts") return true;
    return ext.size() >= 3 && ext.size() <= 4 && ext.front() == 's' && ext.back() == 'p' &&
           std::all_of(ext.begin() + 1, ext.end() - 1, [](char c) { return std::isdigit((unsigned char)c); });
}

// The first bytes of a file (content sniffing for an unknown extension).
std::string head_of(const std::string &path, size_t n)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot open '" + path + "': " + std::strerror(errno), msidutil::ErrorKind::io);
    std::string s(n, '\0');
    in.read(&s[0], (std::streamsize)n);
    s.resize((size_t)std::max<std::streamsize>(0, in.gcount()));
    return s;
}

Format sniff(const std::string &path)
{
    const std::string h = head_of(path, 512);
    if (h.compare(0, 6, "MATLAB") == 0) return Format::Mat;
    size_t i = 0;
    while (i < h.size() && std::isspace((unsigned char)h[i])) ++i;
    if (i < h.size() && h[i] == '{') return Format::Msid;
    if (h.compare(i, 2, "-1") == 0) return Format::Uff;
    // a Touchstone option line ("# Hz S RI R 50": every word one of its keywords or R's number) among
    // the first lines, after '!' comments; a CSV's "# units: ..." is not one
    static const char *const words[] = {"HZ", "KHZ", "MHZ", "GHZ", "S", "Y", "Z", "H", "G", "RI", "MA", "DB", "R"};
    std::istringstream ls(h);
    std::string line;
    while (std::getline(ls, line)) {
        const size_t a = line.find_first_not_of(" \t\r");
        if (a == std::string::npos || line[a] == '!') continue;
        if (line[a] != '#') break;
        std::istringstream ws(line.substr(a + 1));
        std::string w;
        bool option = false, after_r = false;
        while (ws >> w) {
            for (auto &c : w) c = (char)std::toupper((unsigned char)c);
            const bool keyword = std::find(std::begin(words), std::end(words), w) != std::end(words);
            if (!keyword && !after_r) { option = false; break; }
            option = true;
            after_r = w == "R";
        }
        if (option) return Format::Touchstone;
        break;
    }
    return Format::Csv;
}

}  // namespace

Format format_of(const std::string &path, const std::string &name)
{
    if (!name.empty()) {
        const std::vector<std::string> names = {"msid", "touchstone", "uff", "csv", "mat"};
        const auto it = std::find(names.begin(), names.end(), name);
        if (it == names.end())
            throw Error(MSID_OPT("format") " must be msid, touchstone, uff, csv or mat (got '" + name + "')",
                        msidutil::ErrorKind::usage);
        return (Format)(it - names.begin());
    }
    const std::string ext = extension(path);
    if (ext == "json") return Format::Msid;
    if (touchstone_extension(ext)) return Format::Touchstone;
    if (ext == "uff" || ext == "unv") return Format::Uff;
    if (ext == "csv") return Format::Csv;
    if (ext == "mat") return Format::Mat;
    return sniff(path);
}

Imported read_imported(const std::string &path, Format f)
{
    switch (f) {
    case Format::Touchstone: return read_touchstone(path);
    case Format::Uff: return read_uff58(path);
    case Format::Csv: return read_frf_csv(path);
    case Format::Mat: return read_idfrd_mat(path);
    case Format::Msid: break;
    }
    throw Error("'" + path + "' is an msid-frf/1 file: nothing to import");
}

std::string read_text(const std::string &path)
{
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
        throw Error("'" + path + "' is a directory, not a file", msidutil::ErrorKind::io);
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot open '" + path + "': " + std::strerror(errno), msidutil::ErrorKind::io);
    std::ostringstream ss;
    ss << in.rdbuf();
    std::string s = ss.str();
    if (s.empty()) throw Error("'" + path + "' is empty");
    return s;
}

bool take_number(const char *&s, const char *end, double &x)
{
    while (s < end && (*s == ' ' || *s == '\t')) ++s;
    if (s == end) return false;
    const char *b = s + (*s == '+');   // from_chars takes no leading '+'
    auto r = std::from_chars(b, end, x);
    if (r.ec == std::errc::result_out_of_range) return false;
    if (r.ec != std::errc()) return false;
    // Fortran's double-precision exponent (1.0D+03), which UFF writers may use
    if (r.ptr < end && (*r.ptr == 'D' || *r.ptr == 'd')) {
        std::string t(b, r.ptr);
        const char *e = r.ptr + 1;
        const char *q = e + (e < end && (*e == '+' || *e == '-'));
        while (q < end && std::isdigit((unsigned char)*q)) ++q;
        if (q == e || (q == e + 1 && (*e == '+' || *e == '-'))) return false;
        t += 'e';
        t.append(e, q);
        if (std::from_chars(t.data(), t.data() + t.size(), x).ec != std::errc()) return false;
        r.ptr = q;
    }
    // a number ends at a blank, a separator or the end of the line
    if (r.ptr < end && !std::isspace((unsigned char)*r.ptr) && *r.ptr != ',' && *r.ptr != ';') return false;
    s = r.ptr;
    return true;
}

std::string at_line(const std::string &path, size_t line, const std::string &what)
{
    return "'" + path + "' line " + std::to_string(line) + ": " + what;
}

// ---------------- the msid-frf/1 document ----------------

namespace {

void check_sizes(const Imported &im)
{
    const std::string &p = im.path;
    if (im.nu == 0 || im.ny == 0 || im.nu > 16 || im.ny > 16)
        throw Error("'" + p + "': " + std::to_string(im.ny) + " outputs x " + std::to_string(im.nu) +
                    " inputs; msid takes 1..16 of each");
    if (im.omega.empty()) throw Error("'" + p + "' holds no FRF lines");
    if (im.G.size() != im.omega.size()) throw Error("'" + p + "': internal: G and frequencies differ in count");
    const size_t g = (size_t)im.nu * im.ny;
    if (!im.cov.empty() && (im.cov.size() != im.G.size() || im.dof.size() != im.G.size()))
        throw Error("'" + p + "': internal: covariances and lines differ in count");
    for (size_t k = 0; k < im.G.size(); ++k) {
        if (!std::isfinite(im.omega[k]) || im.omega[k] < 0)
            throw Error("'" + p + "': line " + std::to_string(k + 1) + " has frequency " + std::to_string(im.omega[k]) +
                        " rad/s: frequencies must be finite and non-negative");
        if (im.G[k].rows() != (Eigen::Index)im.ny || im.G[k].cols() != (Eigen::Index)im.nu || !im.G[k].allFinite())
            throw Error("'" + p + "': the FRF at line " + std::to_string(k + 1) + " (" + std::to_string(im.omega[k]) +
                        " rad/s) is not a finite " + std::to_string(im.ny) + " x " + std::to_string(im.nu) + " matrix");
        if (!im.cov.empty() && (im.cov[k].rows() != (Eigen::Index)g || !im.cov[k].allFinite() || !(im.dof[k] >= 1)))
            throw Error("'" + p + "': the uncertainty at line " + std::to_string(k + 1) +
                        " is not finite (or its dof is below 1)");
    }
    auto names = [&](const std::vector<std::string> &v, uint32_t n, const char *what) {
        if (!v.empty() && v.size() != n) throw Error("'" + p + "': internal: " + what + " count");
    };
    names(im.input_names, im.nu, "input name");
    names(im.output_names, im.ny, "output name");
    names(im.input_units, im.nu, "input unit");
    names(im.output_units, im.ny, "output unit");
}

// The lines in increasing frequency; two at one frequency are one error (the fits would interpolate
// two values at one point).
std::vector<size_t> frequency_order(const Imported &im)
{
    std::vector<size_t> ix(im.omega.size());
    std::iota(ix.begin(), ix.end(), 0);
    std::stable_sort(ix.begin(), ix.end(), [&](size_t a, size_t b) { return im.omega[a] < im.omega[b]; });
    for (size_t k = 1; k < ix.size(); ++k)
        if (im.omega[ix[k]] == im.omega[ix[k - 1]])
            throw Error("'" + im.path + "': lines " + std::to_string(std::min(ix[k], ix[k - 1]) + 1) + " and " +
                        std::to_string(std::max(ix[k], ix[k - 1]) + 1) + " are at the same frequency (" +
                        std::to_string(im.omega[ix[k]] / (2 * M_PI)) + " Hz): one value per frequency");
    return ix;
}

}  // namespace

Json to_document(const Imported &im)
{
    check_sizes(im);
    const std::vector<size_t> order = frequency_order(im);
    const bool dt = !im.ct;
    const double h = im.sample_time;
    Json doc;
    doc["format"] = "msid-frf/1";
    doc["generator"] = std::string("msid ") + MSID_VERSION + " import";
    doc["period_samples"] = 0;   // not on DFT bins: the lines are where the instrument put them
    doc["n_inputs"] = im.nu;
    doc["n_outputs"] = im.ny;
    doc["n_experiments"] = 1;
    doc["domain"] = dt ? "dt" : "ct";
    if (h > 0) {
        doc["sample_time"] = h;
        doc["fs_hz"] = 1.0 / h;
    }
    if (!im.input_names.empty()) doc["input_names"] = im.input_names;
    if (!im.output_names.empty()) doc["output_names"] = im.output_names;
    if (!im.input_units.empty()) doc["input_units"] = im.input_units;
    if (!im.output_units.empty()) doc["output_units"] = im.output_units;
    doc["vec_convention"] = msidfrf::VEC_CONVENTION;
    Json imp = im.info;
    imp["format"] = im.format;
    imp["source"] = im.path;
    imp["covariance"] = im.cov.empty() ? "none: an unweighted fit, no p-value" : "from the file";
    doc["imported"] = imp;
    doc["periods_used"] = 0;
    doc["periods_rejected"] = 0;
    doc["noise_cov"] = msidfrf::cmat(MatC::Zero(im.ny, im.ny));
    doc["experiments"] = Json::array({Json{{"source", im.path}}});
    Json lines = Json::array();
    for (size_t k = 0; k < order.size(); ++k) {
        const size_t i = order[k];
        const double om = im.omega[i];
        // cycles per sample: DT lines sit on the unit circle at omega h (or omega without a sample time);
        // a CT FRF of an analogue instrument has no samples, its lines are omega (rad/s) and freq_hz
        const double cyc = dt ? om * (h > 0 ? h : 1.0) / (2 * M_PI) : h > 0 ? om * h / (2 * M_PI) : 0.0;
        if (dt && cyc > 0.5 * (1 + 1e-12))
            throw Error("'" + im.path + "': line " + std::to_string(i + 1) + " lies above the Nyquist frequency of " +
                        "its sample time");
        Json e;
        e["bin"] = k;
        e["freq"] = std::min(cyc, 0.5);
        if (!dt || h > 0) e["freq_hz"] = dt ? cyc / h : om / (2 * M_PI);
        if (!dt) e["omega"] = om;
        if (om == 0 && im.G[i].imag().isZero(0.0)) e["real"] = true;
        e["G"] = msidfrf::cmat(im.G[i]);
        if (!im.cov.empty()) {
            e["cov"] = msidfrf::cmat(im.cov[i]);
            e["dof"] = im.dof[i];
            e["cov_known_input"] = e["cov"];
            e["dof_known_input"] = im.dof[i];
            e["snr"] = Json::array();
        }
        lines.push_back(std::move(e));
    }
    doc["lines"] = std::move(lines);
    return doc;
}

Json load_document(const std::string &path, const std::string &format)
{
    const Format f = format_of(path, format);
    if (f == Format::Msid) return msidfrf::read_json(path);
    return to_document(read_imported(path, f));
}

msidfrf::FrfData load_frf(const std::string &path, const std::string &format)
{
    return msidfrf::parse_frf(load_document(path, format), path);
}

}  // namespace msidfrfimport
