#include "lpm_eiv.hpp"

#include <Eigen/Dense>
#include <cstdio>

namespace msidest {

LpmEivResult lpm_eiv(const Spectra &s, unsigned ny, const LpmConfig &c)
{
    if (ny == 0 || s.ny <= ny) throw EstError("the noisy-input LPM needs outputs and inputs in z = [y; u]");
    const unsigned nu = s.ny - ny, nr = s.nu, nz = s.ny;
    if (nr != nu) {
        char b[200];
        std::snprintf(b, sizeof b, "%u reference signal(s) for %u input(s): the noisy-input LPM needs one reference "
                                   "per input (nr = nu)", nr, nu);
        throw EstError(b);
    }
    using MatC = Eigen::Matrix<cd, Eigen::Dynamic, Eigen::Dynamic>;
    using RowC = Eigen::Matrix<cd, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    LpmEivResult r;
    r.zr = lpm(s, c);
    r.nu = nu;
    r.ny = ny;
    const size_t nb = r.zr.bins.size(), g = (size_t)ny * nu, gz = (size_t)nz * nr;
    r.G.resize(nb * g);
    r.cov.resize(nb * g * g);
    r.noise.resize(nb * ny * ny);
    for (size_t l = 0; l < nb; ++l) {
        const Eigen::Map<const RowC> Gzr(&r.zr.G[l * gz], nz, nr);
        const Eigen::Map<const RowC> Cz(&r.zr.noise[l * nz * nz], nz, nz);
        const Eigen::Map<const RowC> Czr(&r.zr.cov[l * gz * gz], gz, gz);
        const MatC Gur = Gzr.bottomRows(nu);
        Eigen::JacobiSVD<MatC> svd(Gur);
        const auto &sv = svd.singularValues();
        if (!(sv(nu - 1) > 1e-10 * sv(0))) {
            char b[300];
            std::snprintf(b, sizeof b,
                          "G_ur is singular at bin %zu (%.6g cycles/sample): the reference signals do not drive the "
                          "inputs independently there; restrict --band or check the --reference columns",
                          r.zr.bins[l], (double)r.zr.bins[l] / s.N);
            throw EstError(b);
        }
        const MatC Gi = Gur.inverse();
        const MatC G = Gzr.topRows(ny) * Gi;                                    // (L7)
        MatC P(ny, nz);                                                          // [I, -G]
        P << MatC::Identity(ny, ny), -G;
        const MatC Ce = P * Cz * P.adjoint();                                    // (L9)
        // J = Gi^T kron P (ny*nu x nz*nr): vec(P dGzr Gi) = (Gi^T kron P) vec(dGzr)
        MatC J(g, gz);
        for (unsigned a = 0; a < nu; ++a)
            for (unsigned b = 0; b < nr; ++b) J.block(a * ny, b * nz, ny, nz) = Gi(b, a) * P;
        const MatC C = J * Czr * J.adjoint();                                    // (L8)
        Eigen::Map<RowC>(&r.G[l * g], ny, nu) = G;
        Eigen::Map<RowC>(&r.cov[l * g * g], g, g) = 0.5 * (C + C.adjoint());
        Eigen::Map<RowC>(&r.noise[l * ny * ny], ny, ny) = 0.5 * (Ce + Ce.adjoint());
    }
    return r;
}

}  // namespace msidest
