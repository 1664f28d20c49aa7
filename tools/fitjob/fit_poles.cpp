// ml in the pole-residue form (poleres.cpp), behind one call so that the demo build, which never
// runs it, leaves poleres.cpp out (fit_left_out.cpp).
#include "fit_job_detail.hpp"

namespace msidfitjob {

PrResult fit_ml_poles(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted, const PrOptions &o)
{
    return pr_ml_fit(f, d, w, weighted, o);
}

}  // namespace msidfitjob
