#include "frf_file.hpp"
#include "frf_text.hpp"

extern "C" {
#include "msid/msid.h"
}

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <exception>
#include <sys/stat.h>
#include <system_error>
#include <thread>
#include <memory>

namespace msidfrf {

const char *const VEC_CONVENTION = "vec stacks columns: G[i][j] has index i + n_outputs*j";

// ---------------- reading ----------------

Json read_json(const std::string &path)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError("cannot open '" + path + "': " + std::strerror(errno));
    // a regular file into one buffer of its size (a stringstream grows by doubling and str()
    // copies: three buffers of fresh pages for a large file); anything else (a pipe, a directory,
    // whose "size" from seeking is not its content) is read the long way
    std::string s;
    struct stat st;
    const bool known = ::stat(path.c_str(), &st) == 0;
    if (known && S_ISDIR(st.st_mode)) throw IoError("'" + path + "' is a directory, not a file");
    const bool regular = known && S_ISREG(st.st_mode);
    std::streamoff size = -1;
    if (regular) {
        in.seekg(0, std::ios::end);
        size = in.tellg();
    }
    if (size > 0) {
        s.resize((size_t)size);
        in.seekg(0, std::ios::beg);
        in.read(&s[0], (std::streamsize)size);
        if (in.gcount() != (std::streamsize)size) s.resize((size_t)std::max<std::streamsize>(0, in.gcount()));
    } else {
        in.clear();
        in.seekg(0, std::ios::beg);
        std::stringstream ss;
        ss << in.rdbuf();
        s = ss.str();
    }
    return parse_json(s, path);
}

Json parse_json(const std::string &s, const std::string &path)
{
    if (s.empty()) throw Error("'" + path + "' is empty");
    try {
        return Json::parse(s);
    } catch (const Json::parse_error &e) {
        throw Error("'" + path + "' is not valid JSON: " + e.what());
    } catch (const Json::out_of_range &e) {
        // e.g. 1e400: a number no double holds (found by fuzz_files; seed regress-number-overflow)
        throw Error("'" + path + "' holds a number beyond the range of a double: " + e.what());
    } catch (const Json::exception &e) {
        throw Error("'" + path + "' cannot be read as JSON: " + e.what());
    }
}

static std::string where(const std::string &file, const std::string &what) { return "'" + file + "': " + what; }

static const Json &need(const Json &o, const char *key, const std::string &file, const std::string &ctx = "")
{
    if (!o.is_object()) throw Error(where(file, (ctx.empty() ? "" : ctx + ": ") + "expected an object"));
    auto it = o.find(key);
    if (it == o.end()) throw Error(where(file, "missing '" + (ctx.empty() ? "" : ctx + ".") + key + "'"));
    return *it;
}

static double num(const Json &v, const std::string &file, const std::string &what)
{
    if (!v.is_number()) throw Error(where(file, what + " must be a number"));
    const double x = v.get<double>();
    if (!std::isfinite(x)) throw Error(where(file, what + " is not finite"));
    return x;
}

static uint32_t uint(const Json &v, const std::string &file, const std::string &what)
{
    if (!v.is_number_integer() || v.get<int64_t>() < 0 || v.get<int64_t>() > 0xFFFFFFFFll)
        throw Error(where(file, what + " must be a non-negative 32-bit integer"));
    return (uint32_t)v.get<int64_t>();
}

MatC parse_cmat(const Json &v, size_t rows, size_t cols, const std::string &file, const std::string &what)
{
    if (!v.is_object() || !v.contains("re") || !v.contains("im"))
        throw Error(where(file, what + " must be {\"re\": [[...]], \"im\": [[...]]}"));
    const Json &re = v["re"], &im = v["im"];
    if (!re.is_array() || !im.is_array() || re.size() != rows || im.size() != rows)
        throw Error(where(file, what + " must have " + std::to_string(rows) + " rows"));
    MatC M((Eigen::Index)rows, (Eigen::Index)cols);
    for (size_t r = 0; r < rows; ++r) {
        if (!re[r].is_array() || !im[r].is_array() || re[r].size() != cols || im[r].size() != cols)
            throw Error(where(file, what + " must have " + std::to_string(cols) + " columns"));
        for (size_t c = 0; c < cols; ++c)
            M((Eigen::Index)r, (Eigen::Index)c) = cd(num(re[r][c], file, what), num(im[r][c], file, what));
    }
    return M;
}

