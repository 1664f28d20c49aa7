// FFTW's first plan in a process is far dearer than the next ones (the planner registers its
// solvers and hashes the problem). msid frf makes that first plan on a second thread while the
// experiment files are read, instead of after.
#pragma once
#include <cstdint>

namespace msidutil {

// Plan (and keep, until the exit) a real-to-complex transform of `period` samples on a thread
// of its own. Nothing else may use FFTW's planner until fftw_planner_ready() returned.
// Starts nothing if a warm-up already ran or no thread is to be had.
void fftw_warmup_start(uint32_t period);

// Wait for the warm-up plan, if one is being made: call before any FFTW planning (plan creation
// or destruction). Safe from any thread, any number of times.
void fftw_planner_ready();

}  // namespace msidutil
