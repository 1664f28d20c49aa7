/* Period statistics (Welford, complex Hermitian) and the leave-one-out
 * transient test. Mean/covariance: Pintelon 2002 eqs. (25), (32). */
#include "msid/msid_pstats.h"
#include "msid/msid_linedft.h"
#include "msid_internal.h"
#include "msid_cmat.h"
#include "msid_pvalue.h"
#include <math.h>

/* The one memory layout (see msid__layout): mean, scatter, then the period history. */
static size_t layout(msid_pstats *ps, const msid_pstats_cfg *c, void *mem)
{
    const size_t L = c->n_lines, q = c->n_channels, H = c->max_periods;
    msid__layout y = msid__layout_begin(mem);
    ps->mean = (msid_cplx *)msid__lay(&y, L * q, sizeof(msid_cplx));
    ps->m2 = (msid_cplx *)msid__lay(&y, msid__mul(L * q, q), sizeof(msid_cplx));
    ps->hist = 0; ps->hflag = 0; ps->hdrop = 0; ps->hpval = 0; ps->hidx = 0; ps->scr = 0;
    ps->tmean = 0; ps->tm2 = 0;
    if (H) {
        ps->hist = (msid_cplx *)msid__lay(&y, msid__mul(H, L * q), sizeof(msid_cplx));
        ps->hflag = (uint8_t *)msid__lay(&y, H, 1);
        ps->hdrop = (uint8_t *)msid__lay(&y, H, 1);
        ps->hpval = (double *)msid__lay(&y, H, sizeof(double));
        ps->hidx = (uint32_t *)msid__lay(&y, H, sizeof(uint32_t));
        ps->scr = (double *)msid__lay(&y, msid__mul(L * q, 5u), sizeof(double));
        if (c->beyond_history) {
            ps->tmean = (msid_cplx *)msid__lay(&y, L * q, sizeof(msid_cplx));
            ps->tm2 = (msid_cplx *)msid__lay(&y, msid__mul(L * q, q), sizeof(msid_cplx));
        }
    }
    return y.size;
}

size_t msid_pstats_mem_size(const msid_pstats_cfg *c)
{
    if (!c || c->n_lines == 0 || c->n_channels == 0 || c->n_channels > MSID_MAX_CHANNELS) return 0;
    msid_pstats tmp;
    return layout(&tmp, c, 0);
}

static void clear_moments(msid_cplx *mean, msid_cplx *m2, size_t L, size_t q)
{
    for (size_t k = 0; k < L * q; ++k) mean[k] = msid__c(0.0, 0.0);
    for (size_t k = 0; k < L * q * q; ++k) m2[k] = msid__c(0.0, 0.0);
}

static void clear_stats(msid_pstats *ps)
{
    ps->K = 0;
    clear_moments(ps->mean, ps->m2, ps->n_lines, ps->n_channels);
}

void msid_pstats_reset(msid_pstats *ps)
{
    clear_stats(ps);
    ps->tK = 0;
    ps->beyond = 0;
    if (ps->tmean) clear_moments(ps->tmean, ps->tm2, ps->n_lines, ps->n_channels);
    ps->nhist = 0;
    ps->seg_skipped = 0;
    msid_pstats_counts z = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    ps->cnt = z;
    ps->drift_pval = NAN;
}

msid_status msid_pstats_init(msid_pstats *ps, const msid_pstats_cfg *c, void *mem, size_t len)
{
    if (!ps || !c) return MSID_E_NULL;
    if (c->n_lines == 0) return MSID_E_NO_LINES;
    if (c->n_channels == 0 || c->n_channels > MSID_MAX_CHANNELS) return MSID_E_DIMS;
    if (c->transient != MSID_TRANSIENT_OFF && c->transient != MSID_TRANSIENT_FLAG &&
        c->transient != MSID_TRANSIENT_DROP) return MSID_E_ARG;
    if (c->transient != MSID_TRANSIENT_OFF && c->max_periods < 3) return MSID_E_ARG;
    if (c->alpha != 0.0 && !(c->alpha > 0.0 && c->alpha < 1.0)) return MSID_E_ARG;
    const msid_status st = msid__mem_check(mem, len, msid_pstats_mem_size(c));
    if (st != MSID_OK) return st;
    (void)layout(ps, c, mem);
    ps->n_lines = c->n_lines;
    ps->n_channels = c->n_channels;
    ps->skip_periods = c->skip_periods;
    ps->max_periods = c->max_periods;
    ps->transient = c->transient;
    ps->alpha = c->alpha != 0.0 ? c->alpha : 0.01;
    msid_pstats_reset(ps);
    return MSID_OK;
}

