/* Period statistics: Welford mean/scatter vs a two-pass long-double
 * computation, exact Hermitian scatter, skip / gap / non-finite accounting,
 * capacity, and the leave-one-out transient test (closed-form p-value,
 * DROP / FLAG behaviour, false-alarm rate on clean data). */
#include "unit_util.h"
#include "../../lib/src/msid_pvalue.h"
#include <float.h>

typedef struct {
    msid_pstats ps;
    void *mem;
} pst;

static msid_status ps_make(pst *o, uint32_t L, uint32_t q, uint32_t skip, uint32_t maxp, msid_transient_mode mode, double alpha)
{
    msid_pstats_cfg c = {L, q, skip, maxp, mode, alpha, 0};
    const size_t n = msid_pstats_mem_size(&c);
    o->mem = tsim_alloc(n);
    return msid_pstats_init(&o->ps, &c, o->mem, n);
}

/* Offer periods from..to-1 of z (L*q values each) with flags[p] (NULL: 0); each must return MSID_OK. */
static void ps_add_periods(pst *o, const msid_cplx *z, uint32_t from, uint32_t to, const uint32_t *flags)
{
    const size_t n = (size_t)o->ps.n_lines * o->ps.n_channels;
    for (uint32_t p = from; p < to; ++p) UT_STATUS(msid_pstats_add(&o->ps, z + p * n, flags ? flags[p] : 0), MSID_OK);
}

/* Random complex periods z[p][l*q + c]: offset mean + circular Gaussian noise. */
static msid_cplx *make_periods(uint32_t K, uint32_t L, uint32_t q, double offset, double sigma, msid_rng *r)
{
    msid_cplx *z = (msid_cplx *)malloc(sizeof(msid_cplx) * K * L * q);
    msid_cplx *mu = (msid_cplx *)malloc(sizeof(msid_cplx) * L * q);
    for (uint32_t k = 0; k < L * q; ++k) mu[k] = ut_c(offset * msid_rng_normal(r), offset * msid_rng_normal(r));
    for (uint32_t p = 0; p < K; ++p)
        for (uint32_t k = 0; k < L * q; ++k)
            z[(size_t)p * L * q + k] = ut_c(mu[k].re + sigma * msid_rng_normal(r), mu[k].im + sigma * msid_rng_normal(r));
    free(mu);
    return z;
}

/* A fresh trial on o: reset, offer K new periods (offset mean, unit noise) and detect.
 * Return values are not checked (the callers check the outcome). */
static void ps_trial(pst *o, uint32_t K, double offset, msid_rng *r)
{
    const uint32_t L = o->ps.n_lines, q = o->ps.n_channels;
    msid_pstats_reset(&o->ps);
    msid_cplx *z = make_periods(K, L, q, offset, 1.0, r);
    for (uint32_t p = 0; p < K; ++p) msid_pstats_add(&o->ps, z + (size_t)p * L * q, 0);
    msid_pstats_detect(&o->ps);
    free(z);
}

/* Two-pass long-double mean and scatter over the periods listed in use[]. */
static void check_against_two_pass(const msid_pstats *ps, const msid_cplx *z, const uint32_t *use, uint32_t nuse, double tol)
{
    const uint32_t L = ps->n_lines, q = ps->n_channels;
    UT_CHECK(msid_pstats_count(ps) == nuse, "K=%u want %u", msid_pstats_count(ps), nuse);
    for (uint32_t l = 0; l < L; ++l) {
        long double mr[MSID_MAX_CHANNELS] = {0}, mi[MSID_MAX_CHANNELS] = {0};
        for (uint32_t k = 0; k < nuse; ++k)
            for (uint32_t c = 0; c < q; ++c) {
                mr[c] += z[((size_t)use[k] * L + l) * q + c].re;
                mi[c] += z[((size_t)use[k] * L + l) * q + c].im;
            }
        const msid_cplx *mean = msid_pstats_mean(ps, l);
        long double mmax = 0.0L;
        for (uint32_t c = 0; c < q; ++c) { mr[c] /= nuse; mi[c] /= nuse; mmax = fmaxl(mmax, sqrtl(mr[c] * mr[c] + mi[c] * mi[c])); }
        for (uint32_t c = 0; c < q; ++c)
            UT_CHECK(fabsl(mean[c].re - mr[c]) <= tol * mmax && fabsl(mean[c].im - mi[c]) <= tol * mmax,
                     "line %u ch %u mean (%.17g, %.17g) vs (%.17Lg, %.17Lg)", l, c, mean[c].re, mean[c].im, mr[c], mi[c]);
        const msid_cplx *S = msid_pstats_scatter(ps, l);
        long double sr[MSID_MAX_CHANNELS * MSID_MAX_CHANNELS] = {0}, si[MSID_MAX_CHANNELS * MSID_MAX_CHANNELS] = {0};
        long double smax = 0.0L;
        for (uint32_t k = 0; k < nuse; ++k)
            for (uint32_t a = 0; a < q; ++a)
                for (uint32_t b = 0; b < q; ++b) {
                    const msid_cplx za = z[((size_t)use[k] * L + l) * q + a], zb = z[((size_t)use[k] * L + l) * q + b];
                    const long double ar = za.re - mr[a], ai = za.im - mi[a], br = zb.re - mr[b], bi = zb.im - mi[b];
                    sr[a * q + b] += ar * br + ai * bi;    /* (z_a - m_a) conj(z_b - m_b) */
                    si[a * q + b] += ai * br - ar * bi;
                }
        for (uint32_t k = 0; k < q * q; ++k) smax = fmaxl(smax, sqrtl(sr[k] * sr[k] + si[k] * si[k]));
        for (uint32_t k = 0; k < q * q; ++k)
            UT_CHECK(fabsl(S[k].re - sr[k]) <= tol * smax && fabsl(S[k].im - si[k]) <= tol * smax,
                     "line %u entry %u scatter (%.17g, %.17g) vs (%.17Lg, %.17Lg)", l, k, S[k].re, S[k].im, sr[k], si[k]);
    }
}

static void check_hermitian(const msid_pstats *ps)
{
    const uint32_t q = ps->n_channels;
    for (uint32_t l = 0; l < ps->n_lines; ++l) {
        const msid_cplx *S = msid_pstats_scatter(ps, l);
        for (uint32_t a = 0; a < q; ++a) {
            UT_CHECK(S[a * q + a].im == 0.0 && S[a * q + a].re >= 0.0, "line %u diag %u (%g, %g)", l, a, S[a * q + a].re, S[a * q + a].im);
            for (uint32_t b = 0; b < a; ++b)
                UT_CHECK(S[a * q + b].re == S[b * q + a].re && S[a * q + b].im == -S[b * q + a].im, "line %u (%u,%u)", l, a, b);
        }
    }
}

