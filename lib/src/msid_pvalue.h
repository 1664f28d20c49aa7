/* Tail probabilities of the transient and drift tests (msid_pstats). Not installed. */
#ifndef MSID_PVALUE_H
#define MSID_PVALUE_H

#include <stdint.h>

/* Upper tail of Gamma(n, 1) at S for integer n >= 1,
 * Q = exp(-S) sum_{j<n} S^j / j!, each term in the log domain (one exp per
 * term). logj[j] = log(j) for 1 <= j < n. The drift test's p-value (written
 * to the FRF file) uses this one, unchanged. Returns a value in [0, 1]. */
double msid__gamma_upper_log(uint32_t n, double S, const double *logj);

/* The same tail by the term ratio recurrence t_j = t_{j-1} S / j (no exp or
 * log per term; sum rescaled by 2^-600 before it could overflow), then
 * Q = m exp(E ln 2 - S) for the sum m 2^E: two transcendental calls per call
 * whatever n. Relative error a few times 1e-16 per term of the recurrence
 * (bounded by 2 (n-1) eps, eps = 2^-53) plus exp's; tests/unit test_pstats
 * bounds it against the log-domain form and a long-double reference. */
double msid__gamma_upper(uint32_t n, double S);

/* P(F(1, n) > f) for integer n >= 1 (two-sided Student-t tail at sqrt(f),
 * Abramowitz & Stegun 26.7.3-26.7.4). In [0, 1]. */
double msid__f1_tail(double f, uint32_t n);

#endif