/* Welford update (Pintelon 2002 eqs. 25, 32 in running form) of mean and the
 * Hermitian scatter of lines [l0, l1) with period z; ps->K already counts z.
 * The upper triangle is computed and mirrored, so m2 is exactly Hermitian.
 * Lines are independent, so updating them in any split gives the same bits. */
static void welford_into(msid_cplx *mean, msid_cplx *m2, uint32_t Kn, size_t q, const msid_cplx *z, size_t l0,
                         size_t l1)
{
    const double K = (double)Kn, invK = 1.0 / K, f = (K - 1.0) / K;
    msid_cplx dl[MSID_MAX_CHANNELS];
    for (size_t l = l0; l < l1; ++l) {
        msid_cplx *mu = mean + l * q;
        msid_cplx *M = m2 + l * q * q;
        const msid_cplx *zl = z + l * q;
        msid_cplx al[MSID_MAX_CHANNELS];
        for (size_t c = 0; c < q; ++c) {
            dl[c] = msid__csub(zl[c], mu[c]);
            al[c] = msid__cscale(dl[c], f);
            mu[c] = msid__cadd(mu[c], msid__cscale(dl[c], invK));
        }
        /* M += f d d^H: upper triangle, diagonal real, lower = conj(upper) */
        for (size_t r = 0; r < q; ++r) {
            M[r * q + r].re += al[r].re * dl[r].re + al[r].im * dl[r].im;
            for (size_t c = r + 1; c < q; ++c) {
                const double vr = M[r * q + c].re + (al[r].re * dl[c].re + al[r].im * dl[c].im);
                const double vi = M[r * q + c].im + (al[r].im * dl[c].re - al[r].re * dl[c].im);
                M[r * q + c].re = vr; M[r * q + c].im = vi;
                M[c * q + r].re = vr; M[c * q + r].im = -vi;
            }
        }
    }
}

static void welford_lines(msid_pstats *ps, const msid_cplx *z, size_t l0, size_t l1)
{
    welford_into(ps->mean, ps->m2, ps->K, ps->n_channels, z, l0, l1);
}

/* Chan, Golub & LeVeque's pairwise update: the statistics of the periods beyond the history
 * (tmean, tm2, tK) merged into mean, m2, K: mean += d Kb/K, M += Mb + d d^H Ka Kb / K with
 * d = mean_b - mean_a (upper triangle computed and mirrored, as welford_into). */
static void merge_beyond(msid_pstats *ps)
{
    if (!ps->tK) return;
    const size_t L = ps->n_lines, q = ps->n_channels;
    const double Ka = (double)ps->K, Kb = (double)ps->tK, K = Ka + Kb, wb = Kb / K, f = Ka * Kb / K;
    msid_cplx d[MSID_MAX_CHANNELS];
    for (size_t l = 0; l < L; ++l) {
        msid_cplx *mu = ps->mean + l * q, *M = ps->m2 + l * q * q;
        const msid_cplx *mb = ps->tmean + l * q, *Mb = ps->tm2 + l * q * q;
        for (size_t c = 0; c < q; ++c) {
            d[c] = msid__csub(mb[c], mu[c]);
            mu[c] = msid__cadd(mu[c], msid__cscale(d[c], wb));
        }
        for (size_t r = 0; r < q; ++r) {
            M[r * q + r].re += Mb[r * q + r].re + f * (d[r].re * d[r].re + d[r].im * d[r].im);
            M[r * q + r].im = 0.0;
            for (size_t c = r + 1; c < q; ++c) {
                const double vr = M[r * q + c].re + Mb[r * q + c].re + f * (d[r].re * d[c].re + d[r].im * d[c].im);
                const double vi = M[r * q + c].im + Mb[r * q + c].im + f * (d[r].im * d[c].re - d[r].re * d[c].im);
                M[r * q + c].re = vr; M[r * q + c].im = vi;
                M[c * q + r].re = vr; M[c * q + r].im = -vi;
            }
        }
    }
    ps->K += ps->tK;
}

