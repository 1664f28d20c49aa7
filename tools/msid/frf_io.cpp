#include "frf_io.hpp"
#include "pipeline.hpp"

#include <cmath>

namespace msidcli {

void write_json_file(const std::string &path, const Json &doc)
{
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
