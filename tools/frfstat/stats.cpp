#include "stats.hpp"

#include <cmath>
#include <limits>

namespace msidstat {

// Series for P(a,x) when x < a+1, continued fraction for Q(a,x) otherwise.
double gamma_q(double a, double x)
{
    if (!(x > 0)) return 1.0;
    if (!std::isfinite(x)) return 0.0;
    const double lg = std::lgamma(a);
    if (x < a + 1.0) {
        double ap = a, sum = 1.0 / a, del = sum;
        for (int n = 0; n < 100000; ++n) {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if (std::fabs(del) < std::fabs(sum) * 1e-16) break;
        }
        const double P = sum * std::exp(-x + a * std::log(x) - lg);
        return std::fmax(0.0, 1.0 - P);
    }
    // Lentz continued fraction
    const double tiny = 1e-300;
    double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
    for (int i = 1; i < 100000; ++i) {
        const double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (std::fabs(d) < tiny) d = tiny;
        c = b + an / c;
        if (std::fabs(c) < tiny) c = tiny;
        d = 1.0 / d;
        const double del = d * c;
        h *= del;
        if (std::fabs(del - 1.0) < 1e-16) break;
    }
    return std::exp(-x + a * std::log(x) - lg) * h;
}

double chi2_sf(double k, double x) { return gamma_q(0.5 * k, 0.5 * x); }

// Each real residual component of a complex line contributes (|e|^2/v)/2 with
// |e|^2/v ~ F(2, 2n) when v is estimated with n complex dof: mean n/(n-1),
// variance n^3/((n-1)^2 (n-2)). For p outputs the mean n/(n-p) of the inverse
// Wishart is used with the same relative variance. Known weights: chi2.
CostLaw cost_law(double nu, double n, double p)
{
    CostLaw L;
    double mu = 1.0, s2 = 1.0;
    if (std::isfinite(n) && n < 1e8) {
        mu = n > p ? n / (n - p) : std::numeric_limits<double>::infinity();
        const double rel = n > 2 ? (n * n * n / ((n - 1) * (n - 1) * (n - 2))) / std::pow(n / (n - 1), 2) : 1e300;
        s2 = rel * mu * mu;
    }
    // per complex residual (2 real components): mean mu, var s2; per real component half of each
    L.mean = 0.5 * nu * mu;
    L.var = 0.5 * nu * s2;    // V = sum over nu/2 complex terms of (|e|^2/v) with var s2
    L.c = L.var / (2.0 * L.mean);
    L.k = 2.0 * L.mean * L.mean / L.var;
    return L;
}

double cost_pvalue(const CostLaw &L, double V)
{
    if (!(L.c > 0) || !std::isfinite(L.k)) return std::numeric_limits<double>::quiet_NaN();
    return chi2_sf(L.k, V / L.c);
}

}  // namespace msidstat

namespace msidstat {

// Continued fraction of I_x(a, b) (modified Lentz), used where it converges fast:
// x < (a + 1) / (a + b + 2); the symmetry I_x(a, b) = 1 - I_{1-x}(b, a) otherwise.
static double beta_cf(double a, double b, double x)
{
    const double tiny = 1e-300;
    double c = 1.0, d = 1.0 - (a + b) * x / (a + 1.0);
    if (std::fabs(d) < tiny) d = tiny;
    d = 1.0 / d;
    double h = d;
    for (int m = 1; m < 100000; ++m) {
        const double m2 = 2.0 * m;
        double aa = m * (b - m) * x / ((a + m2 - 1.0) * (a + m2));
        d = 1.0 + aa * d; if (std::fabs(d) < tiny) d = tiny;
        c = 1.0 + aa / c; if (std::fabs(c) < tiny) c = tiny;
        d = 1.0 / d;
        h *= d * c;
        aa = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0));
        d = 1.0 + aa * d; if (std::fabs(d) < tiny) d = tiny;
        c = 1.0 + aa / c; if (std::fabs(c) < tiny) c = tiny;
        d = 1.0 / d;
        const double del = d * c;
        h *= del;
        if (std::fabs(del - 1.0) < 1e-15) break;
    }
    return h;
}

double beta_inc(double a, double b, double x)
{
    if (!(x > 0)) return 0.0;
    if (!(x < 1)) return 1.0;
    const double lb = std::lgamma(a + b) - std::lgamma(a) - std::lgamma(b) + a * std::log(x) + b * std::log1p(-x);
    if (x < (a + 1.0) / (a + b + 2.0)) return std::exp(lb) * beta_cf(a, b, x) / a;
    return 1.0 - std::exp(lb) * beta_cf(b, a, 1.0 - x) / b;
}

double f_sf(double d1, double d2, double x)
{
    if (!(x > 0)) return 1.0;
    if (!std::isfinite(x)) return 0.0;
    return beta_inc(0.5 * d2, 0.5 * d1, d2 / (d2 + d1 * x));
}

double binom_sf(int n, double p, int k)
{
    if (k <= 0) return 1.0;
    if (k > n) return 0.0;
    return beta_inc((double)k, (double)(n - k + 1), p);   // P(X >= k) = I_p(k, n - k + 1)
}

}  // namespace msidstat