static void welford(msid_pstats *ps, const msid_cplx *z)
{
    ps->K++;
    welford_lines(ps, z, 0, ps->n_lines);
}

msid_status msid_pstats_add_begin(msid_pstats *ps, uint32_t flags, int *use)
{
    *use = 0;
    ps->cnt.offered++;
    if (flags & MSID_PERIOD_GAP) { ps->cnt.gap++; return MSID_OK; }
    if (flags & MSID_PERIOD_NONFINITE) { ps->cnt.nonfinite++; return MSID_OK; }
    if (ps->seg_skipped < ps->skip_periods) { ps->seg_skipped++; ps->cnt.skipped++; return MSID_OK; }
    ps->beyond = 0;
    if (ps->max_periods && ps->nhist >= ps->max_periods) {
        if (!ps->tmean) { ps->cnt.offered--; return MSID_E_CAPACITY; }
        ps->beyond = 1;   /* used without a history entry: in the statistics, not tested */
        ps->tK++;
        ps->cnt.untested++;
    } else if (ps->max_periods) {
        ps->hflag[ps->nhist] = 0;
        ps->hdrop[ps->nhist] = 0;
        ps->hpval[ps->nhist] = NAN;
        ps->hidx[ps->nhist] = ps->cnt.offered - 1u;
        ps->nhist++;
    }
    ps->K++;
    ps->cnt.used = ps->K;
    *use = 1;
    return MSID_OK;
}

void msid_pstats_add_lines(msid_pstats *ps, const msid_cplx *z, uint32_t l0, uint32_t l1)
{
    if (l1 > ps->n_lines) l1 = ps->n_lines;
    if (l0 >= l1) return;
    const size_t q = ps->n_channels;
    if (ps->beyond) {
        welford_into(ps->tmean, ps->tm2, ps->tK, q, z, l0, l1);
    } else if (ps->max_periods) {
        msid_cplx *dst = ps->hist + ((size_t)(ps->nhist - 1u) * ps->n_lines + l0) * q;
        for (size_t k = 0; k < (size_t)(l1 - l0) * q; ++k) dst[k] = z[(size_t)l0 * q + k];
    }
    welford_lines(ps, z, l0, l1);
}

msid_status msid_pstats_add(msid_pstats *ps, const msid_cplx *z, uint32_t flags)
{
    int use;
    const msid_status st = msid_pstats_add_begin(ps, flags, &use);
    if (use) msid_pstats_add_lines(ps, z, 0, ps->n_lines);
    return st;
}

/* Combining p-values: channels by Bonferroni within a line; lines by a
 * Fisher sum (conservative Gamma(L,1) tail) and a Bonferroni minimum, each at
 * half the level. */
typedef struct pcomb { double fisher, pmin, cmin; uint32_t ntested, qt; } pcomb;

static void pc_channel(pcomb *c, double pv)
{
    c->qt++;
    if (pv < c->cmin) c->cmin = pv;
}

static void pc_line_end(pcomb *c)
{
    if (c->qt == 0) return;
    double pl = c->cmin * (double)c->qt;          /* Bonferroni over channels */
    if (pl > 1.0) pl = 1.0;
    c->ntested++;
    c->fisher += pl > 0.0 ? -log(pl) : 745.0;
    if (pl < c->pmin) c->pmin = pl;
    c->cmin = 1.0;
    c->qt = 0;
}

/* Combined p-value 2 min(Fisher tail, Bonferroni minimum). logj given: the
 * Fisher tail in the log-domain form (the drift test, whose p-value is
 * written to the FRF file bit for bit); NULL: the ratio recurrence. */
