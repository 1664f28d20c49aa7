// Inside msid_fitjob: the steps the entry points share.
#pragma once
#include "msid_fit_job.hpp"
#include "msid_host_util.hpp"

#include "frf_data.hpp"
#include "model_io.hpp"
#include "poleres.hpp"

namespace msidfitjob {

using namespace msidfit;
using msidutil::UsageError;
using msidutil::fmt;

// The most states (and LMFD degrees, iterations' counts) a request may ask for: matrices of that order
// squared are beyond any machine's memory well before, and larger counts would wrap as int.
constexpr uint32_t MAX_STATES = 65535;

// Pass a note to the caller now and keep it in the outcome.
void add_note(FitOutcome &out, const Report &report, const std::string &note);

// One fit at one order (fit_frf.cpp); the scan (fit_scan.cpp) calls it at every order.
FitOutcome fit_frf_at_order(const FrfData &f, const FitRequest &rq, const Report &report);
// The order scan of subspace and ml (fit_scan.cpp).
FitOutcome fit_frf_scan(const FrfData &f, const FitRequest &rq, const Report &report);

// ml in the pole-residue form (pr_ml_fit of poleres.cpp; the demo build leaves it out:
// fit_left_out.cpp answers with one message).
PrResult fit_ml_poles(const FrfData &f, Domain d, const std::vector<WeightedLine> &w, bool weighted,
                      const PrOptions &o);

// The model of a --method multi file: poles, numerator, noise AR, noise variance and its dof
// (multi_model.cpp). Throws Error naming `path` for another model or a malformed multi section.
struct MultiModelDoc {
    VecR alpha, noise;
    std::vector<MatR> beta;
    int d0 = 1, nu = 0, ny = 0;
    double s2 = 0, dof = 0, h = 0;
    std::vector<std::string> sources;
};
MultiModelDoc multi_model_doc(const Json &j, const std::string &path);

// msid modes of a multi model (modes_multi.cpp; the demo build: fit_left_out.cpp).
ModesOutcome modes_of_multi(const Json &model_doc, const std::string &path);

}  // namespace msidfitjob
