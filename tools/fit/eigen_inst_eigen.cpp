// The one instance of the eigensolvers of msid_fit (eigen_inst.hpp).
#define MSID_FIT_EIGEN_INST
#include "eigen_inst.hpp"

#define MSID_EIGEN_INST(decl) template decl;
MSID_EIGEN_EIGEN(MSID_EIGEN_INST)