static double pc_result(const pcomb *c, const double *logj)
{
    if (c->ntested == 0) return 1.0;
    const double pf = logj ? msid__gamma_upper_log(c->ntested, c->fisher, logj) : msid__gamma_upper(c->ntested, c->fisher);
    double pb = c->pmin * (double)c->ntested;
    if (pb > 1.0) pb = 1.0;
    double pv = 2.0 * (pf < pb ? pf : pb);
    return pv > 1.0 ? 1.0 : pv;
}

/* Fisher terms up to this -log p take the log-domain path; beyond it the
 * line's p-value would be subnormal and the exact form (745 for 0) is used. */
#define MSID_PSTATS_LOG_FAST_MAX 700.0

/* p-value of one kept period p against the other kept periods; mean[l*q+c]
 * the kept means, m2d[l*q+c] the kept diagonal scatter (see msid_pstats_detect).
 * The complex channels of a line need only
 * the largest statistic: P(F(2, 2n) > t) is decreasing in t and the line keeps
 * only its channels' minimum p-value (the minimum of f(t_c) is f(max t_c) for
 * a non-increasing f; tests/unit test_pstats checks it bit for bit).
 *
 * Log domain (a line of complex channels only): with a = n log1p(tmax/n) =
 * -log P(F(2, 2n) > tmax) (Pintelon 2002 eq. 34 form: (1 + t/n)^-n) and qt
 * tested channels, the line's Bonferroni p-value is pl = min(1, qt e^-a),
 * so its Fisher term -log pl = max(0, a - log qt): one log1p per line, no exp
 * and no log. The Bonferroni minimum over lines takes the direct form
 * min(1, qt exp(-a)) on every line whose term comes within 1e-9 of the
 * largest so far (-log pl and a - log qt agree to ~1e-13 while pl is normal),
 * so the minimum is the direct form's value bit for bit at about log L exps per
 * period. Lines with a real or deterministic channel, and terms above
 * MSID_PSTATS_LOG_FAST_MAX, go through the direct form (pc_channel / pc_line_end). */
static double period_pvalue(const msid_pstats *ps, uint32_t p, const msid_cplx *mean, const double *m2d, uint32_t K,
                            const double *logq)
{
    const size_t L = ps->n_lines, q = ps->n_channels;
    const msid_cplx *zp = ps->hist + (size_t)p * L * q;
    const double Kd = (double)K, n = (double)(K - 2u);
    /* the direct expressions' constant factors, hoisted out of the loops (the same bits) */
    const double KK = Kd / (Kd - 1.0), kf = 1.0 + 1.0 / (Kd - 1.0), rK1 = 1.0 / (Kd - 1.0);
    pcomb pc = {0.0, 1.0, 1.0, 0u, 0u};
    double best = -1.0;                              /* largest log-domain term so far */
    for (size_t l = 0; l < L; ++l) {
        double tmax = -1.0;                          /* largest F(2, 2n) statistic of the line */
        int exact = 0;                               /* a real or deterministic channel: exact form */
        for (size_t c = 0; c < q; ++c) {
            const msid_cplx mu = mean[l * q + c];
            const double dev2 = msid__cabs2(msid__csub(zp[l * q + c], mu));
            const double m2c = m2d[l * q + c];
            /* leave-one-out scatter s2 = X / n and difference d2 */
            const double X = m2c - KK * dev2;
            const double d2 = dev2 * KK * KK;
            const int real = mu.im == 0.0 && zp[l * q + c].im == 0.0;
            /* s2 surely above the deterministic floor (the floor below with a
             * multiplication for its division, margin 1e-6): a complex channel */
            if (!real && X > n * ((1e-24 * (msid__cabs2(mu) + m2c * rK1) + 1e-300) * (1.0 + 1e-6))) {
                const double t = d2 / ((X / n) * kf);
                tmax = t > tmax ? t : tmax;
                pc.qt++;                             /* counted now, its p-value below */
                continue;
            }
            const double s2 = X / n;
            const double floor_ = 1e-24 * (msid__cabs2(mu) + m2c / (Kd - 1.0)) + 1e-300;
            if (s2 <= floor_) {
                if (d2 <= floor_) continue;          /* deterministic channel, unchanged */
                pc_channel(&pc, 0.0);                /* deterministic channel that changed */
                exact = 1;
                continue;
            }
            const double t = d2 / (s2 * kf);
            if (real) {
                pc_channel(&pc, msid__f1_tail(t, K - 2u)); /* real line (DC, Nyquist): F(1, n) */
                exact = 1;
            } else {
                if (t > tmax) tmax = t;
                pc.qt++;
            }
        }
        if (pc.qt == 0) continue;                    /* no channel tested */
        const double a = tmax >= 0.0 ? n * log1p(tmax / n) : 0.0;   /* -log P(F(2, 2n) > tmax) */
        double lp = a - logq[pc.qt];
        if (exact || lp > MSID_PSTATS_LOG_FAST_MAX) {
            if (tmax >= 0.0) {
                const double pv = exp(-a);           /* = exp(-n * log1p(tmax / n)) bit for bit */
                if (pv < pc.cmin) pc.cmin = pv;
            }
            pc_line_end(&pc);
            continue;
        }
        if (lp < 0.0) lp = 0.0;                      /* pl = 1 */
        pc.ntested++;
        pc.fisher += lp;
        if (lp > best - 1e-9) {                      /* may hold the minimum: the exact form */
            double pl = exp(-a) * (double)pc.qt;
            if (pl > 1.0) pl = 1.0;
            if (pl < pc.pmin) pc.pmin = pl;
            if (lp > best) best = lp;
        }
        pc.qt = 0;
    }
    return pc_result(&pc, 0);
}

