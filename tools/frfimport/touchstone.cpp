// Touchstone 1.x (.sNp) of network analysers: an N-port's S, Y, Z, H or G parameters over frequency,
// a continuous-time FRF without a sample time. The option line "# <Hz|kHz|MHz|GHz> <S|Y|Z|H|G>
// <RI|MA|DB> R <n>" (defaults GHz S MA R 50); '!' starts a comment; a 2-port row is N11 N21 N12 N22
// (the format's quirk), any other row N11 N12 .. N1N N21 .. row by row, and for N >= 3 a row may
// continue on the next lines; a 2-port file's noise parameters follow its data, starting at a
// frequency not above the last one, and are not an FRF (left out). Y, Z, H and G values of 1.x are
// normalised to R and are returned in ohms, siemens and their mixtures.
// Touchstone 2.x (a first line "[Version] 2.0", any extension, .ts by convention): the keywords before
// [Network Data] give the port count, the 2-port order (12_21 row by row, 21_12 as 1.x), the point
// count, per-port references and the matrix format (Full, or the Lower / Upper triangle of a
// symmetric matrix); a point's numbers run over as many lines as they need; Y, Z, H and G are not
// normalised; [Noise Data] is not an FRF (left out); mixed-mode data is refused.
#include "frf_import.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

namespace msidfrfimport {

namespace {

struct Options {
    double hz_per_unit = 1e9;
    char param = 'S';
    std::string data = "MA";
    double R = 50.0;
    std::string unit = "GHz";
};

std::string upper(std::string s)
{
    for (auto &c : s) c = (char)std::toupper((unsigned char)c);
    return s;
}

// The port count of the extension (.s2p: 2), 0 when the name carries none.
uint32_t ports_of_name(const std::string &path)
{
    const size_t dot = path.rfind('.');
    if (dot == std::string::npos) return 0;
    const std::string e = upper(path.substr(dot + 1));
    if (e.size() < 3 || e.size() > 4 || e.front() != 'S' || e.back() != 'P') return 0;
    uint32_t n = 0;
    for (size_t i = 1; i + 1 < e.size(); ++i) {
        if (!std::isdigit((unsigned char)e[i])) return 0;
        n = 10 * n + (uint32_t)(e[i] - '0');
    }
    return n;
}

Options parse_options(const std::string &path, size_t lineno, const std::string &line)
{
    Options o;
    std::vector<std::string> t;
    size_t i = 1;
    while (i < line.size()) {
        while (i < line.size() && std::isspace((unsigned char)line[i])) ++i;
        size_t j = i;
        while (j < line.size() && !std::isspace((unsigned char)line[j])) ++j;
        if (j > i) t.push_back(upper(line.substr(i, j - i)));
        i = j;
    }
    for (size_t k = 0; k < t.size(); ++k) {
        const std::string &w = t[k];
        if (w == "HZ" || w == "KHZ" || w == "MHZ" || w == "GHZ") {
            o.hz_per_unit = w == "HZ" ? 1.0 : w == "KHZ" ? 1e3 : w == "MHZ" ? 1e6 : 1e9;
            o.unit = w == "HZ" ? "Hz" : w.substr(0, 1) + "Hz";
        } else if (w.size() == 1 && std::string("SYZHG").find(w[0]) != std::string::npos) {
            o.param = w[0];
        } else if (w == "RI" || w == "MA" || w == "DB") {
            o.data = w;
        } else if (w == "R" && k + 1 < t.size()) {
            const char *s = t[k + 1].c_str();
            double r = 0;
            if (!take_number(s, s + t[k + 1].size(), r) || *s || !(r > 0) || !std::isfinite(r))
                throw Error(at_line(path, lineno, "the reference resistance R must be a positive number (got '" +
                                                      t[k + 1] + "')"));
            o.R = r;
            ++k;
        } else {
            throw Error(at_line(path, lineno, "option '" + w + "' is not Touchstone 1.x's (# <Hz|kHz|MHz|GHz> "
                                                "<S|Y|Z|H|G> <RI|MA|DB> R <n>)"));
        }
    }
    return o;
}

cd value(const Options &o, double a, double b)
{
    if (o.data == "RI") return cd(a, b);
    const double mag = o.data == "MA" ? a : std::pow(10.0, a / 20.0);
    return std::polar(mag, b * M_PI / 180.0);
}

// One frequency point's numbers (1 + 2 N^2) as the N x N matrix, de-normalised (1.x: Y, Z, H, G
// are stored divided or multiplied by R).
MatC point_matrix(const Options &o, const std::vector<double> &v, uint32_t N)
{
    MatC M(N, N);
    for (uint32_t k = 0; k < N * N; ++k) {
        const cd x = value(o, v[1 + 2 * k], v[2 + 2 * k]);
        const uint32_t r = N == 2 ? k % 2 : k / N, c = N == 2 ? k / 2 : k % N;   // 2-port: N11 N21 N12 N22
        M(r, c) = x;
    }
    const double R = o.R;
    if (o.param == 'Z') M *= R;
    if (o.param == 'Y') M /= R;
    if (o.param == 'H') { M(0, 0) *= R; M(1, 1) /= R; }
    if (o.param == 'G') { M(0, 0) /= R; M(1, 1) *= R; }
    return M;
}

// The signals of an N-port's parameters: S maps incident waves a_j to reflected ones b_i, Z currents
// to voltages, Y voltages to currents, H [I1, V2] to [V1, I2], G [V1, I2] to [I1, V2].
void name_signals(Imported &im, char param, uint32_t N)
{
    for (uint32_t p = 1; p <= N; ++p) {
        const std::string k = std::to_string(p);
        std::string in, out, iu, ou;
        switch (param) {
        case 'S': in = "a" + k; out = "b" + k; break;
        case 'Z': in = "I" + k; out = "V" + k; iu = "A"; ou = "V"; break;
        case 'Y': in = "V" + k; out = "I" + k; iu = "V"; ou = "A"; break;
        case 'H': in = p == 1 ? "I1" : "V2"; out = p == 1 ? "V1" : "I2"; iu = p == 1 ? "A" : "V"; ou = p == 1 ? "V" : "A"; break;
        default: in = p == 1 ? "V1" : "I2"; out = p == 1 ? "I1" : "V2"; iu = p == 1 ? "V" : "A"; ou = p == 1 ? "A" : "V"; break;
        }
        im.input_names.push_back(in);
        im.output_names.push_back(out);
        im.input_units.push_back(iu);
        im.output_units.push_back(ou);
    }
}

// The next line of `text` from offset a (a moves past it), its '!' comment cut; false at the end.
bool next_line(const std::string &text, size_t &a, std::string &line)
{
    if (a >= text.size()) return false;
    size_t b = text.find('\n', a);
    if (b == std::string::npos) b = text.size();
    line = text.substr(a, b - a);
    a = b + 1;
    const size_t bang = line.find('!');
    if (bang != std::string::npos) line.resize(bang);
    return true;
}

// The keyword of a Touchstone 2.x line ("[Number of Ports]" -> "NUMBER OF PORTS") and what follows it.
bool keyword(const std::string &line, std::string &key, std::string &rest)
{
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] != '[') return false;
    const size_t close = line.find(']', first);
    if (close == std::string::npos) return false;
    key.clear();
    for (size_t i = first + 1; i < close; ++i) {
        const char c = (char)std::toupper((unsigned char)line[i]);
        if (std::isspace((unsigned char)c)) {
            if (!key.empty() && key.back() != ' ') key += ' ';
        } else {
            key += c;
        }
    }
    while (!key.empty() && key.back() == ' ') key.pop_back();
    rest = line.substr(close + 1);
    return true;
}