// A covariance must be Hermitian with non-negative variances: a hand-edited entry that breaks either
// was taken silently (its Hermitian part) or reported as "singular weights". Tolerance: 1e-6 of the
// entries' standard deviations, far above the rounding of any writer.
static void check_covariance(const MatC &C, const std::string &path, const std::string &what)
{
    for (Eigen::Index i = 0; i < C.rows(); ++i) {
        const double v = C(i, i).real();
        if (v < 0)
            throw Error(where(path, what + " has a negative variance at [" + std::to_string(i) + "][" +
                                        std::to_string(i) + "] (" + std::to_string(v) + ")"));
        for (Eigen::Index j = 0; j <= i; ++j) {
            const double tol = 1e-6 * std::sqrt(C(i, i).real() * C(j, j).real());
            if (i == j && std::abs(C(i, i).imag()) > 0.5 * tol)
                throw Error(where(path, what + " is not Hermitian: its variance [" + std::to_string(i) + "][" +
                                            std::to_string(i) + "] has an imaginary part"));
            if (std::abs(C(i, j) - std::conj(C(j, i))) > tol)
                throw Error(where(path, what + " is not Hermitian: [" + std::to_string(i) + "][" + std::to_string(j) +
                                            "] is not the conjugate of [" + std::to_string(j) + "][" +
                                            std::to_string(i) + "]"));
        }
    }
}

FrfData read_frf(const std::string &path)
{
    return parse_frf(read_json(path), path);
}