/* Level factor of the drift test's second, leave-one-out, trend test
 * (significant at this many times alpha; see msid_pstats_detect). */
#define MSID_PSTATS_DRIFT_LOO 5.0

/* Drift: p-value of a linear trend in the period number over the stored
 * periods [first, nhist) (none dropped yet); see msid_pstats_detect. */
static double trend_pvalue(const msid_pstats *ps, uint32_t first, uint32_t skip, const double *logj)
{
    const size_t L = ps->n_lines, q = ps->n_channels, nq = L * q;
    const uint32_t Kt = ps->nhist - first - (skip < ps->nhist - first ? 1u : 0u);   /* periods in the fit */
    double xm = 0.0;
    for (uint32_t k = 0; k < ps->nhist - first; ++k)
        if (k != skip) xm += (double)k;
    xm /= (double)Kt;
    const double n = (double)(Kt - 2u);
    double Sxx = 0.0;
    for (uint32_t k = 0; k < ps->nhist - first; ++k)
        if (k != skip) Sxx += ((double)k - xm) * ((double)k - xm);
    pcomb pc = {0.0, 1.0, 1.0, 0u, 0u};
    for (size_t l = 0; l < L; ++l) {
        for (size_t c = 0; c < q; ++c) {
            const size_t i = l * q + c;
            msid_cplx zm = msid__c(0.0, 0.0), sxz = msid__c(0.0, 0.0);
            for (uint32_t k = 0; k < ps->nhist - first; ++k)
                if (k != skip) zm = msid__cadd(zm, ps->hist[(size_t)(first + k) * nq + i]);
            zm = msid__cscale(zm, 1.0 / (double)Kt);
            double tss = 0.0;
            int real = 1;
            for (uint32_t k = 0; k < ps->nhist - first; ++k) {
                if (k == skip) continue;
                const msid_cplx z = ps->hist[(size_t)(first + k) * nq + i];
                const msid_cplx d = msid__csub(z, zm);
                if (z.im != 0.0) real = 0;
                tss += msid__cabs2(d);
                sxz = msid__cadd(sxz, msid__cscale(d, (double)k - xm));
            }
            const double ess = msid__cabs2(sxz) / Sxx;      /* |b|^2 Sxx */
            const double rss = tss - ess;
            const double floor_ = 1e-24 * (msid__cabs2(zm) + tss) + 1e-300;
            double pv;
            if (rss <= floor_) {
                if (ess <= floor_) continue;                 /* deterministic channel, constant */
                pv = 0.0;                                    /* deterministic channel, trending */
            } else {
                const double t = ess * n / rss;
                pv = real ? msid__f1_tail(t, Kt - 2u) : exp(-n * log1p(t / n));
            }
            pc_channel(&pc, pv);
        }
        pc_line_end(&pc);
    }
    return pc_result(&pc, logj);
}