static void test_welford_vs_two_pass(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 123u);
    const uint32_t K = 20, L = 4, q = 3;
    const double offsets[] = {0.0, 1.0, 1e3};
    for (int k = 0; k < 3; ++k) {
        msid_cplx *z = make_periods(K, L, q, offsets[k], 1.0, &r);
        pst o;
        UT_STATUS(ps_make(&o, L, q, 0, 0, MSID_TRANSIENT_OFF, 0.0), MSID_OK);
        uint32_t use[20];
        for (uint32_t p = 0; p < K; ++p) {
            UT_STATUS(msid_pstats_add(&o.ps, z + (size_t)p * L * q, 0), MSID_OK);
            use[p] = p;
            if (p >= 1) check_against_two_pass(&o.ps, z, use, p + 1, 1e-12);
            check_hermitian(&o.ps);
        }
        const msid_pstats_counts n = msid_pstats_get_counts(&o.ps);
        UT_CHECK(n.offered == K && n.used == K && n.skipped == 0 && n.gap == 0 && n.nonfinite == 0 && n.tested == 0, "used %u", n.used);
        UT_CHECK(msid_pstats_mean(&o.ps, L) == NULL && msid_pstats_scatter(&o.ps, L) == NULL, "%d", 0);
        /* reset forgets everything */
        msid_pstats_reset(&o.ps);
        const msid_pstats_counts z0 = msid_pstats_get_counts(&o.ps);
        UT_CHECK(msid_pstats_count(&o.ps) == 0 && z0.offered == 0 && z0.used == 0 && msid_pstats_mean(&o.ps, 0)[0].re == 0.0, "%d", 0);
        tsim_free(o.mem);
        free(z);
    }
}

static void test_skip_gap_nonfinite(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 321u);
    const uint32_t K = 12, L = 3, q = 2;
    msid_cplx *z = make_periods(K, L, q, 2.0, 1.0, &r);
    /* flags: gaps/non-finite before, between and after the skipped periods */
    const uint32_t fl[12] = {MSID_PERIOD_GAP, 0, MSID_PERIOD_NONFINITE, 0, MSID_PERIOD_GAP | MSID_PERIOD_NONFINITE, 0, 0,
                             MSID_PERIOD_GAP, 0, 0, MSID_PERIOD_NONFINITE, 0};
    for (int hist = 0; hist < 2; ++hist) {
        pst o;
        UT_STATUS(ps_make(&o, L, q, 3, hist ? 16 : 0, MSID_TRANSIENT_OFF, 0.0), MSID_OK);
        ps_add_periods(&o, z, 0, K, fl);
        /* valid periods: 1, 3, 5 (skipped), 6, 8, 9, 11 (used) */
        const uint32_t use[] = {6, 8, 9, 11};
        check_against_two_pass(&o.ps, z, use, 4, 1e-12);
        const msid_pstats_counts n = msid_pstats_get_counts(&o.ps);
        UT_CHECK(n.offered == 12 && n.skipped == 3 && n.gap == 3 && n.nonfinite == 2 && n.used == 4,
                 "offered %u skipped %u gap %u nonfinite %u used %u", n.offered, n.skipped, n.gap, n.nonfinite, n.used);
        UT_CHECK(msid_pstats_history(&o.ps) == (hist ? 4u : 0u), "history %u", msid_pstats_history(&o.ps));
        /* a new segment skips 3 valid periods again; statistics and counters are kept */
        msid_pstats_new_segment(&o.ps);
        ps_add_periods(&o, z, 0, K, fl);
        const uint32_t use2[] = {6, 8, 9, 11, 6, 8, 9, 11};
        check_against_two_pass(&o.ps, z, use2, 8, 1e-12);
        const msid_pstats_counts n2 = msid_pstats_get_counts(&o.ps);
        UT_CHECK(n2.offered == 24 && n2.skipped == 6 && n2.gap == 6 && n2.nonfinite == 4 && n2.used == 8, "skipped %u used %u", n2.skipped, n2.used);
        tsim_free(o.mem);
    }
    free(z);
}

static void test_capacity(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 99u);
    const uint32_t L = 2, q = 2;
    msid_cplx *z = make_periods(8, L, q, 1.0, 1.0, &r);
    pst o;
    UT_STATUS(ps_make(&o, L, q, 1, 5, MSID_TRANSIENT_FLAG, 0.01), MSID_OK);
    UT_STATUS(msid_pstats_add(&o.ps, z, 0), MSID_OK);                 /* skipped: not stored */
    UT_STATUS(msid_pstats_add(&o.ps, z + 1 * L * q, MSID_PERIOD_GAP), MSID_OK);  /* gap: not stored */
    ps_add_periods(&o, z, 2, 7, NULL);
    UT_STATUS(msid_pstats_add(&o.ps, z + 7 * L * q, 0), MSID_E_CAPACITY);
    const uint32_t use[] = {2, 3, 4, 5, 6};
    check_against_two_pass(&o.ps, z, use, 5, 1e-12);
    const msid_pstats_counts n = msid_pstats_get_counts(&o.ps);
    UT_CHECK(n.used == 5 && msid_pstats_history(&o.ps) == 5 && n.offered == 7, "used %u offered %u", n.used, n.offered);
    /* no history: no capacity limit */
    pst u;
    UT_STATUS(ps_make(&u, L, q, 0, 0, MSID_TRANSIENT_OFF, 0.0), MSID_OK);
    for (int k = 0; k < 200; ++k) UT_STATUS(msid_pstats_add(&u.ps, z + (size_t)(k % 8) * L * q, 0), MSID_OK);
    UT_CHECK(msid_pstats_count(&u.ps) == 200 && msid_pstats_history(&u.ps) == 0, "%u", msid_pstats_count(&u.ps));
    UT_CHECK(msid_pstats_period_state(&u.ps, 0, NULL) == -1 && msid_pstats_period_state(&o.ps, 5, NULL) == -1, "%d", 0);
    tsim_free(o.mem);
    tsim_free(u.mem);
    free(z);
}

/* beyond_history: with the history full, later periods go into the statistics untested. Before the
 * test the statistics are the bits of a history that holds every period; FLAG keeps them; the test
 * covers the first max_periods (it flags the start-up transient of period 0). DROP rebuilds from the
 * kept history merged with the later periods: the two-pass statistics of the kept periods. */