FrfData parse_frf(const Json &j, const std::string &path)
{
    const Json &fm = need(j, "format", path);
    if (!fm.is_string() || fm.get<std::string>() != "msid-frf/1")
        throw Error(where(path, "format is " + fm.dump() + ", expected \"msid-frf/1\""));
    FrfData f;
    f.path = path;
    f.P = uint(need(j, "period_samples", path), path, "'period_samples'");
    f.nu = uint(need(j, "n_inputs", path), path, "'n_inputs'");
    f.ny = uint(need(j, "n_outputs", path), path, "'n_outputs'");
    f.m = uint(need(j, "n_experiments", path), path, "'n_experiments'");
    if (f.nu == 0 || f.ny == 0 || f.nu > 16 || f.ny > 16) throw Error(where(path, "n_inputs/n_outputs out of range"));
    if (f.m == 0 || f.m > 64) throw Error(where(path, "'n_experiments' must be 1..64"));
    const Json &dom = need(j, "domain", path);
    if (dom == "ct") f.domain = Domain::CT;
    else if (dom == "dt") f.domain = Domain::DT;
    else throw Error(where(path, "'domain' must be \"dt\" or \"ct\""));
    if (j.contains("sample_time")) {
        f.h = num(j["sample_time"], path, "'sample_time'");
        if (!(f.h > 0)) throw Error(where(path, "'sample_time' must be positive"));
    }
    // A CT file without a sample time is an analogue instrument's FRF (msid import): its lines must
    // say where they are in rad/s (omega), there being no samples to count cycles of.
    const bool ct_no_h = f.domain == Domain::CT && f.h <= 0;
    if (j.contains("method") && j["method"].is_string()) f.method = j["method"].get<std::string>();
    if (j.contains("lpm") && j["lpm"].is_object() && j["lpm"].contains("window") && j["lpm"]["window"].is_number_unsigned())
        f.lpm_window = j["lpm"]["window"].get<uint64_t>();
    // names and units: kept when they are lists of strings of the right length (readers fall back to
    // u1.., y1.. otherwise, as the Python package does)
    auto strings = [&](const char *key, size_t n) {
        std::vector<std::string> v;
        if (j.contains(key) && j[key].is_array() && j[key].size() == n)
            for (const auto &x : j[key])
                if (x.is_string()) v.push_back(x.get<std::string>());
        if (v.size() != n) v.clear();
        return v;
    };
    f.input_names = strings("input_names", f.nu);
    f.output_names = strings("output_names", f.ny);
    f.input_units = strings("input_units", f.nu);
    f.output_units = strings("output_units", f.ny);
    if (j.contains("nonlinear_distortion") && j["nonlinear_distortion"].is_object() &&
        j["nonlinear_distortion"].contains("realisations") && j["nonlinear_distortion"]["realisations"].is_number_integer())
        f.realisations = (uint32_t)std::max<int64_t>(1, j["nonlinear_distortion"]["realisations"].get<int64_t>());
    const size_t g = f.g();
    // absent from a BLA of one period per realisation (msid frf --realisations): no period-to-period noise
    if (j.contains("noise_cov")) f.noise_time = parse_cmat(j["noise_cov"], f.ny, f.ny, path, "'noise_cov'");
    const Json &lines = need(j, "lines", path);
    if (!lines.is_array() || lines.empty()) throw Error(where(path, "'lines' must be a non-empty array"));
    for (size_t k = 0; k < lines.size(); ++k) {
        const Json &e = lines[k];
        const std::string ctx = "lines[" + std::to_string(k) + "]";
        Line l;
        l.bin = uint(need(e, "bin", path, ctx), path, ctx + ".bin");
        l.freq = num(need(e, "freq", path, ctx), path, ctx + ".freq");
        if (e.contains("omega")) l.omega = num(e["omega"], path, ctx + ".omega");
        else if (ct_no_h)
            throw Error(where(path, ctx + ": a continuous-time file without 'sample_time' needs 'omega' (rad/s) at "
                                          "every line"));
        else if (f.h > 0) l.omega = 2.0 * M_PI * l.freq / f.h;
        else l.omega = 2.0 * M_PI * l.freq;
        l.real = e.contains("real") && e["real"].is_boolean() && e["real"].get<bool>();
        l.G = parse_cmat(need(e, "G", path, ctx), f.ny, f.nu, path, ctx + ".G");
        if (e.contains("cov")) {
            l.cov = parse_cmat(e["cov"], g, g, path, ctx + ".cov");
            l.dof = num(need(e, "dof", path, ctx), path, ctx + ".dof");
            if (!(l.dof >= 1)) throw Error(where(path, ctx + ".dof must be at least 1"));
        }
        if (e.contains("cov_known_input")) {
            l.cov_ki = parse_cmat(e["cov_known_input"], g, g, path, ctx + ".cov_known_input");
            l.dof_ki = e.contains("dof_known_input") ? num(e["dof_known_input"], path, ctx + ".dof_known_input") : l.dof;
            if (!(l.dof_ki >= 1)) throw Error(where(path, ctx + ".dof_known_input must be at least 1"));
        }
        if (e.contains("noise_cov")) l.noise = parse_cmat(e["noise_cov"], f.ny, f.ny, path, ctx + ".noise_cov");
        check_covariance(l.cov, path, ctx + ".cov");
        check_covariance(l.cov_ki, path, ctx + ".cov_known_input");
        f.lines.push_back(std::move(l));
    }
    // Two lines at one frequency (a hand-merged file, a copied line) made the fits interpolate two
    // different values at one point: a model 4000 times the noise level, written without a word.
    std::vector<std::pair<double, size_t>> at;
    for (size_t k = 0; k < f.lines.size(); ++k)
        at.emplace_back(f.domain == Domain::CT ? f.lines[k].omega : f.lines[k].freq, k);
    std::sort(at.begin(), at.end());
    for (size_t k = 1; k < at.size(); ++k)
        if (at[k].first == at[k - 1].first)
            throw Error(where(path, "lines[" + std::to_string(std::min(at[k - 1].second, at[k].second)) + "] and lines[" +
                                        std::to_string(std::max(at[k - 1].second, at[k].second)) +
                                        "] are at the same frequency (bin " + std::to_string(f.lines[at[k].second].bin) +
                                        "): one value per line"));
    return f;
}

// ---------------- writing ----------------

