#include "frf_io.hpp"
#include "frf_file.hpp"
#include "frf_text.hpp"
#include "pipeline.hpp"

#include <cmath>

namespace msidcli {

// The first number in `j` that is NaN or infinite (JSON would write it as null), by its path; "" if none.
static std::string nonfinite_at(const Json &j, const std::string &at)
{
    if (j.is_number_float()) return std::isfinite(j.get<double>()) ? "" : (at.empty() ? "/" : at);
    if (j.is_object())
        for (auto it = j.begin(); it != j.end(); ++it) {
            std::string p = nonfinite_at(it.value(), at + "/" + it.key());
            if (!p.empty()) return p;
        }
    if (j.is_array())
        for (size_t i = 0; i < j.size(); ++i) {
            std::string p = nonfinite_at(j[i], at + "/" + std::to_string(i));
            if (!p.empty()) return p;
        }
    return "";
}

void write_json_file(const std::string &path, const Json &doc, bool durable, const msidfrf::Prerendered *pre)
{
    // A result is never written with a silent null for NaN/Inf (it would fail the schema): one message, no file.
    // The text is nlohmann's dump(1) layout with std::to_chars' shortest round-trip numbers (msidfrf::dump).
    std::string s;
    s.reserve(1 << 16);
    size_t at = std::string::npos;   // where pre's parts go (written from their own strings)
    try {
        if (pre) at = msidfrf::dump_around(doc, 1, s, true, *pre);
        else msidfrf::dump(doc, 1, s, true);
    } catch (const msidfrf::NonFinite &) {
        throw Error("'" + path + "' not written: the result is not finite at " + nonfinite_at(doc, "") +
                    " (inputs beyond double precision's range, e.g. data scaled near 1e150 or a sample rate near 0)");
    }
    s += '\n';
    if (at == std::string::npos) {
        write_file_atomic(path, s, durable);
        return;
    }
    std::vector<std::string_view> pieces{std::string_view(s).substr(0, at)};
    for (const std::string &t : pre->parts) pieces.emplace_back(t);
    pieces.push_back(std::string_view(s).substr(at));
    write_file_atomic(path, pieces, durable);
}

Json cplx_json(const std::complex<double> *a, size_t rows, size_t cols) { return msidfrf::cmat(a, rows, cols); }

Json est_line_json(Json pos, unsigned ny, unsigned nu, const std::complex<double> *G,
                   const std::complex<double> *cov, double dof, const std::complex<double> *noise,
                   const std::vector<double> &snr_db)
{
    const size_t g = (size_t)ny * nu;
    msidfrf::LineStats s;
    s.G = msidfrf::from_row_major(G, ny, nu);
    s.cov = msidfrf::from_row_major(cov, g, g);
    s.dof = dof;   // cov_known_input: the same matrix and dof
    s.noise = msidfrf::from_row_major(noise, ny, ny);
    s.snr = snr_db;
    return msidfrf::line(std::move(pos), s);
}

}  // namespace msidcli
