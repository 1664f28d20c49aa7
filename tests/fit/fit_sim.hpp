// Test helpers for the fitting library: run the real core (design -> simulated
// plant -> msid_meas -> msid_frf) and hand the result to the fitting code as an
// FrfData, without going through files.
#pragma once
#include "frf_data.hpp"
#include "models.hpp"

extern "C" {
#include "msid_test_sim.h"
}

#include <functional>
#include <vector>

namespace fitsim {

using namespace msidfit;

struct Bench {
    msid_design_cfg design{};          // twiddle filled in
    uint32_t ny = 1, K = 8;
    double sigma_y = 0.1, sigma_u = 0.0;
    // noiseless rows [u; y] of experiment e for n samples from period phase 0
    std::function<void(const tsim_design &, uint32_t e, size_t n, double *rows)> clean;
    bool ct = false;                   // CT design: lines carry omega, FRF at +omega
};

// A DT state-space plant as a `clean` function (steady state by warm-up).
std::function<void(const tsim_design &, uint32_t, size_t, double *)> dt_plant(const SSModel &m);
// A CT state-space plant sampled exactly (steady-state multisine response at t = n h).
std::function<void(const tsim_design &, uint32_t, size_t, double *)> ct_plant(const SSModel &m);

// A lightly damped structure as a bench engineer meets it: modes k with natural
// frequency fn[k] (Hz), damping ratio zeta[k], mode shape phi(:, k) at the ny
// acceleration outputs and psi(:, k) at the nu force inputs. CT state space with
// states (q_k, dq_k/dt): q_k'' = -w_k^2 q_k - 2 zeta_k w_k q_k' + psi_k^T u,
// y = sum_k phi_k q_k'' (accelerance: direct feedthrough D = sum_k phi_k psi_k^T).
SSModel structure(const std::vector<double> &fn, const std::vector<double> &zeta, const MatR &phi, const MatR &psi);

// A CT bench on bins first..first+L-1 of a P-sample period at h = 0.01 s, one input, output SNR in dB
// (rms over rms) of the plant's first output.
struct CtBench {
    std::vector<double> om, amp;
    Bench b;
    CtBench(const SSModel &pl, uint32_t P, uint32_t L, uint32_t K, double snr_db, uint64_t seed, uint32_t first = 1);
};

class Runner {
public:
    explicit Runner(const Bench &b);
    ~Runner();
    // One Monte Carlo run: fresh noise from rng, returns the FRF data (lines in design order).
    FrfData run(msid_rng &rng);
    const tsim_design &design() const { return t_; }

private:
    Bench b_;
    tsim_design t_{};
    std::vector<std::vector<double>> clean_;
    std::vector<double> rows_;
    void *mm_ = nullptr, *fm_ = nullptr;
    size_t nm_ = 0, nf_ = 0;
};

}  // namespace fitsim