Json header(const Header &h)
{
    Json doc;
    doc["format"] = "msid-frf/1";
    doc["generator"] = std::string("msid ") + MSID_VERSION;
    doc["period_samples"] = h.period;
    doc["n_inputs"] = h.nu;
    doc["n_outputs"] = h.ny;
    doc["n_experiments"] = h.m;
    doc["domain"] = h.ct ? "ct" : "dt";
    if (h.ct || h.fs > 0) doc["sample_time"] = h.ct ? h.sample_time : 1.0 / h.fs;
    if (h.fs > 0) doc["fs_hz"] = h.fs;
    if (!h.input_names.empty()) doc["input_names"] = h.input_names;
    if (!h.output_names.empty()) doc["output_names"] = h.output_names;
    if (!h.input_units.empty()) doc["input_units"] = h.input_units;
    if (!h.output_units.empty()) doc["output_units"] = h.output_units;
    return doc;
}

Json position(const Position &p)
{
    Json e;
    e["bin"] = p.bin;
    e["freq"] = (double)p.bin / p.period;
    if (p.ct) {
        e["omega"] = p.omega;
        e["folded"] = p.folded;
        e["freq_hz"] = p.omega / (2 * M_PI);
    } else if (p.fs > 0) {
        e["freq_hz"] = (double)p.bin / p.period * p.fs;
    }
    if (p.bin == 0) e["real"] = true;
    return e;
}

Json cmat(const cd *a, size_t rows, size_t cols)
{
    // arrays sized once, rows moved in (no reallocation, no deep copies)
    Json re = Json::array(), im = Json::array();
    auto &vre = re.get_ref<Json::array_t &>(), &vim = im.get_ref<Json::array_t &>();
    vre.reserve(rows);
    vim.reserve(rows);
    for (size_t r = 0; r < rows; ++r) {
        Json rr = Json::array(), ri = Json::array();
        auto &xr = rr.get_ref<Json::array_t &>(), &xi = ri.get_ref<Json::array_t &>();
        xr.reserve(cols);
        xi.reserve(cols);
        for (size_t c = 0; c < cols; ++c) {
            xr.emplace_back(a[r * cols + c].real());
            xi.emplace_back(a[r * cols + c].imag());
        }
        vre.push_back(std::move(rr));
        vim.push_back(std::move(ri));
    }
    Json o = Json::object();
    o["re"] = std::move(re);
    o["im"] = std::move(im);
    return o;
}

Json cmat(const MatC &M)
{
    const Eigen::Matrix<cd, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> R = M;
    return cmat(R.data(), (size_t)R.rows(), (size_t)R.cols());
}

MatC from_row_major(const cd *a, size_t rows, size_t cols)
{
    using RowMajor = Eigen::Matrix<cd, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    return Eigen::Map<const RowMajor>(a, (Eigen::Index)rows, (Eigen::Index)cols);
}

