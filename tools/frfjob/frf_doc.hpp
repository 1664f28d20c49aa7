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

// The memory a document of `lines` host-estimator lines takes while it is built and written, in
// bytes: about 2 kB per line and 130 bytes per number of its matrices (G, cov, cov_known_input,
// noise: 2 (g + 2 g^2 + ny^2) reals, g = ny nu), with a fifth to spare (measured with msid frf
// --method lpm: 3.4 kB per line for 1 x 1, 8.7 kB for 2 x 2).
double est_document_bytes(size_t lines, unsigned ny, unsigned nu);

// The memory this process may use: the smaller of the machine's physical memory and the
// address-space limit (RLIMIT_AS), in bytes.
double usable_memory_bytes();

// Throws Error when a document of `lines` lines would take more than half of usable_memory_bytes():
// `what` names the estimator and the record ("--method lpm on 2000000 samples"), `cure` how to ask for
// fewer lines. An estimator that gives one line per DFT bin of the whole record (the LPM) is bounded
// here instead of ending with the kernel's out-of-memory kill.
void check_document_memory(size_t lines, unsigned ny, unsigned nu, const std::string &what, const std::string &cure);

}  // namespace msidjob
