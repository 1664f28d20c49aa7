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
 * log per term; the sum rescaled by 2^-600 before it could overflow, the
 * loop left once the terms fall below half an ulp of the sum), then
 * Q = ldexp(m exp(F ln 2 - S), E - F) for the sum m 2^E: one exp per call
 * whatever n. Relative error: the recurrence's roundings (at most 2 j eps on
 * term j, eps = 2^-53) plus 1.5 ulp; tests/unit test_pstats bounds it
 * against the log-domain form, a long-double reference and closed forms. */
double msid__gamma_upper(uint32_t n, double S);

/* P(F(1, n) > f) for integer n >= 1 (two-sided Student-t tail at sqrt(f),
 * Abramowitz & Stegun 26.7.3-26.7.4). In [0, 1]. */
double msid__f1_tail(double f, uint32_t n);

#endif