Json finite_or_null(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

Json line(Json e, const LineStats &s)
{
    // room for every member first: the object is a vector of (const key, value) pairs, which a
    // reallocation copies (the const key makes the pair's move not noexcept), subtrees and all
    if (e.is_null()) e = Json::object();
    e.get_ref<Json::object_t &>().reserve(e.size() + 12);
    e["G"] = cmat(s.G);
    e["cov"] = cmat(s.cov);
    e["dof"] = s.dof;
    e["cov_known_input"] = s.cov_ki.size() ? cmat(s.cov_ki) : e["cov"];
    e["dof_known_input"] = s.cov_ki.size() ? s.dof_ki : s.dof;
    if (s.pcov.size()) e["pcov"] = cmat(s.pcov);
    if (s.noise.size()) e["noise_cov"] = cmat(s.noise);
    Json snr = Json::array();
    for (double v : s.snr) snr.push_back(finite_or_null(v));
    e["snr"] = std::move(snr);
    if (s.cond) e["cond"] = *s.cond;
    if (s.input_snr) e["input_snr"] = finite_or_null(*s.input_snr);
    return e;
}

Json experiment(const Experiment &x)
{
    Json je;
    je["source"] = x.source;
    je["samples"] = x.samples;
    je["periods_total"] = x.periods_total;
    je["periods_skipped"] = x.periods_skipped;
    je["periods_used"] = x.periods_used;
    je["periods_gap"] = x.periods_gap;
    je["periods_nonfinite"] = x.periods_nonfinite;
    if (x.transient_tested) je["transient_tested"] = *x.transient_tested;
    if (x.periods_untested) je["periods_untested"] = x.periods_untested;
    je["transient_flagged"] = x.transient_flagged;
    je["transient_dropped"] = x.transient_dropped;
    if (x.drift_block) {
        je["drift_tested"] = x.drift_tested;
        je["drift"] = x.drift;
        je["drift_p_value"] = finite_or_null(x.drift_p_value);
    }
    je["leftover_samples"] = x.leftover_samples;
    return je;
}

Json detection_line(uint32_t bin, uint32_t period, double fs, const MatC &Y_mean, const std::vector<double> &noise_var,
                    const std::vector<double> &p_value)
{
    Json e;
    e["bin"] = bin;
    e["freq"] = (double)bin / period;
    if (fs > 0) e["freq_hz"] = (double)bin / period * fs;
    e["Y_mean"] = cmat(Y_mean);
    e["noise_var"] = noise_var;
    e["p_value"] = p_value;
    return e;
}

}  // namespace msidfrf

// ---------------- text ----------------

namespace msidfrf {

char *format_double(double v, char *buf)
{
    char *p = buf;
    if (std::signbit(v)) { *p++ = '-'; v = -v; }
    if (v == 0) { std::memcpy(p, "0.0", 3); return p + 3; }
    // shortest round-trip digits d[.ddd]e[+-]x from std::to_chars, then nlohmann's layout
    // (detail::format_buffer with min_exp = -4, max_exp = 15)
    char s[40];
    const auto r = std::to_chars(s, s + sizeof s, v, std::chars_format::scientific);
    char dig[24];
    int k = 0;
    const char *q = s;
    for (; q < r.ptr && *q != 'e'; ++q)
        if (*q != '.') dig[k++] = *q;
    int e10 = 0;
    std::from_chars(q + 1 + (q[1] == '+'), r.ptr, e10);
    const int n = e10 + 1;   // position of the decimal point after the first n digits
    if (k <= n && n <= 15) {   // integer: digits, zeros, ".0"
        std::memcpy(p, dig, (size_t)k);
        std::memset(p + k, '0', (size_t)(n - k));
        p += n;
        *p++ = '.';
        *p++ = '0';
        return p;
    }
    if (0 < n && n <= 15) {   // 12.34
        std::memcpy(p, dig, (size_t)n);
        p[n] = '.';
        std::memcpy(p + n + 1, dig + n, (size_t)(k - n));
        return p + k + 1;
    }
    if (-4 < n && n <= 0) {   // 0.00123
        *p++ = '0';
        *p++ = '.';
        std::memset(p, '0', (size_t)-n);
        p += -n;
        std::memcpy(p, dig, (size_t)k);
        return p + k;
    }
    *p++ = dig[0];
    if (k > 1) {
        *p++ = '.';
        std::memcpy(p, dig + 1, (size_t)(k - 1));
        p += k - 1;
    }
    *p++ = 'e';
    int x = n - 1;
    *p++ = x < 0 ? '-' : '+';
    if (x < 0) x = -x;
    if (x < 10) { *p++ = '0'; *p++ = (char)('0' + x); }
    else if (x < 100) { *p++ = (char)('0' + x / 10); *p++ = (char)('0' + x % 10); }
    else { *p++ = (char)('0' + x / 100); *p++ = (char)('0' + x / 10 % 10); *p++ = (char)('0' + x % 10); }
    return p;
}

static void dump_string(const std::string &s, std::string &out)
{
    out += '"';
    size_t a = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        const unsigned char c = (unsigned char)s[i];
        if (c >= 0x20 && c != '"' && c != '\\') continue;
        out.append(s, a, i - a);
        a = i + 1;
        switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\b': out += "\\b"; break;
        case '\f': out += "\\f"; break;
        case '\n': out += "\\n"; break;
        case '\r': out += "\\r"; break;
        case '\t': out += "\\t"; break;
        default: {
            char u[8];
            std::snprintf(u, sizeof u, "\\u%04x", c);
            out += u;
        }
        }
    }
    out.append(s, a, std::string::npos);
    out += '"';
}