static void test_beyond_history(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 7u);
    const uint32_t L = 3, q = 2, K = 40, H = 10;
    msid_cplx *z = make_periods(K, L, q, 1.0, 1.0, &r);
    for (uint32_t k = 0; k < L * q; ++k) z[k].re += 40.0;   /* a start-up transient in period 0 */
    for (int mode = MSID_TRANSIENT_FLAG; mode <= MSID_TRANSIENT_DROP; ++mode) {
        pst a, full;
        msid_pstats_cfg c = {L, q, 0, H, (msid_transient_mode)mode, 0.01, 1};
        const size_t n = msid_pstats_mem_size(&c);
        msid_pstats_cfg c0 = c;
        c0.beyond_history = 0;
        UT_CHECK(n > msid_pstats_mem_size(&c0), "mem %zu", n);   /* the later periods' own moments */
        a.mem = tsim_alloc(n);
        UT_STATUS(msid_pstats_init(&a.ps, &c, a.mem, n), MSID_OK);
        UT_STATUS(ps_make(&full, L, q, 0, K, (msid_transient_mode)mode, 0.01), MSID_OK);
        ps_add_periods(&a, z, 0, K, NULL);
        ps_add_periods(&full, z, 0, K, NULL);
        msid_pstats_counts ca = msid_pstats_get_counts(&a.ps);
        UT_CHECK(ca.untested == K - H && ca.used == K && msid_pstats_history(&a.ps) == H, "untested %u used %u",
                 ca.untested, ca.used);
        for (uint32_t l = 0; l < L; ++l) {
            UT_CHECK(!memcmp(msid_pstats_mean(&a.ps, l), msid_pstats_mean(&full.ps, l), q * sizeof(msid_cplx)), "mean %u", l);
            UT_CHECK(!memcmp(msid_pstats_scatter(&a.ps, l), msid_pstats_scatter(&full.ps, l), q * q * sizeof(msid_cplx)),
                     "scatter %u", l);
        }
        UT_STATUS(msid_pstats_detect(&a.ps), MSID_OK);
        ca = msid_pstats_get_counts(&a.ps);
        UT_CHECK(msid_pstats_period_state(&a.ps, 0, NULL) >= 1 && ca.transient_flagged == 1, "flagged %u",
                 ca.transient_flagged);
        if (mode == MSID_TRANSIENT_FLAG) {
            UT_STATUS(msid_pstats_detect(&full.ps), MSID_OK);
            for (uint32_t l = 0; l < L; ++l)
                UT_CHECK(!memcmp(msid_pstats_mean(&a.ps, l), msid_pstats_mean(&full.ps, l), q * sizeof(msid_cplx)),
                         "FLAG keeps the bits, line %u", l);
            UT_CHECK(ca.used == K, "used %u", ca.used);
        } else {
            uint32_t use[40];
            for (uint32_t p = 1; p < K; ++p) use[p - 1] = p;
            UT_CHECK(ca.used == K - 1 && ca.transient_dropped == 1 && msid_pstats_period_state(&a.ps, 0, NULL) == 2,
                     "used %u dropped %u", ca.used, ca.transient_dropped);
            check_against_two_pass(&a.ps, z, use, K - 1, 1e-12);
        }
        tsim_free(a.mem);
        tsim_free(full.mem);
    }
    free(z);
}

static void test_init_errors(void **state)
{
    (void)state;
    msid_pstats ps;
    msid_pstats_cfg c = {4, 3, 0, 10, MSID_TRANSIENT_DROP, 0.01, 0};
    const size_t need = msid_pstats_mem_size(&c);
    msid_pstats_cfg c0 = c;
    c0.max_periods = 0;
    c0.transient = MSID_TRANSIENT_OFF;
    /* the history holds max_periods * L * q complex values */
    UT_CHECK(msid_pstats_mem_size(&c0) > 0 && need >= msid_pstats_mem_size(&c0) + (size_t)10 * 12 * 16, "mem %zu vs %zu", need,
             msid_pstats_mem_size(&c0));
    unsigned char *mem = (unsigned char *)tsim_alloc(need + 64);
    UT_STATUS(msid_pstats_init(NULL, &c, mem, need), MSID_E_NULL);
    UT_STATUS(msid_pstats_init(&ps, NULL, mem, need), MSID_E_NULL);
    UT_STATUS(msid_pstats_init(&ps, &c, NULL, need), MSID_E_NULL);
    UT_STATUS(msid_pstats_init(&ps, &c, ut_misalign(mem), need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_pstats_init(&ps, &c, mem, need - 1), MSID_E_MEM_SIZE);
    UT_STATUS(msid_pstats_init(&ps, &c, mem + 64, need), MSID_OK);
    UT_CHECK(ps.alpha == 0.01, "%g", ps.alpha);
    msid_pstats_cfg e = c;
    e.n_lines = 0;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_E_NO_LINES);
    e = c; e.n_channels = 0;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_E_DIMS);
    e = c; e.n_channels = MSID_MAX_CHANNELS + 1u;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_E_DIMS);
    UT_CHECK(msid_pstats_mem_size(&e) == 0 && msid_pstats_mem_size(NULL) == 0, "%d", 0);
    e = c; e.max_periods = 2;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_E_ARG);
    e.transient = MSID_TRANSIENT_FLAG;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_E_ARG);
    e.transient = MSID_TRANSIENT_OFF;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_OK);
    e = c; e.transient = (msid_transient_mode)3;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_E_ARG);
    const double bad_alpha[] = {1.0, 1.5, -0.1, NAN};
    for (int k = 0; k < 4; ++k) {
        e = c;
        e.alpha = bad_alpha[k];
        UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_E_ARG);
    }
    e = c; e.alpha = 0.0;
    UT_STATUS(msid_pstats_init(&ps, &e, mem, need), MSID_OK);
    UT_CHECK(ps.alpha == 0.01, "default alpha %g", ps.alpha);
    tsim_free(mem);
}

/* ---------- transient test ---------- */

/* Documented level of period k (acceptance order) of K: alpha (2^-(k+2) + 1/(2K)). */
static double level(double alpha, uint32_t k, uint32_t K)
{
    return alpha * (ldexp(1.0, -(int)(k + 2)) + 0.5 / K);
}

/* Closed form for L = 1, q = 1: leave-one-out t ~ F(2, 2(K-2)), p = (1 + t/n)^-n,
 * and the Fisher/Bonferroni combination of a single value gives min(1, 2p). */
static void test_transient_pvalue_closed_form(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 555u);
    for (uint32_t K = 3; K <= 12; ++K) {
        msid_cplx *z = make_periods(K, 1, 1, 3.0, 1.0, &r);
        pst o;
        UT_STATUS(ps_make(&o, 1, 1, 0, K, MSID_TRANSIENT_FLAG, 1e-9), MSID_OK);
        ps_add_periods(&o, z, 0, K, NULL);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        UT_CHECK(msid_pstats_get_counts(&o.ps).tested == 1, "K=%u", K);
        for (uint32_t p = 0; p < K; ++p) {
            long double mr = 0.0L, mi = 0.0L;
            for (uint32_t j = 0; j < K; ++j) if (j != p) { mr += z[j].re; mi += z[j].im; }
            mr /= (K - 1); mi /= (K - 1);
            long double s2 = 0.0L;
            for (uint32_t j = 0; j < K; ++j) if (j != p) s2 += (z[j].re - mr) * (z[j].re - mr) + (z[j].im - mi) * (z[j].im - mi);
            const long double n = K - 2;
            s2 /= n;
            const long double d2 = (z[p].re - mr) * (z[p].re - mr) + (z[p].im - mi) * (z[p].im - mi);
            const long double t = d2 / (s2 * (1.0L + 1.0L / (K - 1)));
            const long double pl = powl(1.0L + t / n, -n);
            const double want = (double)fminl(1.0L, 2.0L * pl);
            double got;
            const int st = msid_pstats_period_state(&o.ps, p, &got);
            UT_CHECK(st == 0 && fabs(got - want) <= 1e-9 * want + 1e-300, "K=%u period %u: p %.17g want %.17g (state %d)", K, p, got, want, st);
        }
        tsim_free(o.mem);
        free(z);
    }
    /* fewer than 3 periods: not tested, p-values NaN */
    pst o;
    msid_cplx z2[2] = {{1, 0}, {2, 0}};
    UT_STATUS(ps_make(&o, 1, 1, 0, 4, MSID_TRANSIENT_DROP, 0.01), MSID_OK);
    msid_pstats_add(&o.ps, z2, 0);
    msid_pstats_add(&o.ps, z2 + 1, 0);
    UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
    double pv = 0.0;
    UT_CHECK(msid_pstats_get_counts(&o.ps).tested == 0 && msid_pstats_period_state(&o.ps, 0, &pv) == 0 && isnan(pv) &&
             msid_pstats_count(&o.ps) == 2, "%d", 0);
    tsim_free(o.mem);
}

