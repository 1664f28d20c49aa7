// Real DFTs through FFTW (real_dft.hpp). One pair of plans per length for the whole process
// (msidutil::shared_real_plan): planning costs more than the transforms of a cissim fit, which asks
// for the same lengths many times (each experiment's period, the correlations' padded length). The
// plans are executed on each object's own buffers (fftw_execute_dft_*: thread-safe, aligned alike).
#include "real_dft.hpp"
#include "fit_types.hpp"

#include <cstring>
#include <fftw3.h>

#include "msid_fftw_planner.hpp"

namespace msidfit {

namespace {

fftw_plan plan_of(size_t n, bool inverse)
{
    const fftw_plan p = msidutil::shared_real_plan(n, inverse);
    if (!p) throw FitError("FFTW could not plan a DFT of length " + std::to_string(n));
    return p;
}

}  // namespace

RealDft::RealDft(size_t n) : n_(n)
{
    if (n < 1 || n > (size_t)0x7FFFFFFF) throw FitError("a DFT length must be 1 .. 2^31 - 1");
    re_ = fftw_alloc_real(n);
    cx_ = fftw_alloc_complex(n / 2 + 1);
    if (!re_ || !cx_) {
        release();
        throw FitError("no memory for a DFT of length " + std::to_string(n));
    }
}

RealDft::~RealDft() { release(); }

void RealDft::release()
{
    fftw_free(re_);
    fftw_free(cx_);
    re_ = nullptr;
    cx_ = nullptr;
}

void RealDft::forward(const double *x, std::complex<double> *X)
{
    if (!fwd_) fwd_ = plan_of(n_, false);
    std::memcpy(re_, x, n_ * sizeof(double));
    fftw_execute_dft_r2c((fftw_plan)fwd_, re_, (fftw_complex *)cx_);
    std::memcpy((void *)X, cx_, (n_ / 2 + 1) * sizeof(fftw_complex));
}

void RealDft::inverse(const std::complex<double> *X, double *x)
{
    if (!inv_) inv_ = plan_of(n_, true);
    // c2r overwrites its input: the object's own buffer takes the copy
    std::memcpy(cx_, (const void *)X, (n_ / 2 + 1) * sizeof(fftw_complex));
    fftw_execute_dft_c2r((fftw_plan)inv_, (fftw_complex *)cx_, re_);
    std::memcpy(x, re_, n_ * sizeof(double));
}

}  // namespace msidfit
