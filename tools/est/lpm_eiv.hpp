// The LPM with a known reference: FRFs from records whose input is measured with
// noise or runs in closed loop (Pintelon, Schoukens, Vandersteen, Barbé 2010,
// "Estimation of nonparametric noise and FRF models for multivariable systems",
// MSSP 24, Part I §3-4 and Part II's noisy-input / closed-loop case).
//
// The LPM (lpm.hpp) of z = [y; u] against the nr = nu reference signals r gives
// G_zr = [G_yr; G_ur] with Cov vec(G_zr) = M^T kron C_z, C_z the covariance of the
// stacked noise [n_y; n_u] (correlated in closed loop). Then (docs/statistics.md,
// "Noisy inputs and closed loop", (L7)-(L9))
//     G = G_yr G_ur^-1,
//     Cov vec(G) = J Cov vec(G_zr) J^H,   J = G_ur^-T kron [I_ny, -G],
// the exact first-order (linearised) covariance; it equals M'^T kron C_e with
// M' = G_ur^-H M G_ur^-1 and C_e = [I, -G] C_z [I, -G]^H, the covariance of the
// equivalent output error y - G u, which carries the LPM's q degrees of freedom.
#pragma once
#include "lpm.hpp"

namespace msidest {

struct LpmEivResult {
    LpmResult zr;              // LPM of z = [y; u] (nz = ny + nu outputs) on r (nr = nu inputs)
    unsigned nu = 0, ny = 0;
    std::vector<cd> G;         // per bin ny*nu, row-major
    std::vector<cd> cov;       // per bin g*g, g = ny*nu, column-stacked vec (as LpmResult::cov)
    std::vector<cd> noise;     // per bin ny*ny: C_e = [I, -G] C_z [I, -G]^H
};

// `s` holds the references as its inputs (s.nu = nr) and z = [y_1..y_ny, u_1..u_nu]
// as its outputs (s.ny = ny + nu); nr must equal nu. Throws EstError for nr != nu,
// for the LPM's own errors, and for a singular G_ur (the references do not drive
// the inputs independently at a bin; the bin is named).
LpmEivResult lpm_eiv(const Spectra &s, unsigned ny, const LpmConfig &c);

}  // namespace msidest
