// Universal File Format (UFF/UNV) dataset 58 in ASCII, as modal test suites write FRFs: one dataset
// per response/reference pair, each delimited by "-1" lines. Record 6 names the function type (4:
// FRF), the response and reference node and direction; record 7 the ordinate data type (5, 6:
// complex single, double), the number of values and the abscissa spacing (1: even, from min and
// increment; 0: uneven, an abscissa before each value); records 8, 9, 10 the abscissa's, numerator's
// (response) and denominator's (reference) units. The datasets of one file make one MIMO FRF: the
// distinct references are its inputs, the responses its outputs, every pair present once, all on one
// abscissa. Binary 58b (the same records, then the numbers as IEEE 754 bytes) is read too. Other
// datasets (geometry, units, time histories) are skipped.
#include "frf_import.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>

namespace msidfrfimport {

namespace {

struct Text {
    const std::string &path;
    const std::string &s;
    std::vector<std::pair<size_t, size_t>> lines;   // [begin, end) of each line, '\r' left out
    std::string line(size_t k) const { return s.substr(lines[k].first, lines[k].second - lines[k].first); }
};

std::string trim(const std::string &v)
{
    const size_t a = v.find_first_not_of(" \t"), b = v.find_last_not_of(" \t");
    return a == std::string::npos ? "" : v.substr(a, b - a + 1);
}

// Columns [a, a + n) of a fixed-format record (short lines are blank-padded).
std::string field(const std::string &line, size_t a, size_t n) { return a >= line.size() ? "" : line.substr(a, n); }

long long int_field(const Text &t, size_t k, size_t a, size_t n, const char *what)
{
    const std::string f = trim(field(t.line(k), a, n));
    long long v = 0;
    size_t used = 0;
    try {
        v = std::stoll(f, &used);
    } catch (const std::exception &) {
        used = 0;
    }
    if (f.empty() || used != f.size())
        throw Error(at_line(t.path, k + 1, std::string(what) + " must be an integer (got '" + f + "')"));
    return v;
}

struct Signal {
    std::string entity;
    long long node = 0;
    long long dir = 0;
    bool operator<(const Signal &o) const
    {
        return entity != o.entity ? entity < o.entity : node != o.node ? node < o.node : dir < o.dir;
    }
    bool operator==(const Signal &o) const { return entity == o.entity && node == o.node && dir == o.dir; }
    // "101+Z" (an entity name other than NONE in front: "beam:101+Z")
    std::string name() const
    {
        static const char *d[] = {"", "X", "Y", "Z", "RX", "RY", "RZ"};
        std::string s = std::to_string(node);
        if (dir != 0 && std::llabs(dir) <= 6) s += (dir > 0 ? "+" : "-") + std::string(d[std::llabs(dir)]);
        else if (dir != 0) s += ":" + std::to_string(dir);
        const std::string e = entity;
        return e.empty() || e == "NONE" ? s : e + ":" + s;
    }
};

struct Dataset {
    size_t at = 0;              // its "58" line
    Signal rsp, ref;
    std::string x_unit, num_unit, den_unit;
    std::vector<double> x;      // abscissa as given
    std::vector<cd> y;
};

// What records 6 to 10 of a dataset 58 say: its signals and units, and how its data are laid out.
struct Layout {
    size_t n = 0;             // values
    size_t per = 0;           // numbers per value: 2 (even spacing: re, im) or 3 (x, re, im)
    long long otype = 0;      // 5: complex single, 6: complex double
    double x0 = 0, dx = 0;    // the even abscissa
};

// Records 6 to 10 of the dataset whose id line ("58" or "58b") is line k. Returns false for a
// function type other than 4 (not an FRF: skipped). `room`: bytes the data can take at most (a count
// beyond it is refused before anything is allocated).
bool parse58_header(const Text &t, size_t k, double room, const char *where, Dataset &d, Layout &lay)
{
    d.at = k;
    const size_t r6 = k + 6, r7 = k + 7;
    const long long ftype = int_field(t, r6, 0, 5, "record 6's function type");
    if (ftype != 4) return false;
    const std::string l6 = t.line(r6);
    d.rsp = {trim(field(l6, 31, 10)), int_field(t, r6, 41, 10, "the response node"),
             int_field(t, r6, 51, 4, "the response direction")};
    d.ref = {trim(field(l6, 56, 10)), int_field(t, r6, 66, 10, "the reference node"),
             int_field(t, r6, 76, 4, "the reference direction")};
    // record 7, Format(3I10, 3E13.5): ordinate type, count, spacing, abscissa minimum and increment (by
    // column: full-width fields run together, "         62000000000")
    const std::string l7 = t.line(r7);
    double v[5];
    for (int i = 0; i < 5; ++i) {
        const std::string fld = trim(field(l7, i < 3 ? 10 * (size_t)i : 30 + 13 * (size_t)(i - 3), i < 3 ? 10 : 13));
        const char *s = fld.c_str();
        if (!take_number(s, s + fld.size(), v[i]) || *s)
            throw Error(at_line(t.path, r7 + 1, "record 7 must hold the ordinate type, the number of values, the "
                                                "spacing (3I10), the abscissa minimum and increment (E13.5)"));
    }
    const long long otype = (long long)v[0], spacing = (long long)v[2];
    if (otype != 5 && otype != 6)
        throw Error(at_line(t.path, r7 + 1, "ordinate data type " + std::to_string(otype) +
                                                " (an FRF is complex: 5 or 6, single or double precision)"));
    if (spacing != 0 && spacing != 1)
        throw Error(at_line(t.path, r7 + 1, "abscissa spacing must be 0 (uneven) or 1 (even)"));
    lay.per = spacing ? 2 : 3;
    lay.otype = otype;
    if (!(v[1] >= 1) || v[1] * (double)lay.per > room)
        throw Error(at_line(t.path, r7 + 1, "the number of values (" + std::to_string((long long)v[1]) +
                                                ") is more than " + where + " can hold (a truncated file?)"));
    lay.n = (size_t)v[1];
    lay.x0 = v[3];
    lay.dx = v[4];
    d.x_unit = trim(field(t.line(k + 8), 47, 20));
    d.num_unit = trim(field(t.line(k + 9), 47, 20));
    d.den_unit = trim(field(t.line(k + 10), 47, 20));
    return true;
}

// The values of a dataset from its numbers (lay.per per value), in its abscissa's spacing.
void take_values(Dataset &d, const Layout &lay, const std::vector<double> &num)
{
    for (size_t i = 0; i < lay.n; ++i) {
        if (lay.per == 2) {
            d.x.push_back(lay.x0 + lay.dx * (double)i);
            d.y.emplace_back(num[2 * i], num[2 * i + 1]);
        } else {
            d.x.push_back(num[3 * i]);
            d.y.emplace_back(num[3 * i + 1], num[3 * i + 2]);
        }
    }
}

// Dataset 58 starting at line k ("58"), its lines up to (not including) the closing "-1" at `end`.
// d.at is 0 for a dataset that is not an FRF (skipped).
Dataset parse58(const Text &t, size_t k, size_t end)
{
    Dataset d;
    if (end - k < 13)   // "58", 11 records, at least one data line
        throw Error(at_line(t.path, k + 1, "dataset 58 has " + std::to_string(end - k - 1) +
                                               " lines, fewer than its 11 records and data (a truncated file?)"));
    // the count bounded by what the dataset's lines can hold (each number takes 2 characters at least)
    const size_t bytes = t.lines[end - 1].second - t.lines[k + 12].first;
    Layout lay;
    if (!parse58_header(t, k, ((double)bytes + 2) / 2, "the dataset's data lines", d, lay)) {
        d.at = 0;
        return d;
    }
    const size_t n = lay.n, per = lay.per;
    std::vector<double> num;
    num.reserve(n * per);
    for (size_t q = k + 12; q < end; ++q) {
        const std::string l = t.line(q);
        const char *p = l.c_str(), *pe = p + l.size();
        double x;
        while (take_number(p, pe, x)) num.push_back(x);
        while (p < pe && std::isspace((unsigned char)*p)) ++p;
        if (p != pe) throw Error(at_line(t.path, q + 1, "'" + trim(std::string(p, pe)) + "' is not a number"));
    }
    if (num.size() != n * per)
        throw Error(at_line(t.path, k + 1, "dataset 58 (" + d.rsp.name() + " / " + d.ref.name() + ") announces " +
                                               std::to_string(n) + " values (" + std::to_string(n * per) +
                                               " numbers) but holds " + std::to_string(num.size()) +
                                               " (a truncated or corrupt file?)"));
    take_values(d, lay, num);
    return d;
}

// Dataset 58b at id line k: the same 11 records, then the numbers in binary (IEEE 754, the byte order
// the id line names; 4 bytes each for ordinate type 5, 8 for 6) straight after the records, then the
// closing "-1". The data's size is what record 7 makes of it (some writers' id lines count half the
// bytes of complex data); it must end where the "    -1" line starts (I6, after an optional line end). Returns the offset just past that "-1"
// line (the caller goes on from there); d.at is 0 for a dataset that is not an FRF.
size_t parse58b(const Text &t, size_t k, Dataset &d)
{
    const std::string id = t.line(k);
    auto id_field = [&](size_t a, size_t n, const char *what) -> long long {
        const std::string f = trim(field(id, a, n));
        char *e = nullptr;
        const long long v = f.empty() ? 0 : std::strtoll(f.c_str(), &e, 10);
        if (f.empty() || *e) throw Error(at_line(t.path, k + 1, std::string("58b's ") + what + " must be an integer (got '" + f + "')"));
        return v;
    };
    const long long order = id_field(7, 6, "byte ordering"), fp = id_field(13, 6, "floating-point format"),
                    nascii = id_field(19, 12, "number of ASCII lines"), nbytes = id_field(31, 12, "number of bytes");
    if (order != 1 && order != 2) throw Error(at_line(t.path, k + 1, "58b byte ordering must be 1 (little endian) or 2 (big endian)"));
    if (fp != 2) throw Error(at_line(t.path, k + 1, "58b floating-point format " + std::to_string(fp) + ": msid reads IEEE 754 (2)"));
    if (nascii != 11) throw Error(at_line(t.path, k + 1, "58b must be followed by 11 ASCII records (the id line says " + std::to_string(nascii) + ")"));
    if (k + 12 >= t.lines.size()) throw Error(at_line(t.path, k + 1, "dataset 58b ends inside its 11 records (a truncated file?)"));
    const size_t off = t.lines[k + 12].first;   // the byte after the 11th record's newline
    const double room = (double)(t.s.size() - off);
    Layout lay;
    const bool frf = parse58_header(t, k, room / 4.0, "the file's bytes after the records", d, lay);
    const size_t elem = lay.otype == 5 ? 4 : 8, size = lay.n * lay.per * elem;
    if ((double)size > room)
        throw Error(at_line(t.path, k + 8, "dataset 58b announces " + std::to_string(lay.n) + " values (" + std::to_string(size) +
                                               " bytes), more than the file holds after its records (a truncated file?)"));
    // the closing "-1" right after the data (an optional line end before it)
    size_t p = off + size;
    if (p < t.s.size() && t.s[p] == '\r') ++p;
    if (p < t.s.size() && t.s[p] == '\n') ++p;
    // the format's I6 "    -1", exactly: spaces skipped here would hide data that ends a few bytes off
    const size_t q = p + 4;
    const bool closed = t.s.compare(p, 6, "    -1") == 0 &&
                        (q + 2 == t.s.size() || t.s[q + 2] == '\n' || t.s[q + 2] == '\r' || t.s[q + 2] == ' ');
    if (!closed)
        throw Error(at_line(t.path, k + 1, "dataset 58b: no closing -1 after its " + std::to_string(size) +
                                               " bytes of data (record 7: " + std::to_string(lay.n) + " values; the id "
                                               "line says " + std::to_string(nbytes) + " bytes): a truncated or corrupt file?"));
    const size_t e = t.s.find('\n', q);
    const size_t next = e == std::string::npos ? t.s.size() : e + 1;
    if (!frf) {
        d.at = 0;
        return next;
    }
    const bool swap = (order == 1) != (__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__);
    std::vector<double> num(lay.n * lay.per);
    for (size_t i = 0; i < num.size(); ++i) {
        unsigned char b[8];
        std::memcpy(b, t.s.data() + off + i * elem, elem);
        if (swap) std::reverse(b, b + elem);
        if (elem == 4) {
            float f;
            std::memcpy(&f, b, 4);
            num[i] = f;
        } else {
            std::memcpy(&num[i], b, 8);
        }
        if (!std::isfinite(num[i]))
            throw Error(at_line(t.path, k + 1, "dataset 58b: value " + std::to_string(i / lay.per + 1) + " is not finite"));
    }
    take_values(d, lay, num);
    return next;
}

// The abscissa in rad/s: Hz unless its unit label says rad/s.
double to_rad_s(const std::string &unit)
{
    std::string u;
    for (char c : unit) u += (char)std::tolower((unsigned char)c);
    return u.find("rad") != std::string::npos ? 1.0 : 2 * M_PI;
}

}  // namespace

Imported read_uff58(const std::string &path)
{
    const std::string text = read_text(path);
    Text t{path, text, {}};
    for (size_t a = 0; a <= text.size();) {
        size_t b = text.find('\n', a);
        if (b == std::string::npos) b = text.size();
        size_t e = b;
        if (e > a && text[e - 1] == '\r') --e;
        if (!(b == text.size() && a == b)) t.lines.emplace_back(a, e);
        a = b + 1;
    }
    std::vector<Dataset> sets;
    size_t skipped = 0;
    for (size_t k = 0; k < t.lines.size(); ++k) {
        if (trim(t.line(k)) != "-1") continue;
        if (k + 1 >= t.lines.size()) break;
        const std::string kind = trim(t.line(k + 1));
        const std::string id = kind.substr(0, kind.find_first_of(" \t"));
        if (id == "58b") {   // binary data may hold anything, "-1" lines too: found by its size
            Dataset d;
            const size_t next = parse58b(t, k + 1, d);
            if (d.at) sets.push_back(std::move(d));
            else ++skipped;
            size_t q = k + 1;
            while (q < t.lines.size() && t.lines[q].first < next) ++q;
            k = q - 1;   // the line before the next one to look at
            continue;
        }
        size_t end = k + 2;
        while (end < t.lines.size() && trim(t.line(end)) != "-1") ++end;
        if (end == t.lines.size())
            throw Error(at_line(path, k + 2, "dataset " + id + " has no closing -1 (a truncated file?)"));
        if (id == "58") {
            Dataset d = parse58(t, k + 1, end);
            if (d.at) sets.push_back(std::move(d));
            else ++skipped;
        } else {
            ++skipped;
        }
        k = end;   // the closing -1
    }
    if (sets.empty())
        throw Error("'" + path + "' holds no dataset 58 of function type 4 (FRF)" +
                    (skipped ? " (" + std::to_string(skipped) + " other datasets)" : std::string()));
    // the MIMO grid: references are the inputs, responses the outputs, in order of appearance
    std::vector<Signal> ins, outs;
    for (const Dataset &d : sets) {
        if (std::find(ins.begin(), ins.end(), d.ref) == ins.end()) ins.push_back(d.ref);
        if (std::find(outs.begin(), outs.end(), d.rsp) == outs.end()) outs.push_back(d.rsp);
    }
    if (ins.size() > 16 || outs.size() > 16)
        throw Error("'" + path + "': " + std::to_string(outs.size()) + " responses x " + std::to_string(ins.size()) +
                    " references; msid takes 1..16 of each");
    std::map<std::pair<size_t, size_t>, const Dataset *> at;
    for (const Dataset &d : sets) {
        const size_t i = (size_t)(std::find(outs.begin(), outs.end(), d.rsp) - outs.begin());
        const size_t j = (size_t)(std::find(ins.begin(), ins.end(), d.ref) - ins.begin());
        if (at.count({i, j}))
            throw Error(at_line(path, d.at + 1, "a second FRF of response " + d.rsp.name() + " to reference " +
                                                    d.ref.name() + " (the first at line " +
                                                    std::to_string(at[{i, j}]->at + 1) + ")"));
        at[{i, j}] = &d;
    }
    const Dataset &first = sets.front();
    for (size_t i = 0; i < outs.size(); ++i)
        for (size_t j = 0; j < ins.size(); ++j) {
            if (!at.count({i, j}))
                throw Error("'" + path + "' has no FRF of response " + outs[i].name() + " to reference " +
                            ins[j].name() + ": a MIMO FRF needs every pair");
            const Dataset &d = *at[{i, j}];
            bool same = d.x.size() == first.x.size() && d.x_unit == first.x_unit;
            for (size_t q = 0; same && q < d.x.size(); ++q)
                same = std::abs(d.x[q] - first.x[q]) <= 1e-9 * std::max(std::abs(first.x[q]), 1e-300);
            if (!same)
                throw Error(at_line(path, d.at + 1, "the FRF of " + d.rsp.name() + " / " + d.ref.name() +
                                                        " is on other frequencies than the one at line " +
                                                        std::to_string(first.at + 1) + ": one abscissa for all"));
        }
    Imported im;
    im.path = path;
    im.format = "uff58";
    im.nu = (uint32_t)ins.size();
    im.ny = (uint32_t)outs.size();
    im.ct = true;
    const double scale = to_rad_s(first.x_unit);
    for (size_t q = 0; q < first.x.size(); ++q) {
        im.omega.push_back(first.x[q] * scale);
        MatC G(im.ny, im.nu);
        for (size_t i = 0; i < outs.size(); ++i)
            for (size_t j = 0; j < ins.size(); ++j) G((Eigen::Index)i, (Eigen::Index)j) = at[{i, j}]->y[q];
        im.G.push_back(G);
    }
    for (size_t j = 0; j < ins.size(); ++j) {
        im.input_names.push_back(ins[j].name());
        im.input_units.push_back(at[{0, j}]->den_unit);
    }
    for (size_t i = 0; i < outs.size(); ++i) {
        im.output_names.push_back(outs[i].name());
        im.output_units.push_back(at[{i, 0}]->num_unit);
    }
    im.info["datasets"] = sets.size();
    im.info["other_datasets_skipped"] = skipped;
    im.info["abscissa_unit"] = first.x_unit.empty() ? "Hz (none given)" : first.x_unit;
    return im;
}

}  // namespace msidfrfimport