/* The period of the late half [first, nhist) that departs most from the
 * straight line fitted through it: per line and channel the line z_k = a +
 * b (k - xm) and its residual sum of squares RSS; the period with the largest
 * sum of studentised squared residuals |r_k|^2 / ((1 - h_k) RSS), h_k = 1/Kt +
 * (k - xm)^2 / Sxx its leverage (an end period pulls the line towards itself;
 * the leverage undoes that). A drift leaves no period far from its line, a
 * disturbed period stands out. Its index from `first`; scratch ps->scr
 * (2 L q doubles of means, then wk: L q complex slopes and L q RSS). */
/* |z_k - a - b (k - xm)|^2 of channel i of late period k (the residual of its fitted line). */
static double line_res2(const msid_pstats *ps, uint32_t first, uint32_t k, size_t i, msid_cplx a, msid_cplx b, double xm)
{
    const size_t nq = (size_t)ps->n_lines * ps->n_channels;
    return msid__cabs2(msid__csub(msid__csub(ps->hist[(size_t)(first + k) * nq + i], a), msid__cscale(b, (double)k - xm)));
}

static uint32_t late_outlier(const msid_pstats *ps, uint32_t first, double *wk)
{
    const size_t nq = (size_t)ps->n_lines * ps->n_channels;
    const uint32_t Kt = ps->nhist - first;
    const double xm = 0.5 * (double)(Kt - 1u);
    double Sxx = 0.0;
    for (uint32_t k = 0; k < Kt; ++k) Sxx += ((double)k - xm) * ((double)k - xm);
    msid_cplx *zm = (msid_cplx *)ps->scr, *b = (msid_cplx *)wk;
    double *rss = wk + 2u * nq;
    for (size_t i = 0; i < nq; ++i) { zm[i] = msid__c(0.0, 0.0); b[i] = msid__c(0.0, 0.0); rss[i] = 0.0; }
    for (uint32_t k = 0; k < Kt; ++k)
        for (size_t i = 0; i < nq; ++i) {
            const msid_cplx z = ps->hist[(size_t)(first + k) * nq + i];
            zm[i] = msid__cadd(zm[i], z);
            b[i] = msid__cadd(b[i], msid__cscale(z, ((double)k - xm) / Sxx));
        }
    for (size_t i = 0; i < nq; ++i) zm[i] = msid__cscale(zm[i], 1.0 / (double)Kt);
    for (uint32_t k = 0; k < Kt; ++k)
        for (size_t i = 0; i < nq; ++i) rss[i] += line_res2(ps, first, k, i, zm[i], b[i], xm);
    uint32_t worst = 0;
    double wmax = -1.0;
    for (uint32_t k = 0; k < Kt; ++k) {
        const double h = 1.0 / (double)Kt + ((double)k - xm) * ((double)k - xm) / Sxx;
        double sc = 0.0;
        for (size_t i = 0; i < nq; ++i) {
            if (rss[i] > 0.0) sc += line_res2(ps, first, k, i, zm[i], b[i], xm) / rss[i];
        }
        sc /= 1.0 - h;
        if (sc > wmax) { wmax = sc; worst = k; }
    }
    return worst;
}

