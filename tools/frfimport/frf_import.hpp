// FRFs measured by other tools (docs/frf-format.md, "FRFs from other tools"): readers of Touchstone
// (.sNp), UFF/UNV dataset 58, a CSV convention of msid's own and an idfrd-shaped MATLAB .mat, each to
// one neutral Imported value, and that value as an msid-frf/1 document. msid fit, validate, plot and
// import read every format through load_frf(). No command-line types; errors are msidfrfimport::Error.
#pragma once
#include "frf_file.hpp"
#include "msid_host_error.hpp"

#include <string>
#include <vector>

namespace msidfrfimport {

using msidfrf::cd;
using msidfrf::Json;
using msidfrf::MatC;

// One clear message naming the file and, where it helps, the line or record (ErrorKind::data: a
// file's contents; io: a file that cannot be read; usage: a bad --format).
struct Error : msidutil::Error {
    explicit Error(const std::string &m, msidutil::ErrorKind k = msidutil::ErrorKind::data)
        : msidutil::Error(m, k == msidutil::ErrorKind::usage ? 2 : 1, k) {}
};

enum class Format { Msid, Touchstone, Uff, Csv, Mat };

// An FRF as another tool stores it, before it becomes an msid-frf/1 document.
struct Imported {
    std::string path;
    std::string format;              // "touchstone", "uff58", "csv", "mat"
    uint32_t nu = 0, ny = 0;         // 1..16 each
    bool ct = true;                  // a continuous-time FRF (an analogue instrument)
    double sample_time = 0.0;        // s; 0: none (a CT FRF of an analogue instrument)
    std::vector<double> omega;       // rad/s (CT, or DT with a sample time); rad/sample (DT without one)
    std::vector<MatC> G;             // per line, ny x nu
    // per line, g x g (g = ny nu, vec stacks columns) and its complex dof; empty: no uncertainty in the
    // file (the fit is then unweighted and has no p-value)
    std::vector<MatC> cov;
    std::vector<double> dof;
    std::vector<std::string> input_names, output_names, input_units, output_units;
    Json info = Json::object();      // what the format says beyond the FRF (Touchstone: parameter, R)
};

// The format of `path`: `name` when given (msid, touchstone, uff, csv, mat; a bad name is a usage
// error), else from the extension (.json, .sNp, .uff/.unv, .csv, .mat) and, for an unknown one, the
// content (JSON, "-1" dataset delimiters, a Touchstone option line, a MATLAB header).
Format format_of(const std::string &path, const std::string &name = "");

// The readers, one file each (touchstone.cpp, uff58.cpp, frf_csv.cpp, idfrd_mat.cpp).
Imported read_touchstone(const std::string &path);
Imported read_uff58(const std::string &path);
Imported read_frf_csv(const std::string &path);
Imported read_idfrd_mat(const std::string &path);

// Any of them by format (not Msid).
Imported read_imported(const std::string &path, Format f);

// The msid-frf/1 document of an imported FRF: one experiment, period_samples 0 (no DFT bins), the
// lines in increasing frequency with omega and freq_hz (CT), no covariance where the file has none,
// and `imported` {format, source, ...info} saying where it came from. Checks (before writing): the
// sizes, finite values, frequencies strictly increasing and at or below Nyquist (DT).
Json to_document(const Imported &im);

// The document of any FRF file: an msid-frf/1 file as read, any other format imported.
Json load_document(const std::string &path, const std::string &format = "");

// load_document parsed by msidfrf::parse_frf: what msid fit and validate read.
msidfrf::FrfData load_frf(const std::string &path, const std::string &format = "");

// ---- shared by the readers (frf_import.cpp) ----

// The whole file as text (its size is what it holds: no field of it sizes anything before this);
// throws Error (io) when it cannot be read, (data) when it is empty.
std::string read_text(const std::string &path);

// A decimal number at the start of `s` (leading blanks skipped; Fortran's D exponent taken); false
// when there is none. `s` is advanced past it.
bool take_number(const char *&s, const char *end, double &x);

// "'path' line N: what"
std::string at_line(const std::string &path, size_t line, const std::string &what);

}  // namespace msidfrfimport
