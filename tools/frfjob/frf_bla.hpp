// `msid frf --realisations R`: best linear approximation with the noise and
// nonlinear-distortion variances (robust method), one msid-frf/1 document.
#pragma once
#include "msid_frf_job.hpp"
#include "nl_verdict.hpp"

namespace msidjob {

// The experiments split into R consecutive blocks of equal size, one block per
// realisation (each block a complete design: m >= nu experiments); each block
// goes through run_frf, then the BLA and the variance split (tools/frfstat/bla.hpp). When some
// experiment has one usable period (after --skip-periods): the BLA and its total covariance only
// (dof R - 1; R >= ny nu + 1), no noise part, a note saying so (docs/statistics.md).
FrfOutcome run_frf_realisations(const FrfRequest &rq, const std::vector<Record> &recs, uint32_t R);

}  // namespace msidjob

