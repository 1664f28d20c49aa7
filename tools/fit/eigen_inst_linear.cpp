// The one instance of the LU, QR and SVD decompositions of msid_fit (eigen_inst.hpp).
#define MSID_FIT_EIGEN_INST
#include "eigen_inst.hpp"

#define MSID_EIGEN_INST(decl) template decl;
MSID_EIGEN_LINEAR(MSID_EIGEN_INST)
