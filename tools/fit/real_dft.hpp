// Real DFTs of one length through FFTW, for the fits that transform records (cissim's ISP, its
// per-line covariances and residual correlations). Plans are made with FFTW_ESTIMATE (no timing:
// the same plan, so the same bits, on every run), once per length for the process.
#pragma once
#include <complex>
#include <cstddef>
#include <vector>

namespace msidfit {

class RealDft {
public:
    // Buffers for DFTs of length n (>= 1); the plans are made at the first forward()/inverse() of
    // that length in the process, under a lock of their own. Anything else in the process that
    // plans with FFTW must not plan at the same time (the Python extension runs one job at a time).
    explicit RealDft(size_t n);
    ~RealDft();
    RealDft(const RealDft &) = delete;
    RealDft &operator=(const RealDft &) = delete;
    size_t size() const { return n_; }
    // X[k] = sum_{t<n} x[t] e^{-j 2 pi k t / n}, k = 0 .. n/2 (n/2 + 1 values); x holds n values.
    void forward(const double *x, std::complex<double> *X);
    // x[t] = sum_{k<n} X[k] e^{+j 2 pi k t / n} (unnormalised, the Hermitian half X[0 .. n/2] given);
    // x holds n values.
    void inverse(const std::complex<double> *X, double *x);

private:
    void release();
    void forward_half(const double *x, std::complex<double> *X);
    size_t n_;
    double *re_ = nullptr;
    void *cx_ = nullptr;       // fftw_complex[n/2 + 1]
    void *fwd_ = nullptr, *inv_ = nullptr;   // fftw_plan, shared by every object of this length
    void *half_ = nullptr;                   // n even: the complex forward plan of n/2 (shared)
    std::vector<std::complex<double>> tw_;   // its split's twiddles exp(-j 2 pi k / n), k = 0 .. n/2
};

}  // namespace msidfit
