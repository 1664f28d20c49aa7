#include "spectra.hpp"

#include <cstring>
#include <fftw3.h>

namespace msidest {

Spectra record_spectra(const std::vector<RecordView> &recs, unsigned nu, unsigned ny)
{
    if (recs.empty()) throw EstError("no experiment records");
    Spectra s;
    s.N = recs[0].n;
    s.nk = s.N / 2 + 1;
    s.nu = nu;
    s.ny = ny;
    s.m = (unsigned)recs.size();
    for (const auto &r : recs)
        if (r.n != s.N) throw EstError("all experiments must have the same number of samples");
    const unsigned C = nu + ny;
    s.X.resize((size_t)s.m * C * s.nk);
    double *in = fftw_alloc_real(s.N);
    fftw_complex *out = fftw_alloc_complex(s.nk);
    if (!in || !out) throw EstError("out of memory for the FFT");
    // FFTW_ESTIMATE: the plan does not depend on timing, so results are deterministic.
    fftw_plan p = fftw_plan_dft_r2c_1d((int)s.N, in, out, FFTW_ESTIMATE);
    for (unsigned e = 0; e < s.m; ++e)
        for (unsigned c = 0; c < C; ++c) {
            const double *src = recs[e].rows + c;
            const size_t st = recs[e].stride;
            for (size_t t = 0; t < s.N; ++t) in[t] = src[t * st];
            fftw_execute(p);
            std::memcpy(reinterpret_cast<double *>(&s.X[((size_t)e * C + c) * s.nk]), out, s.nk * sizeof(fftw_complex));
        }
    fftw_destroy_plan(p);
    fftw_free(in);
    fftw_free(out);
    return s;
}

}  // namespace msidest
