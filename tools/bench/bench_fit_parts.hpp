// The parts of `msid bench fit` that write into its report (bench_fit.cpp runs them in turn).
#pragma once
#include <cstdint>
#include <string>

#include "bench_util.hpp"

namespace msidbench {

// The simulated structures against scikit-rf vector fitting, and the Monte Carlo over `runs` noise
// seeds; the peer writes its files into `dir` (bench_structures.cpp).
void fit_structures(Writer &w, const std::string &dir, double min_s, uint32_t runs);
// The multiple-experiment ML on case M1 (bench_multi.cpp).
void fit_multi(Writer &w, const MultiBenchRequest &rq);
// Discrete-cISSIM beside subspace and ml (bench_cissim.cpp).
void fit_cissim(Writer &w, const CissimBenchRequest &rq);

}  // namespace msidbench