// The numbers of a line (after its comment is cut); throws naming a cell that is not one.
std::vector<double> numbers_of(const std::string &path, size_t lineno, const std::string &line)
{
    std::vector<double> nums;
    const char *s = line.c_str(), *end = s + line.size();
    while (s < end && std::isspace((unsigned char)*s)) ++s;
    double x;
    while (take_number(s, end, x)) nums.push_back(x);
    while (s < end && std::isspace((unsigned char)*s)) ++s;
    if (s != end) throw Error(at_line(path, lineno, "'" + std::string(s, end) + "' is not a number"));
    return nums;
}

// A keyword's one positive integer (the port or point count).
uint32_t count_of(const std::string &path, size_t lineno, const std::string &key, const std::string &rest,
                  uint32_t max)
{
    const std::vector<double> v = numbers_of(path, lineno, rest);
    if (v.size() != 1 || !(v[0] >= 1) || v[0] > max || v[0] != std::floor(v[0]))
        throw Error(at_line(path, lineno, "[" + key + "] must be one whole number from 1 to " + std::to_string(max)));
    return (uint32_t)v[0];
}

Imported read_touchstone2(const std::string &path, const std::string &text)
{
    Options o;
    bool have_options = false, order_21_12 = false, order_given = false, in_data = false, in_info = false;
    uint32_t N = 0, F = 0;
    char fmt_m = 'F';               // Full, Lower, Upper
    std::vector<double> refs;       // [Reference]: one per port, maybe over several lines
    bool reading_refs = false;
    std::vector<double> point;
    size_t point_line = 0, per = 0, lineno = 0;
    double last_f = -1.0;
    Imported im;
    im.path = path;
    im.format = "touchstone";
    auto need = [&](bool ok, size_t at, const std::string &what) {
        if (!ok) throw Error(at_line(path, at, what));
    };
    std::string line;
    for (size_t a = 0; next_line(text, a, line);) {
        ++lineno;
        const size_t first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos) continue;
        std::string key, rest;
        if (keyword(line, key, rest)) {
            reading_refs = false;
            if (in_info) {
                in_info = key != "END INFORMATION";
                continue;
            }
            if (key == "VERSION") {
                const std::vector<double> v = numbers_of(path, lineno, rest);
                need(v.size() == 1 && v[0] >= 2.0 && v[0] < 3.0, lineno, "msid reads Touchstone 1.x and 2.x files");
            } else if (key == "NUMBER OF PORTS") {
                N = count_of(path, lineno, key, rest, 16);
            } else if (key == "TWO-PORT DATA ORDER") {
                std::string r = upper(rest);
                r.erase(std::remove_if(r.begin(), r.end(), [](char c) { return std::isspace((unsigned char)c); }), r.end());
                need(r == "12_21" || r == "21_12", lineno, "[Two-Port Data Order] is 12_21 or 21_12");
                order_21_12 = r == "21_12";
                order_given = true;
            } else if (key == "NUMBER OF FREQUENCIES") {
                F = count_of(path, lineno, key, rest, 0x7FFFFFFF);
            } else if (key == "NUMBER OF NOISE FREQUENCIES") {
            } else if (key == "REFERENCE") {
                refs = numbers_of(path, lineno, rest);
                reading_refs = true;
            } else if (key == "MATRIX FORMAT") {
                std::string r = upper(rest);
                r.erase(std::remove_if(r.begin(), r.end(), [](char c) { return std::isspace((unsigned char)c); }), r.end());
                need(r == "FULL" || r == "LOWER" || r == "UPPER", lineno, "[Matrix Format] is Full, Lower or Upper");
                fmt_m = r[0];
            } else if (key == "MIXED-MODE ORDER") {
                need(false, lineno, "mixed-mode parameters: msid imports single-ended ones only");
            } else if (key == "BEGIN INFORMATION") {
                in_info = true;
            } else if (key == "NETWORK DATA") {
                need(have_options, lineno, "[Network Data] before the option line (# Hz S RI R 50)");
                need(N > 0, lineno, "[Network Data] before [Number of Ports]");
                need(F > 0, lineno, "[Network Data] before [Number of Frequencies]");
                need(N != 2 || order_given, lineno, "a 2-port file needs [Two-Port Data Order] 12_21 or 21_12");
                need(refs.empty() || refs.size() == N, lineno,
                     "[Reference] gives " + std::to_string(refs.size()) + " value(s) for " + std::to_string(N) + " ports");
                per = 1 + 2 * (fmt_m == 'F' ? (size_t)N * N : (size_t)N * (N + 1) / 2);
                in_data = true;
            } else if (key == "NOISE DATA" || key == "END") {
                break;
            } else {
                need(false, lineno, "[" + key + "] is not a Touchstone 2.x keyword msid knows");
            }
            continue;
        }
        if (in_info) continue;
        if (line[first] == '#') {
            if (!have_options) o = parse_options(path, lineno, line.substr(first));
            have_options = true;
            continue;
        }
        const std::vector<double> nums = numbers_of(path, lineno, line);
        if (reading_refs) {   // [Reference] continues on the next lines
            refs.insert(refs.end(), nums.begin(), nums.end());
            continue;
        }
        need(in_data, lineno, "numbers before [Network Data]");
        if (point.empty()) point_line = lineno;
        for (double x : nums) {
            point.push_back(x);
            if (point.size() < per) continue;
            need(im.omega.size() < F, point_line,
                 "more points than [Number of Frequencies] " + std::to_string(F));
            const double f = point[0] * o.hz_per_unit;
            need(std::isfinite(f), point_line, "the frequency is not finite");
            need(f > last_f, point_line, "frequency " + std::to_string(point[0]) + " " + o.unit +
                                             " is not above the previous one: Touchstone frequencies increase");
            last_f = f;
            MatC M(N, N);
            size_t k = 0;
            for (uint32_t r = 0; r < N; ++r)
                for (uint32_t c = 0; c < N; ++c) {
                    if ((fmt_m == 'L' && c > r) || (fmt_m == 'U' && c < r)) continue;
                    const cd v = value(o, point[1 + 2 * k], point[2 + 2 * k]);
                    ++k;
                    const bool swap = N == 2 && order_21_12;   // 11 21 12 22, as 1.x
                    M(swap ? c : r, swap ? r : c) = v;
                    if (fmt_m != 'F') M(c, r) = v;
                }
            im.omega.push_back(2 * M_PI * f);
            im.G.push_back(M);
            point.clear();
        }
    }
    if (!point.empty())
        throw Error(at_line(path, point_line, "the last point is cut short: " + std::to_string(point.size()) + " of " +
                                                  std::to_string(per) + " numbers (a truncated file?)"));
    if (!in_data) throw Error("'" + path + "' has no [Network Data]");
    if (im.omega.size() != F)
        throw Error("'" + path + "' holds " + std::to_string(im.omega.size()) + " points, but [Number of Frequencies] says " +
                    std::to_string(F) + " (a truncated file?)");
    if ((o.param == 'H' || o.param == 'G') && N != 2)
        throw Error("'" + path + "': " + std::string(1, o.param) + " parameters are a 2-port's, the file has " +
                    std::to_string(N) + " port" + (N == 1 ? "" : "s"));
    im.nu = im.ny = N;
    im.ct = true;
    name_signals(im, o.param, N);
    im.info["version"] = "2";
    im.info["parameter"] = std::string(1, o.param);
    if (refs.empty()) im.info["reference_resistance_ohm"] = o.R;
    else im.info["reference_resistance_ohm"] = refs;
    im.info["frequency_unit"] = o.unit;
    im.info["data_format"] = o.data;
    im.info["matrix_format"] = fmt_m == 'F' ? "full" : fmt_m == 'L' ? "lower" : "upper";
    return im;
}

