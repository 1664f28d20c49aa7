// The Eigen decompositions the fitting library shares, instantiated once (eigen_inst_linear.cpp,
// eigen_inst_eigen.cpp) instead of in every file that uses them: Eigen's template instantiation is
// most of the fitting library's build time.
// The extern declarations hold only inside msid_fit (MSID_FIT_EIGEN_EXTERN, tools/fit/CMakeLists.txt):
// its sources share its flags (-fcx-limited-range), so an instance is the code each file made itself.
// A call with an expression argument (not a plain MatrixXd/MatrixXcd) still instantiates locally.
#pragma once
#include <Eigen/Dense>

// LU, QR, SVD: their work is in non-template members, so the class instance covers it
#define MSID_EIGEN_LINEAR(X)                                                                             \
    X(class Eigen::JacobiSVD<Eigen::MatrixXd>)                                                           \
    X(class Eigen::JacobiSVD<Eigen::MatrixXcd>)                                                          \
    X(class Eigen::PartialPivLU<Eigen::MatrixXd>)                                                        \
    X(class Eigen::PartialPivLU<Eigen::MatrixXcd>)                                                       \
    X(class Eigen::FullPivLU<Eigen::MatrixXd>)                                                           \
    X(class Eigen::HouseholderQR<Eigen::MatrixXd>)                                                       \
    X(class Eigen::ColPivHouseholderQR<Eigen::MatrixXd>)

// eigensolvers: compute() is a member template over the input type; instantiated for plain matrices
#define MSID_EIGEN_EIGEN(X)                                                                              \
    X(Eigen::EigenSolver<Eigen::MatrixXd> &Eigen::EigenSolver<Eigen::MatrixXd>::compute<Eigen::MatrixXd>(  \
        const Eigen::EigenBase<Eigen::MatrixXd> &, bool))                                                \
    X(Eigen::ComplexEigenSolver<Eigen::MatrixXcd> &                                                      \
      Eigen::ComplexEigenSolver<Eigen::MatrixXcd>::compute<Eigen::MatrixXcd>(                            \
          const Eigen::EigenBase<Eigen::MatrixXcd> &, bool))                                             \
    X(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> &                                                   \
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>::compute<Eigen::MatrixXd>(                          \
          const Eigen::EigenBase<Eigen::MatrixXd> &, int))

#if defined(MSID_FIT_EIGEN_EXTERN) && !defined(MSID_FIT_EIGEN_INST)
#define MSID_EIGEN_EXTERN(decl) extern template decl;
MSID_EIGEN_LINEAR(MSID_EIGEN_EXTERN)
MSID_EIGEN_EIGEN(MSID_EIGEN_EXTERN)
#undef MSID_EIGEN_EXTERN
#endif
