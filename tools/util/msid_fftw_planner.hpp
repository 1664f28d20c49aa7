// FFTW's first plan in a process is far dearer than the next ones (the planner registers its
// solvers and hashes the problem). msid frf makes that first plan on a second thread while the
// experiment files are read, instead of after.
#pragma once
#include <cstddef>
#include <cstdint>

#include <fftw3.h>

namespace msidutil {

// Plan (and keep, until the exit) a real-to-complex transform of `period` samples on a thread
// of its own. Nothing else may use FFTW's planner until fftw_planner_ready() returned.
// Starts nothing if a warm-up already ran or no thread is to be had.
void fftw_warmup_start(uint32_t period);

// Wait for the warm-up plan, if one is being made: call before any FFTW planning (plan creation
// or destruction). Safe from any thread, any number of times.
void fftw_planner_ready();

// The process's real DFT plan of length n (1 .. 2^31 - 1): forward (real to complex, n / 2 + 1
// values) or inverse (complex to real, unnormalised), FFTW_ESTIMATE (no timing: the same plan, so
// the same bits, on every run). Made at its first request under a lock of its own, then shared and
// never destroyed: planning costs more than the transforms of a small job, which asks for the same
// lengths again and again. Execute it with fftw_execute_dft_r2c / _c2r (thread-safe) on arrays from
// fftw_alloc_real / fftw_alloc_complex (the alignment it was planned for). nullptr when FFTW could
// not plan (no memory).
fftw_plan shared_real_plan(size_t n, bool inverse);

// The process's forward complex DFT plan of length m (1 .. 2^30), FFTW_ESTIMATE, shared and kept like
// shared_real_plan: a real DFT of 2m samples is that of the m pairs (x[2n], x[2n+1]) split into even
// and odd parts (msid_fft_fftw's MSID_FFTW_LINES). FFTW plans it for a tenth of the instructions of the
// real plan of 2m (about 2 M against 20 M at 2000 or 3000 points), and it is the problem msid's
// warm-up plans for an even period. Execute with fftw_execute_dft on fftw_alloc_complex arrays.
fftw_plan shared_half_plan(size_t m);

}  // namespace msidutil