static void dump_at(const Json &v, int indent, int level, std::string &out, bool split = false);

// Arrays of at least this many elements (an FRF file's lines) are written by two threads.
static const size_t SPLIT_MIN_ELEMENTS = 64;

// The elements [i0, i1) of array `v` at `level`, each on its own line after ",\n" (the first one
// after none when i0 == 0): the text dump_at writes between "[\n" and the closing "\n]".
static void dump_elements(const Json &v, size_t i0, size_t i1, int indent, int level, std::string &out)
{
    for (size_t i = i0; i < i1; ++i) dump_element(v[i], i, indent, level, out);
}

void dump_element(const Json &e, size_t i, int indent, int level, std::string &out)
{
    if (i) out += ",\n";
    out.append((size_t)(indent * (level + 1)), ' ');
    dump_at(e, indent, level + 1, out);
}

// line_element(): the layout of dump_at() written member by member. A value at `level` opens
// with "{\n" or "[\n"; its members or elements each start with ",\n" (but the first) and
// indent * (level + 1) spaces; it closes with "\n", indent * level spaces and "}" or "]".
namespace {
// Writes through a raw pointer into room reserved for the whole line (line_element sizes it from
// an upper bound of every token): no capacity check per append, of which a line has hundreds).
struct LineWriter {
    char *w;
    char *end;   // the scratch's end: every element checks its room first (sep)
    int indent;
    char buf[48];
    void put(const char *t, size_t n)
    {
        std::memcpy(w, t, n);
        w += n;
    }
    void put(const char *t) { put(t, std::strlen(t)); }
    void put(char c) { *w++ = c; }
    void pad(int level)
    {
        const size_t n = (size_t)(indent * level);
        std::memset(w, ' ', n);
        w += n;
    }
    // before every member and element: room for ",\n", the padding and the longest token that
    // follows (a number <= 26, a key <= 24 chars) with its brackets, or stop before any overrun
    void sep(size_t k, int level)
    {
        if ((size_t)(end - w) < (size_t)(indent * (level + 2)) + 64u) std::abort();
        if (k) put(",\n", 2);
        pad(level);
    }
    void close(int level, char c)
    {
        if ((size_t)(end - w) < (size_t)(indent * level) + 64u) std::abort();
        put('\n');
        pad(level);
        put(c);
    }
    // member k of an object at `level`: ",\n", the indent, "\"key\": " (keys need no escapes)
    void key(size_t k, int level, const char *name)
    {
        sep(k, level + 1);
        put('"');
        put(name);
        put("\": ", 3);
    }
    void num(double v)
    {
        if (!std::isfinite(v)) throw NonFinite();
        w = format_double(v, w);
    }
    void num_or_null(double v)
    {
        if (std::isfinite(v)) w = format_double(v, w);
        else put("null", 4);
    }
    void uns(uint64_t v) { w = std::to_chars(w, w + 24, v).ptr; }
    // cmat(): {"re": [[...], ...], "im": [[...], ...]} of a row-major rows x cols array at `level`.
    // A covariance is Hermitian: an element below the diagonal whose value is, bit for bit, the
    // conjugate of its mirror above takes the mirror's text (re as is, im with its sign flipped:
    // format_double writes '-' exactly when the sign bit is set), not a second formatting (finding
    // the shortest digits is the dear part of writing a number; half of a line's numbers are mirrors).
    void cmat(const cd *a, size_t rows, size_t cols, int level)
    {
        constexpr size_t MAXM = 256;   // mirrors kept for matrices of up to 256 elements
        struct Span { const char *at; size_t n; };
        Span sp[MAXM];
        const bool square = rows == cols && rows * cols <= MAXM;
        put("{\n", 2);
        for (int part = 0; part < 2; ++part) {
            key((size_t)part, level, part ? "im" : "re");
            if (!rows) { put("[]", 2); continue; }
            put("[\n", 2);
            for (size_t r = 0; r < rows; ++r) {
                sep(r, level + 2);
                if (!cols) { put("[]", 2); continue; }
                put("[\n", 2);
                for (size_t c = 0; c < cols; ++c) {
                    sep(c, level + 3);
                    const double v = part ? a[r * cols + c].imag() : a[r * cols + c].real();
                    char *const at0 = w;
                    const Span t = square && c < r ? sp[c * cols + r] : Span{nullptr, 0};
                    const double m = !t.at ? 0.0 : part ? -a[c * cols + r].imag() : a[c * cols + r].real();
                    if (t.at && std::memcmp(&v, &m, sizeof v) == 0) {   // the mirror's text (finite)
                        if (!part) put(t.at, t.n);
                        else if (t.at[0] == '-') put(t.at + 1, t.n - 1);
                        else {
                            put('-');
                            put(t.at, t.n);
                        }
                    } else {
                        num(v);
                    }
                    if (square) sp[r * cols + c] = {at0, (size_t)(w - at0)};
                }
                close(level + 2, ']');
            }
            close(level + 1, ']');
        }
        close(level, '}');
    }
};
}  // namespace

