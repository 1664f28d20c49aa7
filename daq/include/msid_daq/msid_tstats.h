/**
 * @file msid_tstats.h
 * @brief Statistics of a stream of durations (tick lateness, round trips):
 *        count, mean and variance (Welford), exact minimum and maximum, and
 *        quantiles from a log-linear histogram, in fixed memory.
 *
 * The histogram has 64 linear buckets per power of two of nanoseconds, so a
 * quantile is within 1/64 (1.6 %) of a value the stream held, from 1 ns to
 * 2^40 ns (18 minutes); larger values land in the last bucket (the maximum
 * stays exact). Results depend only on the values added, not on their order
 * within one bucket. No allocation: the object is the memory.
 */
#ifndef MSID_TSTATS_H
#define MSID_TSTATS_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MSID_TSTATS_SUB 64u     /**< linear buckets per octave */
#define MSID_TSTATS_OCT 41u     /**< octaves: [0, 1), [1, 2), ... up to 2^40 ns */
#define MSID_TSTATS_BUCKETS (MSID_TSTATS_SUB * MSID_TSTATS_OCT)

/** Statistics of non-negative durations in nanoseconds (negative values count as 0 in the histogram). */
typedef struct msid_tstats {
    uint64_t n;
    double mean, m2;          /**< Welford: mean and sum of squared deviations, ns and ns^2 */
    int64_t min, max;         /**< ns (exact) */
    uint32_t bucket[MSID_TSTATS_BUCKETS];
} msid_tstats;

/** @brief Empty statistics. */
void msid_tstats_reset(msid_tstats *s);

/** @brief Add one duration (ns). */
void msid_tstats_add(msid_tstats *s, int64_t ns);

/** @brief The q-quantile (0 <= q <= 1) in ns: the middle of the bucket holding it, clamped to [min, max]; 0 if empty. */
double msid_tstats_quantile(const msid_tstats *s, double q);

/** @brief Sample standard deviation in ns (0 with fewer than 2 values). */
double msid_tstats_sd(const msid_tstats *s);

#ifdef __cplusplus
}
#endif
#endif
