// msid-frf/1 text: the JSON text of a document, written directly (tools/frffile).
#pragma once
#include "frf_file.hpp"

namespace msidfrf {

// ---------------- text ----------------

// Thrown by dump() at the first NaN or infinite number (nlohmann would write null);
// the caller names the offending entry (its path in the document).
struct NonFinite : std::runtime_error {
    NonFinite() : std::runtime_error("non-finite number") {}
};

// The text of `doc` exactly as nlohmann's doc.dump(indent) lays it out (objects in
// insertion order, `indent` spaces per level, "key": value, the same string escapes
// and number layout: "1.0", "0.001", "1e-05", "1.5e+20"), but every double printed
// through std::to_chars' shortest round-trip digits, so reading the text back gives
// the same bits, and without the serializer's per-character virtual calls. Appends
// to `out`. Throws NonFinite at a NaN or infinite number. `two_threads`: arrays of 64 elements
// or more (the lines) are written in two halves by two threads, the same bytes.
void dump(const Json &doc, int indent, std::string &out, bool two_threads = false);

// Element i of an array at `level`, as dump() writes it inside the array's brackets: ",\n"
// before every element but the first, the indent, the element's text.
void dump_element(const Json &e, size_t i, int indent, int level, std::string &out);

// A line whose statistics are row-major complex arrays (the C core's layout), for line_element().
// g = ny nu. Null cov_ki: the same as cov (dof_ki ignored); null noise: not written.
struct LineArrays {
    const cd *G = nullptr;        // ny x nu
    const cd *cov = nullptr;      // g x g
    double dof = 0.0;
    const cd *cov_ki = nullptr;   // g x g or null
    double dof_ki = 0.0;
    const cd *noise = nullptr;    // ny x ny or null
    const double *snr = nullptr;  // ny values, dB (non-finite: null)
    size_t ny = 0, nu = 0;
    std::optional<double> cond, input_snr;   // written when set (input_snr non-finite: null)
};

// The text dump_element(line(position(p), s), i, indent, level, out) appends, for the line
// whose statistics `a` holds (LineStats without pcov), written directly: no tree, no Eigen
// copies (msid frf writes 10^2-10^4 lines this way). Throws NonFinite where dump() would.
void line_element(const Position &p, const LineArrays &a, size_t i, int indent, int level, std::string &out);

// One double in that layout (shortest round-trip digits); `buf` holds >= 32 chars.
// Returns the end of the text. `v` must be finite.
char *format_double(double v, char *buf);

}  // namespace msidfrf
