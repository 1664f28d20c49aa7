// DFTs of whole records, one FFT per channel (FFTW, estimate-mode plans: the
// same samples give bit-identical spectra on every run).
#pragma once
#include <complex>
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace msidest {

using cd = std::complex<double>;

// One clear message for bad requests and data (the CLI prints it once).
struct EstError : std::runtime_error {
    explicit EstError(const std::string &m) : std::runtime_error(m) {}
};

// One experiment's samples: n rows of [u_1..u_nu, y_1..y_ny], row-major with `stride`
// doubles per row (stride >= nu + ny). Not owned.
struct RecordView {
    const double *rows = nullptr;
    size_t n = 0;
    size_t stride = 0;
};

// X_c[k] = sum_{t<N} x_c(t) exp(-j 2 pi k t / N) (no scaling), k = 0..N/2, for every
// channel c of every experiment. All experiments must have the same N.
struct Spectra {
    size_t N = 0;              // samples per experiment
    size_t nk = 0;             // bins stored: N/2 + 1
    unsigned nu = 0, ny = 0, m = 0;
    std::vector<cd> X;         // [(e * (nu + ny) + c) * nk + k]; c < nu inputs, then outputs
    const cd *U(unsigned e, unsigned j) const { return &X[((size_t)e * (nu + ny) + j) * nk]; }
    const cd *Y(unsigned e, unsigned i) const { return &X[((size_t)e * (nu + ny) + nu + i) * nk]; }
};

Spectra record_spectra(const std::vector<RecordView> &recs, unsigned nu, unsigned ny);

}  // namespace msidest
