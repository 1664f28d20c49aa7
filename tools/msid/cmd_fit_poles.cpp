// `msid fit --method ml --param poles` (fit_poles.hpp): left out of the demo build with poleres.cpp.
#include "fit_poles.hpp"

namespace msidcli {

msidfit::PrResult fit_ml_poles(const msidfit::FrfData &f, msidfit::Domain d,
                               const std::vector<msidfit::WeightedLine> &w, bool weighted,
                               const msidfit::PrOptions &o)
{
    return msidfit::pr_ml_fit(f, d, w, weighted, o);
}

}  // namespace msidcli
