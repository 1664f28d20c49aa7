/* Tail probabilities of the transient and drift tests: the Gamma(n, 1)
 * upper tail of a Fisher sum (two forms) and the F(1, n) tail. */
#include "msid_pvalue.h"
#include <math.h>

double msid__gamma_upper_log(uint32_t n, double S, const double *logj)
{
    if (!(S > 0.0)) return 1.0;
    const double lS = log(S);
    double lt = -S, mx = -S;
    for (uint32_t j = 1; j < n; ++j) {
        lt += lS - logj[j];
        if (lt > mx) mx = lt;
    }
    double sum = 0.0;
    lt = -S;
    sum += exp(lt - mx);
    for (uint32_t j = 1; j < n; ++j) {
        lt += lS - logj[j];
        sum += exp(lt - mx);
    }
    const double q = exp(mx + log(sum));
    return q > 1.0 ? 1.0 : q;
}

/* ln 2 in two parts (fdlibm): LN2_HI has 32 significant bits, so F * LN2_HI
 * is exact for |F| < 2^21 and, F being the integer nearest S / ln 2,
 * F LN2_HI - S is exact too (Sterbenz): exp(-S) = 2^-F exp(F ln 2 - S) with
 * an argument in [-0.35, 0.35] that carries no rounding of S's size. */
#define MSID_LN2_HI 6.93147180369123816490e-01
#define MSID_LN2_LO 1.90821492927058770002e-10
#define MSID_INV_LN2 1.44269504088896338700e+00

double msid__gamma_upper(uint32_t n, double S)
{
    if (!(S > 0.0)) return 1.0;
    /* sum_{j<n} S^j / j! = 2^E sum (term, sum kept below 2^600 * S) */
    double term = 1.0, sum = 1.0;
    int E = 0;
    for (uint32_t j = 1; j < n; ++j) {
        term *= S / (double)j;
        sum += term;
        if (sum > 0x1p600) {                 /* exact scaling: both stay normal or negligible */
            term *= 0x1p-600;
            sum *= 0x1p-600;
            E += 600;
        } else if ((double)j >= S && term < sum * 0x1p-54) {
            /* every later term is smaller (ratio S/(j+1) < 1) and below half an
             * ulp of sum: adding it would change no bit */
            break;
        }
    }
    int e;
    const double m = frexp(sum, &e);         /* sum = m 2^e, m in [0.5, 1) */
    E += e;
    /* Q = m 2^E exp(-S) = ldexp(m exp(F ln 2 - S), E - F) */
    const int F = S < 1e9 ? (int)floor(S * MSID_INV_LN2 + 0.5) : (int)(1e9 * MSID_INV_LN2);
    const double x = ((double)F * MSID_LN2_HI - S) + (double)F * MSID_LN2_LO;
    const double q = ldexp(m * exp(x), E - F);
    return q > 1.0 ? 1.0 : q;
}

double msid__f1_tail(double f, uint32_t n)
{
    if (!(f > 0.0)) return 1.0;
    const double th = atan(sqrt(f / (double)n));
    const double c2 = cos(th) * cos(th), sn = sin(th);
    double A;
    if (n & 1u) {
        double term = 1.0, sum = (n > 1u) ? 1.0 : 0.0;
        for (uint32_t k = 1; 2u * k + 1u <= n - 2u && n > 1u; ++k) {
            term *= c2 * (2.0 * k) / (2.0 * k + 1.0);
            sum += term;
        }
        A = 0.63661977236758134308 * (th + (n > 1u ? sn * cos(th) * sum : 0.0));
    } else {
        double term = 1.0, sum = 1.0;
        for (uint32_t k = 1; 2u * k <= n - 2u; ++k) {
            term *= c2 * (2.0 * k - 1.0) / (2.0 * k);
            sum += term;
        }
        A = sn * sum;
    }
    const double p = 1.0 - A;
    return p < 0.0 ? 0.0 : (p > 1.0 ? 1.0 : p);
}
