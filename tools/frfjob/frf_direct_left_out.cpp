// The demo build (MSID_DEMO=ON, cmake/msid_demo.cmake) leaves out the direct time-domain
// estimator and tools/est behind it: asked for, it is one message naming how to get it.
#include "frf_job_detail.hpp"

namespace msidjob {

FrfOutcome run_frf_direct(const FrfRequest &, const Design &, const std::vector<Record> &)
{
    throw msidutil::Error("this msid was built by `./bootstrap.sh demo` without `frf --direct`; build everything "
                          "with `./bootstrap.sh build`",
                          2, msidutil::ErrorKind::usage);
}

}  // namespace msidjob
