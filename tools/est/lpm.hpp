// The local polynomial method (LPM) for FRFs from arbitrary records
// (Pintelon, Schoukens, Vandersteen, Barbé, "Estimation of nonparametric noise and
// FRF models for multivariable systems", MSSP 24 (2010), Part I: theory, §3-4).
//
// Around every DFT bin k of the whole record (N samples), G and the transient
// (leakage) term T are local polynomials of degree R in the bin offset r,
//     Y_e(k+r) = (G(k) + sum_s g_s r^s) U_e(k+r) + T_e(k) + sum_s t_{e,s} r^s + V_e(k+r),
// fitted by least squares over the 2W+1 bins k+r of every experiment e (the
// window is shifted, not cut, at the band edges). The residuals give the noise
// covariance C_v with q = m(2W+1) - (R+1)(nu+m) complex degrees of freedom and
// Cov vec(G(k)) = M^T kron C_v, M the G(k) block of the inverse normal matrix.
// With Gaussian noise that is locally white in frequency, q C_v is complex
// Wishart with q dof, independent of G(k): |Ghat_ij - G_ij|^2 / cov_ii ~ F(2, 2q)
// exactly (docs/statistics.md, "Local polynomial method").
#pragma once
#include "spectra.hpp"

namespace msidest {

struct LpmConfig {
    unsigned order = 2;        // R: degree of the local polynomials of G and T (0..8)
    unsigned window = 0;       // W: half-width (2W+1 bins); 0 = lpm_default_window()
    size_t k_lo = 1;           // first bin of the band (>= 1)
    size_t k_hi = 0;           // last bin of the band (0 = the last bin below Nyquist)
    bool transient = true;     // false: no T polynomial (only for negative-control tests)
    unsigned threads = 1;      // bins are split over this many threads (results do not depend on it)
};

struct LpmResult {
    size_t N = 0;
    unsigned nu = 0, ny = 0, m = 0, R = 0, W = 0, q = 0;
    std::vector<size_t> bins;  // k_lo..k_hi
    std::vector<cd> G;         // per bin ny*nu, row-major (G[i][j] maps input j to output i)
    std::vector<cd> cov;       // per bin g*g, g = ny*nu: Cov vec(G), vec stacks columns (index i + ny*j)
    std::vector<cd> noise;     // per bin ny*ny: C_v, covariance of the output noise DFT V(k)
};

// Complex residual degrees of freedom q = m(2W+1) - (R+1)(nu+m) (without T: m(2W+1) - (R+1)nu).
long lpm_dof(unsigned W, unsigned R, unsigned nu, unsigned m, bool transient = true);
// Smallest W with q >= ny + 4 (finite variance of the inverse-Wishart weights used by msid fit).
unsigned lpm_default_window(unsigned R, unsigned nu, unsigned ny, unsigned m);

// Throws EstError for a window that leaves no dof, a record too short for the
// window, a band outside 1..N/2-1, or a singular local input matrix (naming the bin).
LpmResult lpm(const Spectra &s, const LpmConfig &c);

}  // namespace msidest
