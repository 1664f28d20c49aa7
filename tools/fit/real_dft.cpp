// Real DFTs through FFTW (real_dft.hpp). One plan per length and direction for the whole process
// (msidutil::shared_*_plan): planning costs more than the transforms of a cissim fit, which asks for
// the same lengths many times (each experiment's period, the correlations' padded length). The
// plans are executed on each object's own buffers (fftw_execute_dft_*: thread-safe, aligned alike).
// A forward DFT of even length n is the complex DFT of the n/2 sample pairs, split into the real
// spectrum (msidutil::shared_half_plan: a tenth of the planning of FFTW's real transform, which
// dominated the instructions of a whole `msid fit --method cissim`).
#include "real_dft.hpp"
#include "fit_types.hpp"

#include <cstring>
#include <fftw3.h>

extern "C" {
#include "msid/msid_dmath.h"
}

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
    re_ = fftw_alloc_real(n);   // n even: read as the n/2 complex pairs of the half-length transform
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
    if (n_ % 2 == 0) {
        forward_half(x, X);
        return;
    }
    if (!fwd_) fwd_ = plan_of(n_, false);
    std::memcpy(re_, x, n_ * sizeof(double));
    fftw_execute_dft_r2c((fftw_plan)fwd_, re_, (fftw_complex *)cx_);
    std::memcpy((void *)X, cx_, (n_ / 2 + 1) * sizeof(fftw_complex));
}

// Z = DFT_m(z), z[t] = x[2t] + j x[2t+1], m = n/2: E = (Z[k] + conj Z[m-k]) / 2 and
// O = (Z[k] - conj Z[m-k]) / 2j are the DFTs of the even and odd samples, X[k] = E + W^k O with
// W = exp(-j 2 pi / n) (indices mod m); X[0] and X[m] are Re Z[0] +- Im Z[0], exactly real.
void RealDft::forward_half(const double *x, std::complex<double> *X)
{
    const size_t m = n_ / 2;
    if (!half_) {
        half_ = msidutil::shared_half_plan(m);
        if (!half_) throw FitError("FFTW could not plan a DFT of length " + std::to_string(m));
        tw_.resize(m + 1);
        for (size_t k = 0; k <= m; ++k) {
            double c, s;
            msid_cis_turns(-(double)k / (double)n_, &c, &s);
            tw_[k] = {c, s};
        }
    }
    std::memcpy(re_, x, n_ * sizeof(double));
    fftw_complex *Z = (fftw_complex *)cx_;
    fftw_execute_dft((fftw_plan)half_, (fftw_complex *)re_, Z);
    X[0] = {Z[0][0] + Z[0][1], 0.0};
    X[m] = {Z[0][0] - Z[0][1], 0.0};
    for (size_t k = 1; k < m; ++k) {
        const double zr = Z[k][0], zi = Z[k][1], cr = Z[m - k][0], ci = -Z[m - k][1];
        const double er = 0.5 * (zr + cr), ei = 0.5 * (zi + ci);
        const double orr = 0.5 * (zi - ci), oi = -0.5 * (zr - cr);
        const double wr = tw_[k].real(), wi = tw_[k].imag();
        X[k] = {er + (wr * orr - wi * oi), ei + (wr * oi + wi * orr)};
    }
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
