// Nonlinear distortion in `msid frf` (one realisation, detection lines) and
// `msid validate` (noise level vs distortion level). Implemented in frf_bla.cpp.
#pragma once
#include "model_io.hpp"
#include "msid_frf_job.hpp"

namespace msidjob {

// One realisation with --detect-lines: the distortion level from the output at
// the non-excited lines (fast method: the nonlinear contributions at detection
// lines stand for those at neighbouring excited lines). Null without detection lines.
Json detection_distortion(const Json &frf_doc);

// `msid validate` on an FRF that carries nonlinear-distortion information:
// prints whether the residuals are at the noise level, at the distortion level,
// or above both, and returns that finding (null when the FRF has none).
Json distortion_verdict(const std::string &frf_path, const msidfit::ModelFile &mf, const std::string &weight,
                        double p_total);

}  // namespace msidjob
