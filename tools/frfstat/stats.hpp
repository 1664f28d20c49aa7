// The distribution laws the FRF stage tests with (the BLA's F tests, the detection lines) and the
// fitting stage builds on (the cost's law, the likelihood-ratio tests).
#pragma once

namespace msidstat {

// Regularized upper incomplete gamma Q(a, x) = Gamma(a, x) / Gamma(a), a > 0, x >= 0.
double gamma_q(double a, double x);
// P(chi2_k > x).
double chi2_sf(double k, double x);

// A weighted cost V of (real) dof nu built from whitened residuals with weights
// estimated from n complex dof (p outputs per line; n = inf for known weights):
// V ~ c chi2_k approximately (two-moment match). Returns the p-value P(V' >= V).
struct CostLaw {
    double mean = 0, var = 0, c = 0, k = 0;
};
CostLaw cost_law(double nu, double n, double p);
double cost_pvalue(const CostLaw &law, double V);

}  // namespace msidstat

namespace msidstat {
// Regularized incomplete beta I_x(a, b), a, b > 0, 0 <= x <= 1.
double beta_inc(double a, double b, double x);
// P(F(d1, d2) > x).
double f_sf(double d1, double d2, double x);
// P(Binomial(n, p) >= k).
double binom_sf(int n, double p, int k);
}  // namespace msidstat