// Does the file start (after comments and blank lines) with "[Version]"?
bool is_version2(const std::string &text)
{
    std::string line;
    for (size_t a = 0; next_line(text, a, line);) {
        std::string key, rest;
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        return keyword(line, key, rest) && key == "VERSION";
    }
    return false;
}

}  // namespace

Imported read_touchstone(const std::string &path)
{
    const std::string text = read_text(path);
    if (is_version2(text)) return read_touchstone2(path, text);
    uint32_t N = ports_of_name(path);
    if (N > 16) throw Error("'" + path + "': a " + std::to_string(N) + "-port file; msid takes at most 16 ports");
    Options o;
    bool have_options = false;
    std::vector<double> point;      // the numbers of the point being read
    size_t point_line = 0;          // where it started
    double last_f = -1.0;
    bool noise = false;
    Imported im;
    im.path = path;
    im.format = "touchstone";
    size_t lineno = 0;
    std::string line;
    for (size_t a = 0; !noise && next_line(text, a, line);) {
        ++lineno;
        const size_t first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos) continue;
        if (line[first] == '#') {   // only the first option line counts (1.x)
            if (!have_options) o = parse_options(path, lineno, line.substr(first));
            have_options = true;
            continue;
        }
        if (line[first] == '[')
            throw Error(at_line(path, lineno, "a Touchstone 2.x keyword in a file without [Version] 2.0 first"));
        std::vector<double> nums;
        const char *s = line.c_str() + first, *end = line.c_str() + line.size();
        double x;
        while (take_number(s, end, x)) nums.push_back(x);
        while (s < end && std::isspace((unsigned char)*s)) ++s;
        if (s != end) throw Error(at_line(path, lineno, "'" + std::string(s, end) + "' is not a number"));
        if (N == 0) {   // no port count in the name: a 1- or 2-port by the first row
            if (nums.size() == 3 || nums.size() == 9) N = nums.size() == 3 ? 1 : 2;
            else
                throw Error(at_line(path, lineno, "the file name has no port count (.sNp) and the row's " +
                                                      std::to_string(nums.size()) + " numbers are not a 1- or 2-port's"));
        }
        const size_t per = 1 + 2 * (size_t)N * N;
        if (point.empty()) {
            // a 2-port's noise parameters start at a frequency not above the last one: not an FRF
            if (N == 2 && !im.omega.empty() && nums.size() == 5 && nums[0] * o.hz_per_unit <= last_f) {
                noise = true;
                break;
            }
            point_line = lineno;
        }
        if (N <= 2 && nums.size() != per)
            throw Error(at_line(path, lineno, std::to_string(nums.size()) + " numbers, but a row of a " +
                                                  std::to_string(N) + "-port file (.s" + std::to_string(N) + "p) has " +
                                                  std::to_string(per) + " (the frequency and " + std::to_string(N * N) +
                                                  " pairs): does the file hold as many ports as its name says?"));
        if (point.size() + nums.size() > per)
            throw Error(at_line(path, lineno, "the point that starts on line " + std::to_string(point_line) + " has " +
                                                  std::to_string(point.size() + nums.size()) + " numbers, more than the " +
                                                  std::to_string(per) + " of a " + std::to_string(N) +
                                                  "-port (the frequency and " + std::to_string(N * N) +
                                                  " pairs): does the file hold as many ports as its name says?"));
        point.insert(point.end(), nums.begin(), nums.end());
        if (point.size() < per) continue;
        const double f = point[0] * o.hz_per_unit;
        if (!(f > last_f))
            throw Error(at_line(path, point_line, "frequency " + std::to_string(point[0]) + " " + o.unit +
                                                      " is not above the previous one: Touchstone frequencies increase"));
        if (!std::isfinite(f)) throw Error(at_line(path, point_line, "the frequency is not finite"));
        // H and G are a 2-port's (their de-normalisation indexes [1][1]; fuzz_frf_import found a 1-port H)
        if ((o.param == 'H' || o.param == 'G') && N != 2)
            throw Error("'" + path + "': " + std::string(1, o.param) + " parameters are a 2-port's, the file has " +
                        std::to_string(N) + " port" + (N == 1 ? "" : "s"));
        last_f = f;
        im.omega.push_back(2 * M_PI * f);
        im.G.push_back(point_matrix(o, point, N));
        point.clear();
    }
    if (!point.empty())
        throw Error(at_line(path, point_line, "the last point is cut short: " + std::to_string(point.size()) + " of " +
                                                  std::to_string(1 + 2 * (size_t)N * N) + " numbers (a truncated file, " +
                                                  "or not a " + std::to_string(N) + "-port?)"));
    if (im.omega.empty()) throw Error("'" + path + "' holds no Touchstone data rows");
    im.nu = im.ny = N;
    im.ct = true;
    name_signals(im, o.param, N);
    im.info["parameter"] = std::string(1, o.param);
    im.info["reference_resistance_ohm"] = o.R;
    im.info["frequency_unit"] = o.unit;
    im.info["data_format"] = o.data;
    if (noise) im.info["noise_parameters"] = "present, not imported (not an FRF)";
    return im;
}

}  // namespace msidfrfimport
