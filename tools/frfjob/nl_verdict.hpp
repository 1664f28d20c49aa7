// Nonlinear distortion in `msid frf` (one realisation, detection lines); `msid validate` weighs the
// residuals against it (tools/fitjob/validate_frf.cpp). Implemented in frf_bla.cpp.
#pragma once
#include "msid_frf_job.hpp"

namespace msidjob {

// One realisation with --detect-lines: the distortion level from the output at
// the non-excited lines (fast method: the nonlinear contributions at detection
// lines stand for those at neighbouring excited lines). Null without detection lines.
Json detection_distortion(const Json &frf_doc);

}  // namespace msidjob
