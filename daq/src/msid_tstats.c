/* Statistics of durations (msid_tstats.h): Welford moments, exact extremes, a log-linear histogram. */
#include "msid_daq/msid_tstats.h"

#include <math.h>
#include <string.h>

void msid_tstats_reset(msid_tstats *s)
{
    memset(s, 0, sizeof *s);
    s->min = INT64_MAX;
    s->max = INT64_MIN;
}

/* Bucket of v >= 0: values below 64 ns one bucket each; above, octave o >= 1 of [2^(o+5), 2^(o+6)) split into
 * 64 linear buckets. */
static uint32_t bucket_of(uint64_t v)
{
    if (v < MSID_TSTATS_SUB) return (uint32_t)v;
    uint32_t o = 0;
    while ((v >> (o + 6)) > 1) ++o;   /* v in [2^(o+6), 2^(o+7)) */
    const uint32_t oct = o + 1;
    if (oct >= MSID_TSTATS_OCT) return MSID_TSTATS_BUCKETS - 1;
    const uint32_t sub = (uint32_t)((v >> o) - MSID_TSTATS_SUB);   /* 0..63 */
    return oct * MSID_TSTATS_SUB + sub;
}

/* [lo, hi) of bucket b in ns. */
static void bucket_range(uint32_t b, double *lo, double *hi)
{
    const uint32_t oct = b / MSID_TSTATS_SUB, sub = b % MSID_TSTATS_SUB;
    if (oct == 0) { *lo = sub; *hi = sub + 1.0; return; }
    const double w = ldexp(1.0, (int)oct - 1);
    *lo = (MSID_TSTATS_SUB + sub) * w;
    *hi = *lo + w;
}

void msid_tstats_add(msid_tstats *s, int64_t ns)
{
    ++s->n;
    const double x = (double)ns, d = x - s->mean;
    s->mean += d / (double)s->n;
    s->m2 += d * (x - s->mean);
    if (ns < s->min) s->min = ns;
    if (ns > s->max) s->max = ns;
    ++s->bucket[bucket_of(ns < 0 ? 0u : (uint64_t)ns)];
}

double msid_tstats_sd(const msid_tstats *s) { return s->n > 1 ? sqrt(s->m2 / (double)(s->n - 1)) : 0.0; }

double msid_tstats_quantile(const msid_tstats *s, double q)
{
    if (!s->n) return 0.0;
    if (q <= 0) return (double)s->min;
    if (q >= 1) return (double)s->max;
    /* the value of rank ceil(q n) (1-based); a high quantile is counted down from the maximum's bucket, a low one up
       from the minimum's, so that a p99 looks at the few buckets of the tail */
    uint64_t rank = (uint64_t)ceil(q * (double)s->n);
    if (rank < 1) rank = 1;
    uint32_t b = 0;
    if (q > 0.5) {
        const uint64_t above = s->n - rank;   /* values of higher rank */
        uint64_t acc = 0;
        for (b = bucket_of(s->max < 0 ? 0u : (uint64_t)s->max);; --b) {
            acc += s->bucket[b];
            if (acc > above || b == 0) break;
        }
    } else {
        uint64_t acc = 0;
        for (b = bucket_of(s->min < 0 ? 0u : (uint64_t)s->min); b < MSID_TSTATS_BUCKETS; ++b) {
            acc += s->bucket[b];
            if (acc >= rank) break;
        }
        if (b == MSID_TSTATS_BUCKETS) return (double)s->max;
    }
    double lo, hi;
    bucket_range(b, &lo, &hi);
    double v = 0.5 * (lo + hi);
    if (v < (double)s->min) v = (double)s->min;
    if (v > (double)s->max) v = (double)s->max;
    return v;
}
