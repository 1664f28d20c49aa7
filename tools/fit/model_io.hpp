// msid-model/1: reading and writing model files.
#pragma once
#include "lmfd_fit.hpp"
#include "subspace.hpp"

#include "json_util.hpp"
#include <optional>

namespace msidfit {

Json rmat_json(const MatR &M);
Json cmat_json(const MatC &M);

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

}  // namespace msidfit
