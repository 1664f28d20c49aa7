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

// One double in that layout (shortest round-trip digits); `buf` holds >= 32 chars.
// Returns the end of the text. `v` must be finite.
char *format_double(double v, char *buf);

}  // namespace msidfrf
