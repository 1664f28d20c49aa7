#include "frf_io.hpp"
#include "pipeline.hpp"

#include <cmath>

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

void write_json_file(const std::string &path, const Json &doc)
{
    // A result is never written with a silent null for NaN/Inf (it would fail the schema): one message, no file.
    const std::string bad = nonfinite_at(doc, "");
    if (!bad.empty())
        throw Error("'" + path + "' not written: the result is not finite at " + bad +
                    " (inputs beyond double precision's range, e.g. data scaled near 1e150 or a sample rate near 0)");
    std::string s = doc.dump(1);
    s += '\n';
    write_file_atomic(path, s);
}

Json cplx_json(const std::complex<double> *a, size_t rows, size_t cols)
{
    static_assert(sizeof(std::complex<double>) == sizeof(msid_cplx), "msid_cplx is {re, im}");
    return cmat_json(reinterpret_cast<const msid_cplx *>(a), rows, cols);
}

Json est_line_json(Json pos, unsigned ny, unsigned nu, const std::complex<double> *G,
                   const std::complex<double> *cov, double dof, const std::complex<double> *noise,
                   const std::vector<double> &snr_db)
{
    const size_t g = (size_t)ny * nu;
    pos["G"] = cplx_json(G, ny, nu);
    pos["cov"] = cplx_json(cov, g, g);
    pos["dof"] = dof;
    pos["cov_known_input"] = pos["cov"];
    pos["dof_known_input"] = dof;
    pos["noise_cov"] = cplx_json(noise, ny, ny);
    Json snr = Json::array();
    for (double s : snr_db)
        if (std::isfinite(s)) snr.push_back(s); else snr.push_back(nullptr);
    pos["snr"] = snr;
    return pos;
}

}  // namespace msidcli