static void test_transient_drop(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 1234u);
    const uint32_t K = 10, L = 20, q = 2;
    for (int trial = 0; trial < 5; ++trial) {
        msid_cplx *z = make_periods(K, L, q, 5.0, 1.0, &r);
        for (uint32_t k = 0; k < L * q; ++k) { z[k].re += 6.0; z[k].im -= 4.0; }  /* a plant transient in period 0 */
        pst o, ref;
        UT_STATUS(ps_make(&o, L, q, 0, K, MSID_TRANSIENT_DROP, 0.01), MSID_OK);
        UT_STATUS(ps_make(&ref, L, q, 0, 0, MSID_TRANSIENT_OFF, 0.0), MSID_OK);
        ps_add_periods(&o, z, 0, K, NULL);
        ps_add_periods(&ref, z, 1, K, NULL);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        double pv;
        UT_CHECK(msid_pstats_period_state(&o.ps, 0, &pv) == 2 && pv < level(0.01, 0, K), "trial %d: period 0 state %d p %.3g", trial,
                 msid_pstats_period_state(&o.ps, 0, NULL), pv);
        for (uint32_t p = 1; p < K; ++p)
            UT_CHECK(msid_pstats_period_state(&o.ps, p, &pv) == 0 && pv >= level(0.01, p, K), "trial %d period %u p %.3g", trial, p, pv);
        const msid_pstats_counts n = msid_pstats_get_counts(&o.ps);
        UT_CHECK(n.tested == 1 && n.transient_flagged == 1 && n.transient_dropped == 1 && n.used == K - 1 && msid_pstats_count(&o.ps) == K - 1,
                 "flagged %u dropped %u used %u", n.transient_flagged, n.transient_dropped, n.used);
        const uint32_t use[] = {1, 2, 3, 4, 5, 6, 7, 8, 9};
        check_against_two_pass(&o.ps, z, use, K - 1, 1e-12);
        check_hermitian(&o.ps);
        for (uint32_t l = 0; l < L; ++l) {
            UT_CHECK(memcmp(msid_pstats_mean(&o.ps, l), msid_pstats_mean(&ref.ps, l), q * sizeof(msid_cplx)) == 0, "mean line %u", l);
            UT_CHECK(memcmp(msid_pstats_scatter(&o.ps, l), msid_pstats_scatter(&ref.ps, l), q * q * sizeof(msid_cplx)) == 0, "scatter line %u", l);
        }
        tsim_free(o.mem);
        tsim_free(ref.mem);
        free(z);
    }
}

static void test_transient_flag_keeps_stats(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 4321u);
    const uint32_t K = 10, L = 20, q = 2;
    msid_cplx *z = make_periods(K, L, q, 5.0, 1.0, &r);
    for (uint32_t k = 0; k < L * q; ++k) z[k].re += 8.0;
    pst o;
    UT_STATUS(ps_make(&o, L, q, 0, K, MSID_TRANSIENT_FLAG, 0.01), MSID_OK);
    ps_add_periods(&o, z, 0, K, NULL);
    msid_cplx *mean0 = (msid_cplx *)malloc(sizeof(msid_cplx) * L * q), *m20 = (msid_cplx *)malloc(sizeof(msid_cplx) * L * q * q);
    memcpy(mean0, o.ps.mean, sizeof(msid_cplx) * L * q);
    memcpy(m20, o.ps.m2, sizeof(msid_cplx) * L * q * q);
    UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
    UT_CHECK(msid_pstats_period_state(&o.ps, 0, NULL) == 1, "state %d", msid_pstats_period_state(&o.ps, 0, NULL));
    const msid_pstats_counts n = msid_pstats_get_counts(&o.ps);
    UT_CHECK(n.transient_flagged >= 1 && n.transient_dropped == 0 && n.used == K && msid_pstats_count(&o.ps) == K, "used %u", n.used);
    UT_CHECK(memcmp(mean0, o.ps.mean, sizeof(msid_cplx) * L * q) == 0 && memcmp(m20, o.ps.m2, sizeof(msid_cplx) * L * q * q) == 0,
             "%s", "FLAG mode changed the statistics");
    /* detecting again does not count the same period twice */
    UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
    UT_CHECK(msid_pstats_get_counts(&o.ps).transient_flagged == n.transient_flagged, "%u", msid_pstats_get_counts(&o.ps).transient_flagged);
    /* OFF mode: detect is a no-op */
    pst off;
    UT_STATUS(ps_make(&off, L, q, 0, K, MSID_TRANSIENT_OFF, 0.0), MSID_OK);
    for (uint32_t p = 0; p < K; ++p) msid_pstats_add(&off.ps, z + (size_t)p * L * q, 0);
    UT_STATUS(msid_pstats_detect(&off.ps), MSID_OK);
    UT_CHECK(msid_pstats_get_counts(&off.ps).tested == 0 && msid_pstats_period_state(&off.ps, 0, NULL) == 0, "%d", 0);
    UT_CHECK(memcmp(mean0, off.ps.mean, sizeof(msid_cplx) * L * q) == 0, "%d", 0);
    tsim_free(o.mem);
    tsim_free(off.mem);
    free(mean0);
    free(m20);
    free(z);
}

/* FLAG mode: a period is flagged exactly when its p-value is below its level. */
static void test_transient_flag_levels(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 6060u);
    const uint32_t K = 8, L = 3, q = 1;
    const double alpha = 0.6;
    pst o;
    UT_STATUS(ps_make(&o, L, q, 0, K, MSID_TRANSIENT_FLAG, alpha), MSID_OK);
    uint32_t nflag = 0, nkeep = 0;
    for (int t = 0; t < 300; ++t) {
        ps_trial(&o, K, 1.0, &r);
        uint32_t flagged = 0;
        for (uint32_t p = 0; p < K; ++p) {
            double pv;
            const int st = msid_pstats_period_state(&o.ps, p, &pv);
            const int want = pv < level(alpha, p, K);
            UT_CHECK(st == want && pv >= 0.0 && pv <= 1.0, "trial %d period %u: state %d, p %.4g, level %.4g", t, p, st, pv, level(alpha, p, K));
            flagged += (uint32_t)want;
            nflag += (uint32_t)want;
            nkeep += (uint32_t)!want;
        }
        UT_CHECK(msid_pstats_get_counts(&o.ps).transient_flagged == flagged && msid_pstats_count(&o.ps) == K, "trial %d", t);
    }
    UT_CHECK(nflag > 20 && nkeep > 20, "both outcomes exercised: %u flagged, %u kept", nflag, nkeep);
    tsim_free(o.mem);
}

