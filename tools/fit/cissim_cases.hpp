// Reference cases of discrete-cISSIM (docs/benchmarks.md, /work/shared/reference-cases.md Y1, Y2)
// shared by tests/fit/test_cissim.cpp and `msid bench fit --only 5`, and the peer FRF through the
// real core (msid_meas + msid_frf) so `subspace` and `ml` see the same samples as cissim.
#pragma once
#include "cissim.hpp"
#include "frf_data.hpp"

extern "C" {
#include "msid/msid_rng.h"
}

namespace msidfit {

// One simulated periodic record, rows [u.., y..] row-major.
struct CissimRecord {
    std::vector<double> rows;
    size_t n_rows = 0;
    uint32_t nu = 1, ny = 1, period = 0;
};

// Y1 (You et al. 6.2): a random stable 4th-order SISO system with two pole pairs of radius
// [rmin, rmax] at angles in [0.05 pi, 0.35 pi] (inside the chirp band), B, C ~ N(0, 1), D ~ N(0, 1/4).
SSModel y1_system(msid_rng &r, double rmin = 0.6, double rmax = 0.95);
// The record of K periods of the periodic input u (T x nu, row-major) through m from zero state (the
// first period carries the transient), white output noise at snr_db of the output power.
CissimRecord periodic_record(const SSModel &m, const std::vector<double> &u, uint32_t T, uint32_t K, double snr_db,
                             msid_rng &r);
// Periodic chirp 0 -> 0.4 pi rad/sample over T samples, K periods (from zero state, so the first
// period carries the transient), white output noise at snr_db of the output power.
CissimRecord y1_record(const SSModel &m, uint32_t T, uint32_t K, double snr_db, msid_rng &r);
// The reduced set of Y1: q bins spread uniformly over the chirp band (1 .. 0.2 T).
std::vector<uint32_t> y1_reduced_bins(uint32_t T, uint32_t q);

// Y2 (You et al. 6.3): A = diag(0.8, 0.2), B = [1; 1], C = [1 0; 1 1], D = 0,
// Sigma = diag(2.30, 0.16 | 2.30, 3.64 | 0.11) 1e-3 (w | v | tau), random periodic input (unit variance).
SSModel y2_system();
void y2_sigmas(MatR &Sww, MatR &Svv, MatR &Stt);
CissimRecord y2_record(uint32_t T, uint32_t K, msid_rng &r);

// The whole-process cases (`msid bench fit --cissim-process`, docs/benchmarks.md): one
// record each, fitted at `order` on `lines` by `msid fit --method cissim` and by the authors' code.
//   "2x2": a 2x2 4th-order plant (pole pairs 0.9 at 0.2 pi, 0.8 at 0.6 pi, D = 0), P = 2000, 30 periods
//          (60,000 samples), both inputs random-phase multisines on the 300 lines 3:3:900, 30 dB;
//   "sparse": the first lightly damped system of the sparse-lines comparison (seed 4242, radii
//          0.97-0.995), T = 3000, 24 periods (72,000 samples), 50 lines, 20 dB.
struct CissimProcessCase {
    const char *name = "";
    SSModel truth;
    CissimRecord rec;
    std::vector<uint32_t> lines;
    int order = 4;
};
std::vector<CissimProcessCase> cissim_process_cases();

// Relative covariance errors of You et al. Table 2: eta_w after the similarity compensation
// (diagonalise A-hat, order the modes like the truth, scale each state so that C-hat matches C),
// eta_v, eta_tau, and eta_r = sum_{j=0..r} ||Xi_rr^j(model) - Xi_rr^j(true)||_F / ||Xi_rr^j(true)||_F.
struct CovErrors {
    double w = 0, v = 0, tau = 0, r = 0;
};
CovErrors y2_errors(const SSModel &est, const NoiseCov &nc, int r = 10);
// One Y2 estimate: a record of K + 1 periods (the first skipped), order 2 on the full set,
// M = clamp(round(N^(1/3)), 5, 50) lags; `seconds` gets the estimation time (ISP to covariances).
CovErrors y2_run(uint32_t T, uint32_t K, uint64_t seed, double *seconds = nullptr);
// Xi_rr^j implied by (A, C, Sigma_ww, Sigma_vv) through (23)-(24).
std::vector<MatR> model_correlations(const SSModel &m, const MatR &Sww, const MatR &Svv, int lags);

// The nonparametric periodic FRF of one experiment through the real core (msid_meas stream path,
// msid_frf), at `bins`, skipping `skip` periods: what `msid frf` computes from the same samples.
// Needs nu = 1 (one experiment).
FrfData core_frf(const CissimRecord &rec, const std::vector<uint32_t> &bins, uint32_t skip);

}  // namespace msidfit
