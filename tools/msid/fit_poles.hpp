// `msid fit --method ml --param poles` (the pole-residue ML of poleres.cpp), behind one call so that the
// demo build (MSID_DEMO, cmake/msid_demo.cmake), which never runs it, leaves poleres.cpp out:
// cmd_fit_poles.cpp in the full build, left_out.cpp's one message in the demo build.
#pragma once
#include "poleres.hpp"

namespace msidcli {

// pr_ml_fit(f, d, w, weighted, o) (poleres.hpp): the weighted ML in pole-residue form from the
// vector-fitting and subspace starts. Throws msidfit::FitError as pr_ml_fit does.
msidfit::PrResult fit_ml_poles(const msidfit::FrfData &f, msidfit::Domain d,
                               const std::vector<msidfit::WeightedLine> &w, bool weighted,
                               const msidfit::PrOptions &o);

}  // namespace msidcli
