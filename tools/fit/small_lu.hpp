// A small dense LU of the resolvent z I - A (cissim.cpp, cissim_ml.cpp; compiled with msid_fit's -fcx-limited-range).
#pragma once
#include "fit_types.hpp"

#include <utility>
#include <vector>

namespace msidfit {

// LU with partial pivoting of z I - A (n x n complex, row-major in `a`) and its solves: the
// resolvent of a fitted model of a few states, evaluated at hundreds of lines per step, where
// Eigen's dynamic-size LU and triangular solves spend their time in blocking logic and allocation,
// not in the handful of products.
struct SmallLu {
    Eigen::Index n = 0;
    std::vector<cd> a;
    std::vector<Eigen::Index> piv;
    explicit SmallLu(Eigen::Index n_) : n(n_), a((size_t)(n_ * n_)), piv((size_t)n_) {}
    cd &at(Eigen::Index i, Eigen::Index j) { return a[(size_t)(i * n + j)]; }
    // a = L U of P (z I - A), A real or complex
    template <class Mat> void compute(const Mat &A, cd z)
    {
        for (Eigen::Index i = 0; i < n; ++i)
            for (Eigen::Index j = 0; j < n; ++j) at(i, j) = (i == j ? z : cd(0)) - A(i, j);
        for (Eigen::Index k = 0; k < n; ++k) {
            Eigen::Index p = k;
            double best = std::norm(at(k, k));
            for (Eigen::Index i = k + 1; i < n; ++i)
                if (std::norm(at(i, k)) > best) best = std::norm(at(i, k)), p = i;
            piv[(size_t)k] = p;
            if (p != k)
                for (Eigen::Index j = 0; j < n; ++j) std::swap(at(k, j), at(p, j));
            const cd d = at(k, k);
            if (d == cd(0)) continue;   // singular: the solves give inf/nan, refused by the callers
            for (Eigen::Index i = k + 1; i < n; ++i) {
                const cd l = at(i, k) / d;
                at(i, k) = l;
                for (Eigen::Index j = k + 1; j < n; ++j) at(i, j) -= l * at(k, j);
            }
        }
    }
    // X = (z I - A)^-1 R, column by column (R: n x r)
    void solve(const MatC &R, MatC &X)
    {
        X = R;
        for (Eigen::Index c = 0; c < X.cols(); ++c) {
            cd *x = X.col(c).data();
            for (Eigen::Index k = 0; k < n; ++k)
                if (piv[(size_t)k] != k) std::swap(x[k], x[piv[(size_t)k]]);
            for (Eigen::Index i = 1; i < n; ++i)
                for (Eigen::Index j = 0; j < i; ++j) x[i] -= at(i, j) * x[j];
            for (Eigen::Index i = n - 1; i >= 0; --i) {
                for (Eigen::Index j = i + 1; j < n; ++j) x[i] -= at(i, j) * x[j];
                x[i] /= at(i, i);
            }
        }
    }
    // Y = (z I - A)^-T R: U^T L^T P y = r
    void solve_t(const MatC &R, MatC &Y)
    {
        Y = R;
        for (Eigen::Index c = 0; c < Y.cols(); ++c) {
            cd *y = Y.col(c).data();
            for (Eigen::Index i = 0; i < n; ++i) {
                for (Eigen::Index j = 0; j < i; ++j) y[i] -= at(j, i) * y[j];
                y[i] /= at(i, i);
            }
            for (Eigen::Index i = n - 1; i >= 0; --i)
                for (Eigen::Index j = i + 1; j < n; ++j) y[i] -= at(j, i) * y[j];
            for (Eigen::Index k = n - 1; k >= 0; --k)
                if (piv[(size_t)k] != k) std::swap(y[k], y[piv[(size_t)k]]);
        }
    }
};

}  // namespace msidfit