static void test_transient_false_alarm_rate(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 2025u);
    const uint32_t N = 500, K = 10, L = 20, q = 2;
    const double alpha = 0.05;
    pst o;
    UT_STATUS(ps_make(&o, L, q, 0, K, MSID_TRANSIENT_DROP, alpha), MSID_OK);
    uint32_t any = 0;
    for (uint32_t t = 0; t < N; ++t) {
        ps_trial(&o, K, 3.0, &r);
        any += msid_pstats_get_counts(&o.ps).transient_flagged > 0;
    }
    const double frac = (double)any / N, bound = alpha + 4.0 * sqrt(alpha * (1 - alpha) / N);
    print_message("transient false alarms: %u of %u experiments (bound %.3f)\n", any, N, bound);
    UT_CHECK(frac <= bound, "false alarms in %.3f of experiments (bound %.3f)", frac, bound);
    tsim_free(o.mem);
}

/* period_pvalue evaluates P(F(2, 2n) > t) = exp(-n log1p(t/n)) once per line,
 * at the largest statistic of its complex channels, instead of per channel and
 * taking the minimum. Same bits only if the computed function is
 * non-increasing in t: checked here on this libm for n = 1..300, statistics
 * spread over 1e-6..1e4 and neighbours one ulp apart. Negative control: the
 * wrong choice (the smallest statistic) must give a different minimum. */
static void test_transient_line_max_same_bits(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 77u);
    uint32_t bad = 0, control = 0, N = 0;
    for (uint32_t k = 0; k < 60000u; ++k) {
        const double n = (double)(1u + msid_rng_u64(&r) % 300u);
        double t[4];
        t[0] = pow(10.0, -6.0 + 10.0 * msid_rng_uniform(&r));
        for (int c = 1; c < 4; ++c)
            t[c] = (k & 1u) ? nextafter(t[c - 1], (msid_rng_u64(&r) & 1u) ? HUGE_VAL : 0.0)
                            : t[0] * (0.5 + msid_rng_uniform(&r));
        double mn = HUGE_VAL, tmax = -1.0, tmin = HUGE_VAL;
        for (int c = 0; c < 4; ++c) {
            const double pv = exp(-n * log1p(t[c] / n));
            if (pv < mn) mn = pv;
            if (t[c] > tmax) tmax = t[c];
            if (t[c] < tmin) tmin = t[c];
        }
        bad += exp(-n * log1p(tmax / n)) != mn;
        control += exp(-n * log1p(tmin / n)) != mn;
        ++N;
    }
    print_message("line maximum vs channel minimum: %u of %u differ (control: %u)\n", bad, N, control);
    UT_CHECK(bad == 0, "%u of %u lines differ", bad, N);
    UT_CHECK(control > N / 4, "negative control found only %u differences", control);
}

/* ---------- the log-domain evaluation of the period p-values ---------- */

/* Reference Gamma(n, 1) upper tail in long double: exp(-S) sum_{j<n} S^j / j!,
 * every term in the log domain with long-double logs (on targets where long
 * double is double this is the double log-domain form). */
static long double gamma_upper_ref(uint32_t n, long double S)
{
    if (!(S > 0.0L)) return 1.0L;
    const long double lS = logl(S);
    long double lt = -S, mx = -S, lf = 0.0L;
    for (uint32_t j = 1; j < n; ++j) {
        lf += logl((long double)j);
        lt = -S + j * lS - lf;
        if (lt > mx) mx = lt;
    }
    long double sum = 0.0L;
    lf = 0.0L;
    for (uint32_t j = 0; j < n; ++j) {
        if (j) lf += logl((long double)j);
        sum += expl(-S + j * lS - lf - mx);
    }
    const long double q = expl(mx + logl(sum));
    return q > 1.0L ? 1.0L : q;
}

/* The ratio-recurrence Gamma tail (transient test) against the log-domain form
 * it replaced (kept for the drift test), a long-double reference and closed
 * forms, over n = 1..2000 and S from 1e-3 to where Q underflows. Relative
 * errors are measured where Q > 1e-290. Negative control: the tail at n - 1
 * (the classic off-by-one of this sum) must miss by far more than the bound
 * wherever Q < 1/2. */
static void test_gamma_tail_accuracy(void **state)
{
    (void)state;
    static const uint32_t ns[] = {1, 2, 3, 4, 7, 10, 31, 64, 100, 200, 513, 2000};
    const int long_ref = LDBL_MANT_DIG > 53;
    static double logj[2001];
    for (uint32_t j = 1; j <= 2000; ++j) logj[j] = log((double)j);
    double e_old = 0.0, e_new = 0.0, e_ref_old = 0.0;
    uint32_t N = 0, control = 0, cpts = 0;
    for (size_t k = 0; k < sizeof ns / sizeof ns[0]; ++k) {
        const uint32_t n = ns[k];
        /* measured on x86-64 (glibc): recurrence vs long double <= 3.7e-15 at n = 200, 2.1e-14 at
         * n = 2000 (about 1e-17 n); the log-domain form <= 1.1e-12 and 8e-12 */
        const double tol_ref = 2e-15 + 2e-17 * n, tol_old = 1e-12 + 1e-14 * n;
        double en = 0.0, eo = 0.0, er = 0.0;
        for (int i = 0; i <= 300; ++i) {
            /* S from 1e-3 to n + 40 sqrt(n) + 700, log-spaced, some of them integers */
            const double top = n + 40.0 * sqrt((double)n) + 700.0;
            double S = 1e-3 * pow(top / 1e-3, i / 300.0);
            if (i % 50 == 7) S = floor(S) + 0.0;
            const double qn = msid__gamma_upper(n, S), qo = msid__gamma_upper_log(n, S, logj);
            UT_CHECK(qn >= 0.0 && qn <= 1.0, "n %u S %.17g: Q %.17g", n, S, qn);
            if (n == 1 && S < 660.0) UT_CHECK(fabs(qn - exp(-S)) <= 4e-16 * exp(-S), "n 1 S %.17g: %.17g vs %.17g", S, qn, exp(-S));
            if (n == 2 && S < 660.0) {
                const double w = exp(-S) * (1.0 + S);
                UT_CHECK(fabs(qn - w) <= 8e-16 * w, "n 2 S %.17g: %.17g vs %.17g", S, qn, w);
            }
            if (qo > 1e-290) {
                const double d = fabs(qn - qo) / qo;
                if (d > eo) eo = d;
                if (n > 1 && qo < 0.5) {
                    ++cpts;
                    control += fabs(msid__gamma_upper(n - 1, S) - qn) > 1e3 * tol_ref * qn;
                }
                ++N;
                if (long_ref) {
                    const long double r = gamma_upper_ref(n, S);
                    const double dn = (double)(fabsl(qn - r) / r), dr = (double)(fabsl(qo - r) / r);
                    if (dn > en) en = dn;
                    if (dr > er) er = dr;
                }
            }
        }
        UT_CHECK(eo <= tol_old, "n %u: recurrence vs log-domain form: relative %.3g (bound %.3g)", n, eo, tol_old);
        if (long_ref) UT_CHECK(en <= tol_ref, "n %u: recurrence vs long double: relative %.3g (bound %.3g)", n, en, tol_ref);
        if (eo > e_old) e_old = eo;
        if (en > e_new) e_new = en;
        if (er > e_ref_old) e_ref_old = er;
    }
    print_message("Gamma tail, %u points, n <= 2000: recurrence vs log-domain form %.2e; vs long double: recurrence %.2e, "
                  "log-domain form %.2e\n", N, e_old, e_new, e_ref_old);
    UT_CHECK(cpts > 500 && control == cpts, "negative control: the tail at n - 1 differs at only %u of %u points", control, cpts);
    /* S <= 0, NaN: 1 */
    UT_CHECK(msid__gamma_upper(5, 0.0) == 1.0 && msid__gamma_upper(5, -1.0) == 1.0 && msid__gamma_upper(5, NAN) == 1.0, "%d", 0);
}