/* Two-pass mean and diagonal scatter over the kept history periods. */
static void kept_moments(const msid_pstats *ps, int flagged_out, msid_cplx *mean, double *m2d, uint32_t *K)
{
    const size_t L = ps->n_lines, q = ps->n_channels, n = L * q;
    uint32_t k = 0;
    for (size_t i = 0; i < n; ++i) { mean[i] = msid__c(0.0, 0.0); m2d[i] = 0.0; }
    for (uint32_t p = 0; p < ps->nhist; ++p) {
        if (ps->hdrop[p] || (flagged_out && ps->hflag[p])) continue;
        k++;
        const msid_cplx *z = ps->hist + (size_t)p * n;
        for (size_t i = 0; i < n; ++i) mean[i] = msid__cadd(mean[i], z[i]);
    }
    for (size_t i = 0; i < n; ++i) mean[i] = msid__cscale(mean[i], 1.0 / (double)k);
    for (uint32_t p = 0; p < ps->nhist; ++p) {
        if (ps->hdrop[p] || (flagged_out && ps->hflag[p])) continue;
        const msid_cplx *z = ps->hist + (size_t)p * n;
        for (size_t i = 0; i < n; ++i) m2d[i] += msid__cabs2(msid__csub(z[i], mean[i]));
    }
    *K = k;
}

/* Level of period k of K: alpha * (2^-(k+2) + 1/(2K)); sum over k < 1. */
static double period_level(double alpha, uint32_t k, uint32_t K)
{
    const double early = k < 60u ? ldexp(1.0, -(int)(k + 2u)) : 0.0;
    return alpha * (early + 0.5 / (double)K);
}

msid_status msid_pstats_detect(msid_pstats *ps)
{
    if (ps->transient == MSID_TRANSIENT_OFF) return MSID_OK;
    if (ps->nhist < 3) { ps->cnt.tested = 0; return MSID_OK; }
    /* Scratch (ps->scr, 5 L q doubles): kept means and diagonal scatter (the
     * drift test's robustness check: means, slopes and RSS of late_outlier),
     * first the log(j) table of the drift test. The Welford statistics are
     * left alone until a period is dropped. */
    msid_cplx *mean = (msid_cplx *)ps->scr;
    double *m2d = ps->scr + 2u * (size_t)ps->n_lines * ps->n_channels;
    double *logj = ps->scr;
    for (uint32_t j = 1; j < ps->n_lines; ++j) logj[j] = log((double)j);
    double logq[MSID_MAX_CHANNELS + 1];
    for (uint32_t j = 1; j <= ps->n_channels; ++j) logq[j] = log((double)j);
    const uint32_t K0 = ps->nhist;
    ps->cnt.tested = 1;
    /* A flag without a drop is the verdict of the last call only: every call
     * tests all kept periods afresh, so a period flagged by an earlier call
     * (a new segment since, or a drift then) neither stays out of the
     * sequential test's reference nor escapes DROP. Dropped periods stay out. */
    for (uint32_t p = 0; p < K0; ++p)
        if (ps->hflag[p] && !ps->hdrop[p]) { ps->hflag[p] = 0; ps->cnt.transient_flagged--; }
    /* Drift first: a trend that persists through the late half is no start-up
     * transient; then flag only, drop nothing. */
    msid_transient_mode mode = ps->transient;
    ps->cnt.drift_tested = 0;
    ps->cnt.drift = 0;
    ps->drift_pval = NAN;
    if (K0 >= 6u) {
        ps->drift_pval = trend_pvalue(ps, K0 / 2u, UINT32_MAX, logj);
        ps->cnt.drift_tested = 1;
        if (ps->drift_pval < ps->alpha && K0 - K0 / 2u >= 5u) {
            /* A trend must persist without the late period that departs most:
             * one disturbed period (a knock, a glitch) at an end of the late
             * half makes a straight line fit as well as a drift does. The
             * second test at MSID_PSTATS_DRIFT_LOO alpha (p1 / that factor
             * below alpha), the first at alpha: max(p, p1 / factor) is a
             * valid p-value, the false-alarm probability stays <= alpha, and
             * the power lost to the left-out period at 9-12 periods is
             * about halved against p1 < alpha (docs/statistics.md). */
            const uint32_t k = late_outlier(ps, K0 / 2u, ps->scr + 2u * (size_t)ps->n_lines * ps->n_channels);
            for (uint32_t j = 1; j < ps->n_lines; ++j) logj[j] = log((double)j);
            const double p1 = trend_pvalue(ps, K0 / 2u, k, logj) / MSID_PSTATS_DRIFT_LOO;
            if (p1 > ps->drift_pval) ps->drift_pval = p1;
        }
        if (ps->drift_pval < ps->alpha) { ps->cnt.drift = 1; mode = MSID_TRANSIENT_FLAG; }
    }
    /* Without drift both modes test sequentially: the most significant period
     * (relative to its level) leaves the reference and the rest are tested
     * again, so one large disturbance does not hide a start-up transient by
     * inflating the others' scatter. DROP drops what is flagged, FLAG keeps
     * it. With drift FLAG tests once against all periods. */
    const int sequential = !ps->cnt.drift;
    int dropped = 0;
    for (;;) {
        uint32_t K;
        kept_moments(ps, sequential, mean, m2d, &K);
        if (K < 3) break;
        /* Weighted Bonferroni over periods: transients sit at the start of a
         * record, so early periods get more of alpha; the weights sum to < 1. */
        double worst = HUGE_VAL;
        uint32_t wp = 0;
        for (uint32_t p = 0; p < ps->nhist; ++p) {
            if (ps->hdrop[p] || (sequential && ps->hflag[p])) continue;
            const double pv = period_pvalue(ps, p, mean, m2d, K, logq);
            ps->hpval[p] = pv;
            const double r = pv / period_level(ps->alpha, p, K0);
            if (r < worst) { worst = r; wp = p; }
        }
        if (!sequential) {
            for (uint32_t p = 0; p < ps->nhist; ++p)
                if (ps->hpval[p] < period_level(ps->alpha, p, K0) && !ps->hflag[p]) {
                    ps->hflag[p] = 1;
                    ps->cnt.transient_flagged++;
                }
            break;
        }
        if (!(worst < 1.0)) break;
        ps->hflag[wp] = 1;
        ps->cnt.transient_flagged++;
        if (mode == MSID_TRANSIENT_DROP) {
            ps->hdrop[wp] = 1;
            ps->cnt.transient_dropped++;
            dropped = 1;
        }
    }
    if (dropped) {
        /* Rebuild the Welford statistics from the kept periods, in order. */
        clear_stats(ps);
        const size_t n = (size_t)ps->n_lines * ps->n_channels;
        for (uint32_t p = 0; p < ps->nhist; ++p)
            if (!ps->hdrop[p]) welford(ps, ps->hist + (size_t)p * n);
        merge_beyond(ps);   /* the periods beyond the history, never tested, are kept */
    }
    /* Nothing dropped: mean, m2 and K are the Welford statistics of the
     * kept periods in order already (the streaming updates are the rebuild's,
     * line by line; tests/unit test_pstats checks the bits). */
    ps->cnt.used = ps->K;
    return MSID_OK;
}

