// msid-model/1 (docs/model-format.md): the one reader (read_model, model_io.cpp) and the one
// writer (the blocks below, model_write.cpp) of model files. Every fitting method builds its
// document from these blocks, in the order the format lists them: head, state space, stability,
// parameters, the method's own sections, cost, model FRF at the lines, modes.
#pragma once
#include "lmfd_fit.hpp"
#include "subspace.hpp"

#include "json_util.hpp"
#include <optional>

namespace msidfit {

// ---------------- writing ----------------

// A real matrix as rows of numbers; a complex one as {"re": rows, "im": rows}.
Json rmat_json(const MatR &M);
Json cmat_json(const MatC &M);

// The head of every model: format, generator, source (a path, or an array of paths), experiments
// (when given: the record files of a time-domain fit), domain, sample_time (when h > 0), method.
Json model_head(const Json &source, Domain d, double h, const std::string &method, const Json &experiments = Json());

// The state-space model: order, n_inputs, n_outputs, settings, A, B, C, D, stable.
void model_put_ss(Json &doc, const SSModel &ss, int order, size_t nu, size_t ny, const Json &settings);
// The signals' names and units of the data the model was fitted to (msid-frf/1's keys of the same
// names), each written only when not empty.
void model_put_signals(Json &doc, const std::vector<std::string> &input_names,
                       const std::vector<std::string> &output_names, const std::vector<std::string> &input_units,
                       const std::vector<std::string> &output_units);

// "stability": stable, enforced (a constraint of the fit kept it stable), and the largest real part
// (CT) or modulus (DT) of `poles`, the eigenvalues of A as the method computes them (null for no states).
Json model_stability(const SSModel &ss, bool enforced, const VecC &poles);

// "parameters": names, values, cov, cov_factor (when given: the sample-ML factor already in cov),
// cov_rank.
Json model_params(const std::vector<std::string> &names, const VecR &theta, const MatR &cov, int rank,
                  const double *cov_factor = nullptr);

// "lmfd": D(p)^-1 N(p) with p = s (CT) or z^-1 (DT): nD, nN, variable, D, N.
Json model_lmfd(const LmfdModel &m);

// "cost": the weighted cost V, its expectation and p-value under the law of `dof` real equations
// weighted by covariances of `nmin` dof (1e300: known weights) for `ny` outputs.
Json model_cost(double V, double dof, double nmin, double ny);

// One element of "frf": the model at a line (bin, freq, omega), with its covariance or null.
Json model_frf_line(uint32_t bin, double freq, double omega, const MatC &G, const MatC *cov);

// "modes": the modal parameters of the document's model (an {"error": ...} object when it has
// none); the table msid prints of them to *text when asked.
void model_put_modes(Json &doc, std::string *text = nullptr);

// ---------------- reading ----------------

struct ModelFile {
    std::string path;
    Domain domain = Domain::DT;
    double h = 0.0;
    SSModel ss;
    std::optional<LmfdModel> lmfd;
    std::string method;
    std::string weight;       // "cov", "known-input", "none"
    int n_params = 0;         // free parameters behind the fit (for validation dof)
    // pole_residue.poles of an ml --param poles model (pairs by their Im > 0 member); empty otherwise
    std::vector<cd> poles;
};

ModelFile read_model(const std::string &path);
// The same on a document already in memory; `name` stands for the file in messages and ModelFile::path.
ModelFile parse_model(const Json &doc, const std::string &name);

}  // namespace msidfit