/* A line's Fisher term in the log domain, max(0, n log1p(t/n) - log qt),
 * against the form it replaced, -log(min(1, qt exp(-n log1p(t/n)))), for
 * n = 1..300, t over 1e-6..1e4 and qt = 1..4 (terms up to the 700 where the
 * exact form takes over). Negative control: without the log qt the terms
 * differ. */
static void test_line_term_log_domain(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 4242u);
    double worst = 0.0;
    uint32_t N = 0, control = 0;
    for (uint32_t k = 0; k < 50000u; ++k) {
        const double n = (double)(1u + msid_rng_u64(&r) % 300u), qt = (double)(1u + msid_rng_u64(&r) % 4u);
        const double t = pow(10.0, -6.0 + 10.0 * msid_rng_uniform(&r));
        const double a = n * log1p(t / n);
        double lp = a - log(qt);
        if (lp > 700.0) continue;
        if (lp < 0.0) lp = 0.0;
        double pl = qt * exp(-n * log1p(t / n));
        if (pl > 1.0) pl = 1.0;
        const double old = pl > 0.0 ? -log(pl) : 745.0;
        const double d = fabs(lp - old) / (old > 1.0 ? old : 1.0);
        if (d > worst) worst = d;
        control += qt > 1.0 && fabs(((a < 0.0) ? 0.0 : a) - old) > 1e-6;
        ++N;
    }
    print_message("line term, %u points: log domain vs exp/log form, %.2e (relative, absolute below 1)\n", N, worst);
    UT_CHECK(worst <= 2e-15, "log-domain line term off by %.3g", worst);
    UT_CHECK(control > N / 2, "negative control: %u of %u", control, N);
}

/* Period p-values of the library against an independent long-double
 * evaluation of the documented test (leave-one-out F(2, 2n) statistics,
 * Bonferroni over channels, Fisher sum and Bonferroni minimum over lines),
 * with periods that carry a transient so both small and large p-values occur. */
static void test_transient_pvalue_reference(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 8080u);
    const uint32_t K = 9, L = 25, q = 3;
    double worst = 0.0;
    uint32_t small = 0, flagged = 0;
    for (int trial = 0; trial < 40; ++trial) {
        msid_cplx *z = make_periods(K, L, q, 4.0, 1.0, &r);
        const double bump = 0.3 * (trial % 8);
        for (uint32_t k = 0; k < L * q; ++k) { z[k].re += bump * msid_rng_normal(&r); z[k].im += bump; }
        pst o;
        UT_STATUS(ps_make(&o, L, q, 0, K, MSID_TRANSIENT_FLAG, 0.01), MSID_OK);
        ps_add_periods(&o, z, 0, K, NULL);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        /* the documented sequential test: every period against the periods not yet flagged;
         * the most significant (p over its level) is flagged while below its level, and keeps
         * the p-value it was flagged with */
        int out[9] = {0};
        long double want[9];
        for (;;) {
            uint32_t Ke = 0;
            for (uint32_t j = 0; j < K; ++j) Ke += !out[j];
            if (Ke < 3) break;
            const long double n = Ke - 2;
            long double worst_r = 1e300L;
            uint32_t wp = 0;
            for (uint32_t p = 0; p < K; ++p) {
                if (out[p]) continue;
                long double fisher = 0.0L, pmin = 1.0L;
                uint32_t nt = 0;
                for (uint32_t l = 0; l < L; ++l) {
                    long double cmin = 1.0L;
                    for (uint32_t c = 0; c < q; ++c) {
                        long double mr = 0.0L, mi = 0.0L, s2 = 0.0L;
                        for (uint32_t j = 0; j < K; ++j)
                            if (j != p && !out[j]) { mr += z[((size_t)j * L + l) * q + c].re; mi += z[((size_t)j * L + l) * q + c].im; }
                        mr /= (Ke - 1); mi /= (Ke - 1);
                        for (uint32_t j = 0; j < K; ++j)
                            if (j != p && !out[j]) {
                                const long double dr = z[((size_t)j * L + l) * q + c].re - mr, di = z[((size_t)j * L + l) * q + c].im - mi;
                                s2 += dr * dr + di * di;
                            }
                        s2 /= n;
                        const long double dr = z[((size_t)p * L + l) * q + c].re - mr, di = z[((size_t)p * L + l) * q + c].im - mi;
                        const long double t = (dr * dr + di * di) / (s2 * (1.0L + 1.0L / (Ke - 1)));
                        const long double pc = powl(1.0L + t / n, -n);
                        if (pc < cmin) cmin = pc;
                    }
                    long double pl = cmin * q;
                    if (pl > 1.0L) pl = 1.0L;
                    fisher -= logl(pl);
                    if (pl < pmin) pmin = pl;
                    ++nt;
                }
                const long double pf = gamma_upper_ref(nt, fisher);
                long double pb = pmin * nt;
                if (pb > 1.0L) pb = 1.0L;
                want[p] = 2.0L * (pf < pb ? pf : pb);
                if (want[p] > 1.0L) want[p] = 1.0L;
                const long double lev = 0.01L * ((p < 60 ? ldexpl(1.0L, -(int)(p + 2)) : 0.0L) + 0.5L / K);
                if (want[p] / lev < worst_r) { worst_r = want[p] / lev; wp = p; }
            }
            if (!(worst_r < 1.0L)) break;
            out[wp] = 1;
            ++flagged;
        }
        for (uint32_t p = 0; p < K; ++p) {
            double got;
            UT_CHECK((msid_pstats_period_state(&o.ps, p, &got) >= 1) == out[p], "trial %d period %u flagged", trial, p);
            const double d = (double)(fabsl(got - want[p]) / want[p]);
            if (d > worst) worst = d;
            small += want[p] < 1e-3L;
        }
        tsim_free(o.mem);
        free(z);
    }
    print_message("period p-values vs long-double reference: relative %.2e (%u below 1e-3, %u flagged in sequence)\n",
                  worst, small, flagged);
    UT_CHECK(worst <= (LDBL_MANT_DIG > 53 ? 1e-12 : 1e-10), "relative %.3g", worst);
    UT_CHECK(small > 20, "only %u small p-values", small);
    UT_CHECK(flagged > 20, "only %u periods flagged: the sequence is not exercised", flagged);
}

/* The deterministic floor (s2 <= 1e-24 (|mean|^2 + scatter/(K-1))): channel 0
 * carries noise swept across the floor, channel 1 ordinary noise (L = 1,
 * q = 2). A test-side mirror of the earlier rule in double (two-pass kept
 * moments, the same expressions) gives each period's class: channel 0
 * deterministic and unchanged (not tested), deterministic and changed
 * (p = 0 exactly), or tested; the library must agree on every class and on
 * the p-value to 1e-12 relative. Negative control: both classes near the floor
 * occur. */
