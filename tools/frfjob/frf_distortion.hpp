// The last step of the FRF job, for a caller that runs FrfJob itself (samples pushed by the caller:
// the Python extension's Measurement) and wants the document estimate_frf() gives.
#pragma once
#include "msid_frf_job.hpp"

namespace msidjob {

// One realisation with detection lines: the nonlinear distortion level beside the noise
// (o.doc["nonlinear_distortion"], and a note when distortion is detected). No-op without
// detection lines.
void add_detection_distortion(FrfOutcome &o);

}  // namespace msidjob
