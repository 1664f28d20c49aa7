// Shared by the LPM Monte Carlo tests: IIR plants and a portable Gaussian generator.
#pragma once
#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <random>
#include <vector>

namespace lpmsim {

using cd = std::complex<double>;

// y = B(q^-1)/A(q^-1) u, direct form II transposed; A[0] = 1.
struct Iir {
    std::vector<double> b, a, s;
    Iir(std::vector<double> b_, std::vector<double> a_) : b(b_), a(a_), s(std::max(b_.size(), a_.size()), 0.0)
    {
        b.resize(s.size(), 0.0);
        a.resize(s.size(), 0.0);
    }
    double step(double x)
    {
        const size_t n = s.size();
        const double y = b[0] * x + s[0];
        for (size_t i = 0; i + 1 < n; ++i) s[i] = b[i + 1] * x - a[i + 1] * y + s[i + 1];
        s[n - 1] = 0.0;
        return y;
    }
    cd freq(double f) const   // at exp(j 2 pi f)
    {
        cd num = 0, den = 0, z1 = std::polar(1.0, -2 * M_PI * f), p = 1;
        for (size_t i = 0; i < b.size(); ++i, p *= z1) {
            num += b[i] * p;
            den += a[i] * p;
        }
        return num / den;
    }
};

// Second-order resonant sections (pole radius 0.95): bandwidth ~ 0.016 cycles/sample.
inline Iir plant(double ang, double g0, double zero)
{
    const double r = 0.95;
    return Iir({g0, g0 * zero}, {1.0, -2 * r * std::cos(ang), r * r});
}

struct Rng {
    std::mt19937_64 g;
    explicit Rng(uint64_t seed) : g(seed) {}
    double n()   // Box-Muller (portable, unlike std::normal_distribution)
    {
        const double u1 = ((g() >> 11) + 0.5) * (1.0 / 9007199254740992.0), u2 = (g() >> 11) * (1.0 / 9007199254740992.0);
        return std::sqrt(-2 * std::log(u1)) * std::cos(2 * M_PI * u2);
    }
};

}  // namespace lpmsim
