// The demo build (MSID_DEMO=ON, cmake/msid_demo.cmake) leaves out the pole-residue ML (poleres.cpp):
// asked for, it is one message naming how to get it.
#include "fit_job_detail.hpp"

namespace msidfitjob {

PrResult fit_ml_poles(const FrfData &, Domain, const std::vector<WeightedLine> &, bool, const PrOptions &)
{
    throw msidutil::Error("this msid was built by `./bootstrap.sh demo` without `fit --method ml --param poles`; "
                          "build everything with `./bootstrap.sh build`",
                          2, msidutil::ErrorKind::usage);
}

}  // namespace msidfitjob