void line_element(const Position &p, const LineArrays &a, size_t i, int indent, int level, std::string &out)
{
    const int L = level + 1;   // the line object's level; members as position() and line() add them
    const size_t g = a.ny * a.nu;
    // Room: every token bounded (a number <= 26 chars, a key <= 24, padding <= indent * (L + 4)),
    // twice over; LineWriter::sep checks the room before each element all the same.
    const size_t nums = 2 * g + 4 * g * g + 2 * a.ny * a.ny + a.ny + 8, rows = 4 * (a.ny + 2 * g) + 8;
    const size_t line_w = 32 + (size_t)indent * (size_t)(L + 4);
    const size_t room = 2 * (1024 + (nums + 2 * rows + 64) * line_w);
    // the line is written into this thread's scratch (not zero-filled, kept between lines), then
    // appended once
    thread_local std::unique_ptr<char[]> scratch;
    thread_local size_t scratch_n = 0;
    if (scratch_n < room) {
        scratch.reset(new char[room]);
        scratch_n = room;
    }
    char *const end = scratch.get() + room;
    LineWriter w{scratch.get(), end, indent, {}};
    if (i) w.put(",\n", 2);
    w.pad(level + 1);
    size_t k = 0;
    w.put("{\n", 2);
    w.key(k++, L, "bin");
    w.uns(p.bin);
    w.key(k++, L, "freq");
    w.num((double)p.bin / p.period);
    if (p.ct) {
        w.key(k++, L, "omega");
        w.num(p.omega);
        w.key(k++, L, "folded");
        w.put(p.folded ? "true" : "false");
        w.key(k++, L, "freq_hz");
        w.num(p.omega / (2 * M_PI));
    } else if (p.fs > 0) {
        w.key(k++, L, "freq_hz");
        w.num((double)p.bin / p.period * p.fs);
    }
    if (p.bin == 0) {
        w.key(k++, L, "real");
        w.put("true", 4);
    }
    {
        w.key(k++, L, "G");
        w.cmat(a.G, a.ny, a.nu, L + 1);
        w.key(k++, L, "cov");
        w.cmat(a.cov, g, g, L + 1);
        w.key(k++, L, "dof");
        w.num(a.dof);
        w.key(k++, L, "cov_known_input");
        w.cmat(a.cov_ki ? a.cov_ki : a.cov, g, g, L + 1);
        w.key(k++, L, "dof_known_input");
        w.num(a.cov_ki ? a.dof_ki : a.dof);
        if (a.noise) {
            w.key(k++, L, "noise_cov");
            w.cmat(a.noise, a.ny, a.ny, L + 1);
        }
        w.key(k++, L, "snr");
        if (!a.ny) w.put("[]", 2);
        else {
            w.put("[\n", 2);
            for (size_t y = 0; y < a.ny; ++y) {
                w.sep(y, L + 2);
                w.num_or_null(a.snr[y]);
            }
            w.close(L + 1, ']');
        }
        if (a.cond) {
            w.key(k++, L, "cond");
            w.num(*a.cond);
        }
        if (a.input_snr) {
            w.key(k++, L, "input_snr");
            w.num_or_null(*a.input_snr);
        }
        w.close(L, '}');
    }   // NonFinite thrown above: nothing of this line is in `out`
    out.append(scratch.get(), (size_t)(w.w - scratch.get()));
}

