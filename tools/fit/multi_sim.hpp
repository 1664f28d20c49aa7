// Simulated data for the multiple-experiment ML (multi.hpp): case M1 of
// shared/reference-cases.md (Markovsky & Pintelon §VII) and an input-output case.
// Used by tests/fit/test_fit_multi.cpp and `msid bench fit --only 5`.
// The clean trajectories are computed here by routes independent of the
// estimator: closed-form damped sinusoids (M1) and a state-space recursion (I/O).
#pragma once
#include "multi.hpp"

extern "C" {
#include "msid/msid_rng.h"
}

namespace msidfit {

// M1: CT autonomous system of order 6, resonances 2 pi {80, 130, 200} rad/s, damping
// ratios {0.15, 0.1, 0.2}, sampled at ts = 1e-3 s.
struct M1Case {
    double fn[3] = {80.0, 130.0, 200.0};
    double zeta[3] = {0.15, 0.1, 0.2};
    double ts = 1e-3;
    int Tmin = 60, Tmax = 120;   // record lengths, uniform: the slowest mode (time constant 13 ms) decays
                                 // to 1% within 61 samples
    // true alpha (DT characteristic coefficients of z_k = exp(s_k ts))
    VecR alpha() const;
    std::vector<cd> poles_ct() const;   // s_k with Im >= 0, k = 0..2
};

// One clean M1 ring-down: y(t) = sum_k exp(sigma_k t ts) (a_k cos(w_k t ts) + b_k sin(w_k t ts)),
// a_k, b_k ~ N(0, 1) (random initial conditions), T samples. x0 (1 x 6) receives the
// pre-initial values y(-1..-6) of the same closed form (the record's initial conditions
// in the parametrisation of multi.hpp).
MatR m1_record(const M1Case &c, msid_rng &r, int T, MatR *x0);

// A clean data set: N records of random length in [Tmin, Tmax]. x0: per record.
struct MultiData {
    std::vector<MultiRecord> clean;
    std::vector<MatR> x0;
};
MultiData m1_data(const M1Case &c, msid_rng &r, int N);

// Noise standard deviation for SNR = rms(clean) / sd (an amplitude ratio; SNR 100 = 40 dB).
double multi_noise_sd(const std::vector<MultiRecord> &clean, double snr);
// clean + N(0, sd^2) on the outputs (inputs exact).
std::vector<MultiRecord> multi_add_noise(const std::vector<MultiRecord> &clean, msid_rng &r, double sd);
// clean + stationary AR noise c(q^-1) v = e on the outputs, var v = sd^2 (300 samples of burn-in per record).
std::vector<MultiRecord> multi_add_ar_noise(const std::vector<MultiRecord> &clean, msid_rng &r, const VecR &c, double sd);

// The input-output case: DT SISO order 4 (poles 0.9 e^{+-0.5j}, 0.8 e^{+-1.4j}), strictly proper
// numerator beta_{1..4}, white-noise input, random initial state, lengths T_i in [Tmin, Tmax].
struct IoCase {
    int Tmin = 40, Tmax = 200;
    VecR alpha() const;
    std::vector<MatR> beta() const;   // d = 1..4, 1 x 1 each
};
MultiData io_data(const IoCase &c, msid_rng &r, int N);

}  // namespace msidfit
