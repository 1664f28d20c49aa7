// msid-frf/1 parts of the host estimators over tools/frffile.
#pragma once
#include "msid_frf_job.hpp"
#include "frf_text.hpp"
#include <complex>

namespace msidjob {

// {"re": [[...]], "im": [[...]]} of a rows x cols complex matrix (row-major).
Json cplx_json(const std::complex<double> *a, size_t rows, size_t cols);

// One msid-frf/1 line of a host estimator (tools/est: lpm, etfe): `pos` holds the
// position fields (line_position()); G is ny x nu, cov (ny nu)^2 and noise ny x ny,
// all row-major. The known-input covariance is the same matrix (the noise is pooled
// over the window / the neighbouring bins, the input is taken as exact), with the
// same dof; snr per output is |Y|^2 / noise of the output DFT (dB, summed over experiments).
Json est_line_json(Json pos, unsigned ny, unsigned nu, const std::complex<double> *G,
                   const std::complex<double> *cov, double dof, const std::complex<double> *noise,
                   const std::vector<double> &snr_db);

}  // namespace msidjob