static void test_transient_floor_boundary(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 2468u);
    const uint32_t K = 5, q = 2;
    uint32_t n_det = 0, n_changed = 0, n_tested = 0;
    double worst = 0.0;
    for (int trial = 0; trial < 600; ++trial) {
        msid_cplx z[5 * 2];
        const double sigma = 1e-13 * pow(100.0, trial / 599.0);   /* s2 / floor from ~1e-2 to ~1e2 */
        for (uint32_t p = 0; p < K; ++p) {
            z[p * q] = ut_c(1.0 + sigma * msid_rng_normal(&r), 1.0 + sigma * msid_rng_normal(&r));
            z[p * q + 1] = ut_c(3.0 + msid_rng_normal(&r), -2.0 + msid_rng_normal(&r));
        }
        if (trial % 3 == 0) z[0].re += 1e-9;                    /* period 0 departs in channel 0 */
        pst o;
        UT_STATUS(ps_make(&o, 1, q, 0, K, MSID_TRANSIENT_FLAG, 0.01), MSID_OK);
        ps_add_periods(&o, z, 0, K, NULL);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        /* the earlier rule, expression by expression, over the periods not yet flagged (the
         * sequential test: the most significant period, p over its level, is flagged while below
         * its level and keeps its p-value; the others are tested again without it) */
        int out[5] = {0}, chg[5] = {0};
        double want[5];
        for (int pass = 0;; ++pass) {
            uint32_t Ke = 0;
            for (uint32_t p = 0; p < K; ++p) Ke += !out[p];
            if (Ke < 3) break;
            msid_cplx mean[2] = {{0.0, 0.0}, {0.0, 0.0}};
            double m2d[2] = {0.0, 0.0};
            for (uint32_t p = 0; p < K; ++p)
                if (!out[p])
                    for (uint32_t c = 0; c < q; ++c) { mean[c].re += z[p * q + c].re; mean[c].im += z[p * q + c].im; }
            for (uint32_t c = 0; c < q; ++c) { mean[c].re *= 1.0 / (double)Ke; mean[c].im *= 1.0 / (double)Ke; }
            for (uint32_t p = 0; p < K; ++p)
                if (!out[p])
                    for (uint32_t c = 0; c < q; ++c) {
                        const double dr = z[p * q + c].re - mean[c].re, di = z[p * q + c].im - mean[c].im;
                        m2d[c] += dr * dr + di * di;
                    }
            const double Kd = (double)Ke, n = (double)(Ke - 2u);
            double worst_r = HUGE_VAL;
            uint32_t wp = 0;
            for (uint32_t p = 0; p < K; ++p) {
                if (out[p]) continue;
                double cmin = 1.0, tmax = -1.0;
                uint32_t qt = 0;
                int changed = 0;
                for (uint32_t c = 0; c < q; ++c) {
                    const double dr = z[p * q + c].re - mean[c].re, di = z[p * q + c].im - mean[c].im;
                    const double dev2 = dr * dr + di * di;
                    const double s2 = (m2d[c] - Kd / (Kd - 1.0) * dev2) / n;
                    const double d2 = dev2 * (Kd / (Kd - 1.0)) * (Kd / (Kd - 1.0));
                    const double mu2 = mean[c].re * mean[c].re + mean[c].im * mean[c].im;
                    const double floor_ = 1e-24 * (mu2 + m2d[c] / (Kd - 1.0)) + 1e-300;
                    if (s2 <= floor_) {
                        if (c == 0 && pass == 0) n_det += d2 <= floor_;
                        if (d2 <= floor_) continue;
                        ++qt;
                        cmin = 0.0;
                        changed = 1;
                        continue;
                    }
                    if (c == 0 && pass == 0) ++n_tested;
                    const double t = d2 / (s2 * (1.0 + 1.0 / (Kd - 1.0)));
                    if (t > tmax) tmax = t;
                    ++qt;
                }
                if (tmax >= 0.0) {
                    const double pv = exp(-n * log1p(tmax / n));
                    if (pv < cmin) cmin = pv;
                }
                double pl = cmin * qt;
                if (pl > 1.0) pl = 1.0;
                /* one line: Fisher tail exp(-(-log pl)) = pl and Bonferroni pl: p = min(1, 2 pl) */
                want[p] = 2.0 * pl > 1.0 ? 1.0 : 2.0 * pl;
                chg[p] = changed;
                const double lev = 0.01 * (ldexp(1.0, -(int)(p + 2u)) + 0.5 / (double)K);
                if (want[p] / lev < worst_r) { worst_r = want[p] / lev; wp = p; }
            }
            if (!(worst_r < 1.0)) break;
            out[wp] = 1;
        }
        for (uint32_t p = 0; p < K; ++p) {
            n_changed += (uint32_t)chg[p];   /* as the period was last tested */
            double got;
            if (chg[p]) UT_CHECK(msid_pstats_period_state(&o.ps, p, &got) >= 0 && got == 0.0,
                                 "trial %d period %u: deterministic change, p %.17g", trial, p, got);
            else {
                msid_pstats_period_state(&o.ps, p, &got);
                const double d = fabs(got - want[p]) / want[p];
                if (d > worst) worst = d;
                UT_CHECK(d <= 1e-12, "trial %d period %u: p %.17g want %.17g", trial, p, got, want[p]);
            }
        }
        tsim_free(o.mem);
    }
    print_message("floor boundary: %u deterministic, %u changed, %u tested channel-periods; p within %.2e\n", n_det,
                  n_changed, n_tested, worst);
    UT_CHECK(n_det > 200 && n_tested > 200 && n_changed > 50, "classes: %u deterministic, %u tested, %u changed", n_det, n_tested,
             n_changed);
}

/* Welford statistics after detection without a drop are the streaming ones
 * bit for bit (no rebuild), and equal those of a TRANSIENT_OFF object given
 * the same periods (also in line blocks, also after a second detection and
 * more periods). Negative control: with a drop, they differ from the
 * pre-detection statistics. */