// The largest array's text in two halves on two threads, appended in order: the same bytes as
// one thread writes. An exception (NonFinite) of either half is rethrown after both are done.
// Both strings are sized once from the first element's text (elements of an FRF file's lines
// are alike): growing by doubling would copy each string into fresh pages several times.
static void dump_elements_split(const Json &v, int indent, int level, std::string &out)
{
    const size_t n = v.size(), h = n / 2;
    std::string first;
    dump_at(v[0], indent, level + 1, first);
    const size_t per = first.size() + (size_t)(indent * (level + 1)) + 2;   // ",\n", indent, text
    const size_t slack = per / 4 + 64;
    out.reserve(out.size() + n * (per + slack) + 4096);
    out.append((size_t)(indent * (level + 1)), ' ');
    out += first;
    std::string second;
    std::exception_ptr err;
    std::thread th;
    try {
        th = std::thread([&] {
            try {
                second.reserve((n - h) * (per + slack));
                dump_elements(v, h, n, indent, level, second);
            } catch (...) {
                err = std::current_exception();
            }
        });
    } catch (const std::system_error &) {   // no thread to be had: one after the other
        dump_elements(v, 1, n, indent, level, out);
        return;
    }
    try {
        dump_elements(v, 1, h, indent, level, out);
    } catch (...) {
        th.join();
        throw;
    }
    th.join();
    if (err) std::rethrow_exception(err);
    out += second;
}

static void dump_at(const Json &v, int indent, int level, std::string &out, bool split)
{
    char buf[48];
    switch (v.type()) {
    case Json::value_t::object: {
        if (v.empty()) { out += "{}"; return; }
        out += "{\n";
        size_t i = 0;
        for (auto it = v.begin(); it != v.end(); ++it, ++i) {
            if (i) out += ",\n";
            out.append((size_t)(indent * (level + 1)), ' ');
            dump_string(it.key(), out);
            out += ": ";
            dump_at(it.value(), indent, level + 1, out, split);
        }
        out += '\n';
        out.append((size_t)(indent * level), ' ');
        out += '}';
        return;
    }
    case Json::value_t::array: {
        if (v.empty()) { out += "[]"; return; }
        out += "[\n";
        if (split && v.size() >= SPLIT_MIN_ELEMENTS) dump_elements_split(v, indent, level, out);
        else dump_elements(v, 0, v.size(), indent, level, out);
        out += '\n';
        out.append((size_t)(indent * level), ' ');
        out += ']';
        return;
    }
    case Json::value_t::string: dump_string(v.get_ref<const std::string &>(), out); return;
    case Json::value_t::boolean: out += v.get<bool>() ? "true" : "false"; return;
    case Json::value_t::number_integer: {
        const auto r = std::to_chars(buf, buf + sizeof buf, v.get<int64_t>());
        out.append(buf, r.ptr);
        return;
    }
    case Json::value_t::number_unsigned: {
        const auto r = std::to_chars(buf, buf + sizeof buf, v.get<uint64_t>());
        out.append(buf, r.ptr);
        return;
    }
    case Json::value_t::number_float: {
        const double x = v.get<double>();
        if (!std::isfinite(x)) throw NonFinite();
        out.append(buf, format_double(x, buf));
        return;
    }
    case Json::value_t::null:
    case Json::value_t::discarded:
    default: out += "null"; return;
    }
}

void dump(const Json &doc, int indent, std::string &out, bool two_threads)
{
    dump_at(doc, indent, 0, out, two_threads && std::thread::hardware_concurrency() >= 2);
}

}  // namespace msidfrf
