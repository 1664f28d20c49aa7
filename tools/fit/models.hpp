// Parametric models: state space and left matrix fraction (LMFD), their
// frequency responses and conversions.
#pragma once
#include "fit_types.hpp"

namespace msidfit {

// x(k+1) = A x + B u, y = C x + D u (DT), or dx/dt = A x + B u (CT).
struct SSModel {
    Domain domain = Domain::DT;
    double h = 0.0;    // sample time (0: unknown, DT in rad/sample)
    MatR A, B, C, D;
    size_t n() const { return (size_t)A.rows(); }
};

// G(x) = C (x I - A)^{-1} B + D, x = z (DT) or s (CT).
MatC ss_eval(const SSModel &m, cd x);

// LMFD (González et al. 2025 eq. 48-49): G = D(p)^{-1} N(p),
// D(p) = I + sum_{i=1}^{nD} D_i p^i, N(p) = sum_{j=0}^{nN} N_j p^j,
// with p = s (CT) or p = z^{-1} (DT).
struct LmfdModel {
    Domain domain = Domain::DT;
    double h = 0.0;
    int nD = 0, nN = 0;
    std::vector<MatR> Dm;   // D_1..D_nD (ny x ny)
    std::vector<MatR> Nm;   // N_0..N_nN (ny x nu)
    size_t ny() const { return Nm.empty() ? 0 : (size_t)Nm[0].rows(); }
    size_t nu() const { return Nm.empty() ? 0 : (size_t)Nm[0].cols(); }
};

// Polynomial variable of a frequency point: p = s (CT), p = 1/z (DT).
cd lmfd_var(Domain d, cd x);
MatC lmfd_eval(const LmfdModel &m, cd x);

// Observer-form realisation of an LMFD (needs nN <= nD; CT also needs D_nD
// invertible). Throws FitError otherwise.
SSModel lmfd_to_ss(const LmfdModel &m);

// The DT LMFD of degree nD (nN = nD, p = z^-1) with the same FRF as a state-space model of order
// nD ny: [D_nD .. D_1] O = -C A^nD with O = [C; C A; ..; C A^(nD-1)], N_j = sum_{i<=j} D_i h_(j-i) (h the
// Markov parameters). False when the order differs or O is singular (observability indices not all nD).
bool ss_to_lmfd_dt(const SSModel &m, int nD, LmfdModel &out);

// Stable? DT: all |eig(A)| < 1; CT: all Re eig(A) < 0.
bool ss_stable(const SSModel &m);

// Eigenvalues of A after diagonal balancing by powers of 2 (Parlett & Reinsch 1969, the scaling of
// LAPACK's gebal: exact in floating point, the same eigenvalues). The companion realisation of a CT
// LMFD has a condition number near 1e20 (2x2, nD = 12): unbalanced, Eigen put a pole at +0.80 where
// LAPACK and the balanced matrix give -0.18, and the model was labelled UNSTABLE.
VecC ss_eigenvalues(const MatR &A);
// Reflect unstable poles into the stable region, keeping A's eigenvectors
// (A = V diag(lambda) V^-1, real realisation rebuilt). Returns how many were reflected.
int ss_reflect_unstable(SSModel &m);

// Relative H2 and Hinf distance ||a - b|| / ||b|| (b is the reference). H2 by
// Gramians (stable models; CT needs D_a = D_b), Hinf by a dense frequency grid
// with local refinement. Throws FitError if a model is unstable.
struct Distance {
    double h2 = 0.0, hinf = 0.0;
    double h2_ref = 0.0, hinf_ref = 0.0;
};
Distance ss_distance(const SSModel &a, const SSModel &b);

}  // namespace msidfit
