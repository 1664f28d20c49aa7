#include "multi_sim.hpp"

#include <cmath>

namespace msidfit {

std::vector<cd> M1Case::poles_ct() const
{
    std::vector<cd> s;
    for (int k = 0; k < 3; ++k) {
        const double w = 2 * M_PI * fn[k];
        s.emplace_back(-zeta[k] * w, w * std::sqrt(1 - zeta[k] * zeta[k]));
    }
    return s;
}

VecR M1Case::alpha() const
{
    std::vector<cd> z;
    for (const cd &s : poles_ct()) {
        z.push_back(std::exp(s * ts));
        z.push_back(std::conj(z.back()));
    }
    return multi_alpha_from_poles(z);
}

MatR m1_record(const M1Case &c, msid_rng &r, int T, MatR *x0)
{
    const auto s = c.poles_ct();
    double a[3], b[3];
    for (int k = 0; k < 3; ++k) {
        a[k] = msid_rng_normal(&r);
        b[k] = msid_rng_normal(&r);
    }
    auto y = [&](double t) {
        double v = 0;
        for (int k = 0; k < 3; ++k)
            v += std::exp(s[k].real() * t * c.ts) * (a[k] * std::cos(s[k].imag() * t * c.ts) + b[k] * std::sin(s[k].imag() * t * c.ts));
        return v;
    };
    MatR out(T, 1);
    for (int t = 0; t < T; ++t) out(t, 0) = y(t);
    if (x0) {
        *x0 = MatR(1, 6);
        for (int m = 1; m <= 6; ++m) (*x0)(0, m - 1) = y(-m);
    }
    return out;
}

MultiData m1_data(const M1Case &c, msid_rng &r, int N)
{
    MultiData d;
    for (int i = 0; i < N; ++i) {
        const int T = c.Tmin + (int)(msid_rng_uniform(&r) * (c.Tmax - c.Tmin + 1));
        MatR x0;
        MultiRecord rec;
        rec.y = m1_record(c, r, T, &x0);
        rec.u = MatR(T, 0);
        d.clean.push_back(rec);
        d.x0.push_back(x0);
    }
    return d;
}

double multi_noise_sd(const std::vector<MultiRecord> &clean, double snr)
{
    double ss = 0, n = 0;
    for (const auto &r : clean) {
        ss += r.y.squaredNorm();
        n += (double)r.y.size();
    }
    return std::sqrt(ss / n) / snr;
}

std::vector<MultiRecord> multi_add_noise(const std::vector<MultiRecord> &clean, msid_rng &r, double sd)
{
    std::vector<MultiRecord> out = clean;
    for (auto &rec : out)
        for (Eigen::Index k = 0; k < rec.y.size(); ++k) rec.y.data()[k] += sd * msid_rng_normal(&r);
    return out;
}

std::vector<MultiRecord> multi_add_ar_noise(const std::vector<MultiRecord> &clean, msid_rng &rng, const VecR &c, double sd)
{
    const double se = sd / std::sqrt(multi_ar_autocov(c, 0)(0));   // innovations sd for var v = sd^2
    std::vector<MultiRecord> out = clean;
    const int p = (int)c.size();
    for (auto &rec : out)
        for (Eigen::Index j = 0; j < rec.y.cols(); ++j) {
            const Eigen::Index T = rec.y.rows(), B = 300;
            VecR v = VecR::Zero(T + B);
            for (Eigen::Index t = 0; t < T + B; ++t) {
                double acc = se * msid_rng_normal(&rng);
                for (int k = 1; k <= p && t - k >= 0; ++k) acc -= c(k - 1) * v(t - k);
                v(t) = acc;
            }
            rec.y.col(j) += v.tail(T);
        }
    return out;
}

VecR IoCase::alpha() const
{
    const cd z1 = std::polar(0.9, 0.5), z2 = std::polar(0.8, 1.4);
    return multi_alpha_from_poles({z1, std::conj(z1), z2, std::conj(z2)});
}

std::vector<MatR> IoCase::beta() const
{
    const double b[4] = {1.0, -0.5, 0.3, 0.2};
    std::vector<MatR> out;
    for (double x : b) out.push_back(MatR::Constant(1, 1, x));
    return out;
}

MultiData io_data(const IoCase &c, msid_rng &r, int N)
{
    // observer-form state space of b(q^-1) / a(q^-1) (strictly proper):
    // x(t+1) = A x(t) + B u(t), y(t) = x_1(t), A = [-alpha | I; 0], B = beta
    const VecR a = c.alpha();
    const auto bt = c.beta();
    const int n = 4;
    MatR A = MatR::Zero(n, n);
    VecR B(n);
    for (int i = 0; i < n; ++i) {
        A(i, 0) = -a(i);
        if (i + 1 < n) A(i, i + 1) = 1.0;
        B(i) = bt[(size_t)i](0, 0);
    }
    MultiData d;
    for (int i = 0; i < N; ++i) {
        const int T = c.Tmin + (int)(msid_rng_uniform(&r) * (c.Tmax - c.Tmin + 1));
        MultiRecord rec;
        rec.u = MatR(T, 1);
        rec.y = MatR(T, 1);
        VecR x(n);
        for (int k = 0; k < n; ++k) x(k) = 3.0 * msid_rng_normal(&r);   // a large transient
        for (int t = 0; t < T; ++t) {
            rec.u(t, 0) = msid_rng_normal(&r);
            rec.y(t, 0) = x(0);
            x = A * x + B * rec.u(t, 0);
        }
        d.clean.push_back(rec);
        d.x0.emplace_back();   // filled by the caller where needed (exact fit at the true alpha)
    }
    return d;
}

}  // namespace msidfit