static void test_detect_no_drop_keeps_stats(void **state)
{
    (void)state;
    msid_rng r;
    msid_rng_seed(&r, 1357u);
    const uint32_t K = 12, L = 17, q = 3;
    uint32_t no_drop = 0, with_drop = 0;
    for (int trial = 0; trial < 30; ++trial) {
        msid_cplx *z = make_periods(K, L, q, 2.0, 1.0, &r);
        const int transient = trial % 3 == 0;
        if (transient) for (uint32_t k = 0; k < L * q; ++k) z[k].re += 7.0;
        pst o, ref;
        UT_STATUS(ps_make(&o, L, q, 0, K, MSID_TRANSIENT_DROP, 0.01), MSID_OK);
        UT_STATUS(ps_make(&ref, L, q, 0, 0, MSID_TRANSIENT_OFF, 0.0), MSID_OK);
        /* the first 8 periods in line blocks of 5 */
        for (uint32_t p = 0; p < 8; ++p) {
            int use;
            UT_STATUS(msid_pstats_add_begin(&o.ps, 0, &use), MSID_OK);
            for (uint32_t l0 = 0; l0 < L; l0 += 5) msid_pstats_add_lines(&o.ps, z + (size_t)p * L * q, l0, l0 + 5);
        }
        const size_t nm = (size_t)L * q * sizeof(msid_cplx), ns = nm * q;
        msid_cplx *mean0 = (msid_cplx *)malloc(nm), *m20 = (msid_cplx *)malloc(ns);
        memcpy(mean0, o.ps.mean, nm);
        memcpy(m20, o.ps.m2, ns);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        const int dropped = msid_pstats_get_counts(&o.ps).transient_dropped > 0;
        const int same = memcmp(mean0, o.ps.mean, nm) == 0 && memcmp(m20, o.ps.m2, ns) == 0;
        if (!dropped) {
            UT_CHECK(same, "trial %d: detection without a drop changed the statistics", trial);
            ++no_drop;
        } else {
            UT_CHECK(!same, "trial %d: a drop left the statistics unchanged", trial);
            ++with_drop;
        }
        /* four more periods, detect again: still the statistics of the kept periods in order */
        ps_add_periods(&o, z, 8, K, NULL);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        for (uint32_t p = 0; p < K; ++p)
            if (msid_pstats_period_state(&o.ps, p, NULL) != 2) ps_add_periods(&ref, z, p, p + 1, NULL);
        UT_CHECK(msid_pstats_count(&o.ps) == msid_pstats_count(&ref.ps) && memcmp(o.ps.mean, ref.ps.mean, nm) == 0 &&
                     memcmp(o.ps.m2, ref.ps.m2, ns) == 0,
                 "trial %d: statistics differ from the kept periods' (K %u vs %u)", trial, msid_pstats_count(&o.ps),
                 msid_pstats_count(&ref.ps));
        check_hermitian(&o.ps);
        free(mean0);
        free(m20);
        tsim_free(o.mem);
        tsim_free(ref.mem);
        free(z);
    }
    UT_CHECK(no_drop >= 10 && with_drop >= 5, "both cases exercised: %u without, %u with a drop", no_drop, with_drop);
}

/* Detection after every segment (msid_meas_end of each segment) ends as one
 * detection over all the periods: states, p-values and counts bit for bit, in
 * FLAG and DROP modes. The records: 6 periods that ramp a k^2 (drift declared
 * in the first call, which flags but drops nothing), then 6 at the final
 * level. Negative control: the first call leaves periods flagged and kept;
 * before every call tested afresh, such a stale flag stayed set, kept its
 * period out of the second call's reference and out of DROP (fails at trial
 * 0: 5 flagged, one call 4). */
static void test_detect_per_segment_equals_one_call(void **state)
{
    (void)state;
    const uint32_t L = 20, q = 2;
    uint32_t stale = 0, dropped = 0, compared = 0;
    for (int trial = 0; trial < 24; ++trial) {
        const msid_transient_mode mode = trial % 2 ? MSID_TRANSIENT_DROP : MSID_TRANSIENT_FLAG;
        const double a = 0.1 + 0.05 * (trial / 2 % 6);
        msid_rng r;
        msid_rng_seed(&r, trial < 2 ? 4242u : 4242u + (uint32_t)trial);
        msid_cplx *mu = make_periods(1, L, q, 3.0, 0.0, &r), *d = make_periods(1, L, q, 1.0, 0.0, &r);
        msid_cplx *z = make_periods(12, L, q, 0.0, 1.0, &r);
        for (uint32_t p = 0; p < 12; ++p) {
            const double s = p < 6 ? a * p * p : 25.0 * a;
            for (uint32_t k = 0; k < L * q; ++k) {
                z[(size_t)p * L * q + k].re += mu[k].re + s * d[k].re;
                z[(size_t)p * L * q + k].im += mu[k].im + s * d[k].im;
            }
        }
        pst o, one;
        UT_STATUS(ps_make(&o, L, q, 0, 12, mode, 0.01), MSID_OK);
        UT_STATUS(ps_make(&one, L, q, 0, 12, mode, 0.01), MSID_OK);
        ps_add_periods(&o, z, 0, 6, NULL);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        for (uint32_t p = 0; p < 6; ++p) stale += msid_pstats_period_state(&o.ps, p, NULL) == 1;
        /* a drop is final: compare only records the first call dropped nothing from */
        const int comparable = msid_pstats_get_counts(&o.ps).transient_dropped == 0;
        compared += comparable;
        msid_pstats_new_segment(&o.ps);
        ps_add_periods(&o, z, 6, 12, NULL);
        UT_STATUS(msid_pstats_detect(&o.ps), MSID_OK);
        ps_add_periods(&one, z, 0, 12, NULL);
        UT_STATUS(msid_pstats_detect(&one.ps), MSID_OK);
        const msid_pstats_counts c = msid_pstats_get_counts(&o.ps), c1 = msid_pstats_get_counts(&one.ps);
        UT_CHECK(!comparable || c.transient_flagged == c1.transient_flagged && c.transient_dropped == c1.transient_dropped &&
                     c.used == c1.used && c.drift == c1.drift,
                 "trial %d: flagged %u/%u dropped %u/%u used %u/%u drift %d/%d", trial, c.transient_flagged,
                 c1.transient_flagged, c.transient_dropped, c1.transient_dropped, c.used, c1.used, c.drift, c1.drift);
        for (uint32_t p = 0; p < 12; ++p) {
            double pv, pv1;
            const int s = msid_pstats_period_state(&o.ps, p, &pv), s1 = msid_pstats_period_state(&one.ps, p, &pv1);
            UT_CHECK(!comparable || (s == s1 && memcmp(&pv, &pv1, sizeof pv) == 0), "trial %d period %u: state %d (p %.3g), one call %d (p %.3g)",
                     trial, p, s, pv, s1, pv1);
        }
        dropped += comparable && c1.transient_dropped > 0;
        tsim_free(o.mem);
        tsim_free(one.mem);
        free(mu);
        free(d);
        free(z);
    }
    print_message("periods flagged and kept by the first call: %u; %u records compared, %u of them with a drop\n", stale,
                  compared, dropped);
    UT_CHECK(stale >= 8 && compared >= 16 && dropped >= 4, "not exercised: %u stale flags, %u compared, %u with a drop", stale,
             compared, dropped);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_welford_vs_two_pass),
        cmocka_unit_test(test_skip_gap_nonfinite),
        cmocka_unit_test(test_capacity),
        cmocka_unit_test(test_init_errors),
        cmocka_unit_test(test_transient_pvalue_closed_form),
        cmocka_unit_test(test_transient_drop),
        cmocka_unit_test(test_transient_flag_keeps_stats),
        cmocka_unit_test(test_transient_flag_levels),
        cmocka_unit_test(test_transient_false_alarm_rate),
        cmocka_unit_test(test_transient_line_max_same_bits),
        cmocka_unit_test(test_gamma_tail_accuracy),
        cmocka_unit_test(test_line_term_log_domain),
        cmocka_unit_test(test_transient_pvalue_reference),
        cmocka_unit_test(test_transient_floor_boundary),
        cmocka_unit_test(test_detect_no_drop_keeps_stats),
        cmocka_unit_test(test_detect_per_segment_equals_one_call),
        cmocka_unit_test(test_beyond_history),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
