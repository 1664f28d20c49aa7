// The plant of a closed loop through its reference (the closed-loop preset of a CiA 402 drive, docs/devices.md):
// the periodic FRF from the one reference r to every measured signal z = [z_0 .. z_{n-1}] gives G_zr with the
// covariance of vec(G_zr) from the period spread; the plant from z_u (the torque demand) to the others is
//     G = G_yr G_ur^-1,   Cov vec(G) = J Cov vec(G_zr) J^H,   J = G_ur^-T (x) [I, -G]
// (docs/statistics.md (L7)-(L8), there for the LPM; on period means the same first-order formula, and with
// m = nu = 1 the same estimate as Ybar Ubar^-1). The per-line noise covariance becomes that of the equivalent
// output error y - G u: C_e = [I, -G] C_z [I, -G]^H (L9), with the same degrees of freedom.
#include "msid_mapped.hpp"

#include "frf_file.hpp"

#include <cmath>

namespace msidacq {

namespace {

using msidfrf::MatC;
using msidfrf::cd;

MatC jmat(const Json &v)
{
    const Json &re = v.at("re");
    return msidfrf::parse_cmat(v, re.size(), re.empty() ? 0 : re[0].size(), "reference FRF", "matrix");
}

// The n-1 signals other than u, in order.
std::vector<uint32_t> others(uint32_t n, uint32_t u)
{
    std::vector<uint32_t> o;
    for (uint32_t i = 0; i < n; ++i)
        if (i != u) o.push_back(i);
    return o;
}

Json pick(const Json &a, const std::vector<uint32_t> &idx)
{
    Json r = Json::array();
    for (uint32_t i : idx) r.push_back(a.at(i));
    return r;
}

}  // namespace

Json plant_through_reference(const Json &ref, uint32_t u)
{
    const uint32_t n = ref.at("n_outputs").get<uint32_t>();
    if (ref.at("n_inputs").get<uint32_t>() != 1 || u >= n || n < 2)
        throw Error("the plant through the reference needs one reference and its input among two or more signals");
    const std::vector<uint32_t> y = others(n, u);
    const Eigen::Index ny = (Eigen::Index)y.size();
    Json doc = ref;
    doc["n_outputs"] = ny;
    for (const char *k : {"input_names", "input_units"}) {
        const char *from = k[6] == 'n' ? "output_names" : "output_units";
        if (ref.contains(from)) doc[k] = Json::array({ref[from].at(u)});
    }
    for (const char *k : {"output_names", "output_units"})
        if (ref.contains(k)) doc[k] = pick(ref[k], y);
    if (ref.contains("noise_cov")) {
        const MatC N = jmat(ref["noise_cov"]);
        MatC Ny(ny, ny);
        for (Eigen::Index a = 0; a < ny; ++a)
            for (Eigen::Index b = 0; b < ny; ++b) Ny(a, b) = N(y[(size_t)a], y[(size_t)b]);
        doc["noise_cov"] = msidfrf::cmat(Ny);
    }
    doc.erase("detection_lines");       // spectra of the reference's FRF outputs, not of the plant's
    doc.erase("nonlinear_distortion");
    Json lines = Json::array();
    for (const Json &e : ref.at("lines")) {
        const MatC g = jmat(e.at("G"));   // n x 1
        const cd gu = g(u, 0);
        if (!(std::abs(gu) > 0))
            throw Error(msidutil::fmt("bin %u: the reference does not move the plant's input (G_ur = 0)",
                                        e.at("bin").get<unsigned>()));
        MatC G(ny, 1), K = MatC::Zero(ny, n);   // K = [I, -G] in z's order
        for (Eigen::Index a = 0; a < ny; ++a) {
            G(a, 0) = g(y[(size_t)a], 0) / gu;
            K(a, y[(size_t)a]) = 1.0;
            K(a, u) = -G(a, 0);
        }
        const MatC J = K / gu;
        Json o = e;
        const MatC C = jmat(e.at("cov"));
        // a G_ur this close to 0 overflows the plant or its covariance: refused here, where the line is known,
        // instead of a file whose numbers are null
        const auto finite = [&](const MatC &M) {
            if (!M.allFinite())
                throw Error(msidutil::fmt("bin %u: the reference barely moves the plant's input (|G_ur| = %.3g): "
                                          "G = G_yr / G_ur or its covariance is not a finite number",
                                          e.at("bin").get<unsigned>(), std::abs(gu)));
            return msidfrf::cmat(M);
        };
        o["G"] = finite(G);
        o["cov"] = finite(MatC(J * C * J.adjoint()));
        if (e.contains("cov_known_input")) o["cov_known_input"] = finite(MatC(J * jmat(e["cov_known_input"]) * J.adjoint()));
        if (e.contains("noise_cov")) o["noise_cov"] = finite(MatC(K * jmat(e["noise_cov"]) * K.adjoint()));
        if (e.contains("snr") && e["snr"].is_array()) o["snr"] = pick(e["snr"], y);
        o["cond"] = 1.0;
        // the plant's input: its period mean against that mean's noise, |G_ur|^2 / var(G_ur) (the reference cancels)
        const double vu = C(u, u).real();
        o["input_snr"] = vu > 0 ? msidfrf::finite_or_null(10.0 * std::log10(std::norm(gu) / vu)) : Json(nullptr);
        lines.push_back(std::move(o));
    }
    doc["lines"] = std::move(lines);
    doc["reference"] = {{"estimator", "G = G_yr G_ur^-1 on the period means, its covariance linearised "
                                      "(docs/statistics.md (L7)-(L9))"},
                        {"signal", ref.contains("input_names") ? ref["input_names"].at(0) : Json("u1")},
                        {"input", ref.contains("output_names") ? ref["output_names"].at(u) : Json("y" + std::to_string(u + 1))}};
    return doc;
}

}  // namespace msidacq