void msid_pstats_new_segment(msid_pstats *ps) { ps->seg_skipped = 0; }

uint32_t msid_pstats_count(const msid_pstats *ps) { return ps->K; }

const msid_cplx *msid_pstats_mean(const msid_pstats *ps, uint32_t l)
{
    return l < ps->n_lines ? ps->mean + (size_t)l * ps->n_channels : 0;
}

const msid_cplx *msid_pstats_scatter(const msid_pstats *ps, uint32_t l)
{
    return l < ps->n_lines ? ps->m2 + (size_t)l * ps->n_channels * ps->n_channels : 0;
}

msid_pstats_counts msid_pstats_get_counts(const msid_pstats *ps) { return ps->cnt; }
uint32_t msid_pstats_history(const msid_pstats *ps) { return ps->nhist; }

uint32_t msid_pstats_period_number(const msid_pstats *ps, uint32_t k)
{
    return k < ps->nhist ? ps->hidx[k] : UINT32_MAX;
}

double msid_pstats_drift_pvalue(const msid_pstats *ps) { return ps->drift_pval; }

int msid_pstats_period_state(const msid_pstats *ps, uint32_t k, double *pval)
{
    if (k >= ps->nhist) return -1;
    if (pval) *pval = ps->hpval[k];
    if (ps->hdrop[k]) return 2;
    return ps->hflag[k] ? 1 : 0;
}
