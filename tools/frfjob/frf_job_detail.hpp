// What the FRF job's sources share inside msid_frfjob (not installed).
#pragma once
#include "msid_frf_job.hpp"
#include "msid_fftw_planner.hpp"
#include "msid_host_util.hpp"

namespace msidjob {

using msidutil::check;
using msidutil::fmt;
using msidutil::Mem;
using msidutil::fftw_planner_ready;
using msidutil::fftw_warmup_start;

}  // namespace msidjob
