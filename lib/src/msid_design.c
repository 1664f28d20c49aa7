/* Multisine design: validation, aliasing map (González et al. 2025,
 * Assumptions 1-2, eqs. 2-5), phases, MIMO pattern, crest factors. */
#include "msid/msid_design.h"
#include "msid/msid_dmath.h"
#include "msid/msid_rng.h"
#include "msid_internal.h"
#include "msid_cmat.h"
#include <math.h>

#define TWO_PI 6.28318530717958647692528676655900577

static size_t cond_work_doubles(uint32_t nu) { return 4u * nu * nu + 2u * nu; }

/* Scratch chunks of msid_design_init that are not members of the design. */
typedef struct design_scratch {
    uint8_t *bitmap;    /* [P/16 + 8] bins taken (P/2 + 1 bits, with room) */
    uint32_t *idx;      /* [L] running twiddle index (direct crest factors) */
    msid_cplx *lm;      /* [m*nu] one line's input matrix */
    double *work;       /* [cond_work_doubles(nu)] singular values */
    double *fx, *fre;   /* MSID_CREST_FFT: [P] DFT input, [P/2 + 1] real parts of the first transform */
    msid_cplx *fX;      /* MSID_CREST_FFT: [P/2 + 1] DFT output */
} design_scratch;

/* The one memory layout (see msid__layout): the design's arrays, then its
 * scratch. Returns 0 for an unknown crest mode. */
static size_t layout(msid_design *d, design_scratch *w, const msid_design_cfg *c, void *mem)
{
    const size_t L = c->n_lines, nu = c->n_inputs, m = c->n_experiments;
    msid__layout y = msid__layout_begin(mem);
    d->bins = (uint32_t *)msid__lay(&y, L, sizeof(uint32_t));
    d->folded = (uint8_t *)msid__lay(&y, L, 1);
    d->omega = (double *)msid__lay(&y, L, sizeof(double));
    d->amp = (double *)msid__lay(&y, nu * L, sizeof(double));
    d->phase = (double *)msid__lay(&y, nu * L, sizeof(double));
    d->coef = (msid_cplx *)msid__lay(&y, m * nu * L, sizeof(msid_cplx));
    d->cond = (double *)msid__lay(&y, L, sizeof(double));
    d->crest = (double *)msid__lay(&y, m * nu, sizeof(double));
    w->bitmap = (uint8_t *)msid__lay(&y, c->period / 16u + 8u, 1);
    w->idx = (uint32_t *)msid__lay(&y, L, sizeof(uint32_t));
    w->lm = (msid_cplx *)msid__lay(&y, m * nu, sizeof(msid_cplx));
    w->work = (double *)msid__lay(&y, cond_work_doubles(c->n_inputs), sizeof(double));
    w->fx = 0; w->fre = 0; w->fX = 0;
    if (c->crest == MSID_CREST_FFT) {
        w->fx = (double *)msid__lay(&y, c->period, sizeof(double));
        w->fX = (msid_cplx *)msid__lay(&y, c->period / 2u + 1u, sizeof(msid_cplx));
        w->fre = (double *)msid__lay(&y, c->period / 2u + 1u, sizeof(double));
    } else if (c->crest != MSID_CREST_DIRECT && c->crest != MSID_CREST_NONE) {
        return 0;
    }
    return y.size;
}

size_t msid_design_mem_size(const msid_design_cfg *c)
{
    if (!c) return 0;
    if (c->period < MSID_MIN_PERIOD || c->period > MSID_MAX_PERIOD) return 0;
    if (c->n_lines == 0 || c->n_lines > c->period) return 0;
    if (c->n_inputs == 0 || c->n_inputs > MSID_MAX_INPUTS) return 0;
    if (c->n_experiments == 0 || c->n_experiments > MSID_MAX_EXPERIMENTS) return 0;
    msid_design tmp;
    design_scratch w;
    return layout(&tmp, &w, c, 0);
}

static msid_status fail(msid_design *d, msid_status st, int32_t a, int32_t b, int64_t bin)
{
    d->diag.line_a = a;
    d->diag.line_b = b;
    d->diag.bin = bin;
    return st;
}

static int bit_get(const uint8_t *bm, uint32_t b) { return (bm[b >> 3] >> (b & 7u)) & 1u; }
static void bit_set(uint8_t *bm, uint32_t b) { bm[b >> 3] |= (uint8_t)(1u << (b & 7u)); }

/* Sign/phase of the pattern entry T[i][e], in turns. */
static double pattern_turns(msid_pattern p, uint32_t i, uint32_t e, uint32_t m)
{
    if (p == MSID_PATTERN_HADAMARD) {
        /* Sylvester: H[i][e] = (-1)^popcount(i & e) */
        uint32_t x = i & e, par = 0;
        while (x) { par ^= 1u; x &= x - 1u; }
        return par ? 0.5 : 0.0;
    }
    /* DFT: exp(-j 2 pi i e / m) */
    return -(double)((uint64_t)i * e % m) / (double)m;
}

/* Real pattern for a DC line (its value must be real): Hadamard signs, or the
 * real DFT basis 1, cos(2 pi k e/m), sin(2 pi k e/m), k = 1, 2, ... Rows are
 * orthogonal, so the nu x m DC input matrix has condition number <= sqrt(2). */
static double dc_pattern(msid_pattern p, uint32_t i, uint32_t e, uint32_t m)
{
    if (p == MSID_PATTERN_HADAMARD) return pattern_turns(p, i, e, m) != 0.0 ? -1.0 : 1.0;
    if (i == 0u) return 1.0;
    const uint32_t k = (i + 1u) / 2u;
    double cs, sn;
    msid_cis_turns((double)((uint64_t)k * e % m) / (double)m, &cs, &sn);
    return (i & 1u) ? cs : sn;
}

/* Crest factors from two real DFTs per input and experiment, O(m nu P log P). With w[k] = exp(-j 2 pi k/P)
 * the generated sample is u(n) = sum_l Re(c_l) cos(phi) - Im(c_l) sin(phi), phi = 2 pi b_l n / P. Put Re(c_l),
 * Im(c_l) at bin b_l of two real sequences a, b; their forward DFTs A, B give, for n = 0..P/2,
 *   u(n) = Re A(n) + Im B(n),   u(P - n) = Re A(n) - Im B(n)   (the cosines are even, the sines odd).
 * Deterministic for a deterministic backend; equal to direct synthesis up to rounding. */
static msid_status crest_fft(msid_design *d, const msid_fft_backend *fft, double *x, msid_cplx *X, double *re)
{
    const uint32_t P = d->period, L = d->n_lines, nu = d->n_inputs, m = d->n_experiments, H = P / 2u;
    for (uint32_t n = 0; n < P; ++n) x[n] = 0.0;
    for (uint32_t e = 0; e < m; ++e)
        for (uint32_t i = 0; i < nu; ++i) {
            const msid_cplx *cf = d->coef + ((size_t)e * nu + i) * L;
            for (uint32_t l = 0; l < L; ++l) x[d->bins[l]] = cf[l].re;
            if (fft->r2c(fft->ctx, x, X) != MSID_OK) return MSID_E_BACKEND;
            for (uint32_t k = 0; k <= H; ++k) re[k] = X[k].re;
            for (uint32_t l = 0; l < L; ++l) x[d->bins[l]] = cf[l].im;
            if (fft->r2c(fft->ctx, x, X) != MSID_OK) return MSID_E_BACKEND;
            for (uint32_t l = 0; l < L; ++l) x[d->bins[l]] = 0.0;
            double peak = 0.0, ss = 0.0;
            for (uint32_t k = 0; k <= H; ++k) {
                const double u = re[k] + X[k].im;
                peak = fmax(peak, fabs(u));
                ss += u * u;
                if (k > 0 && P - k != k) {   /* sample P - k (for even P, k = P/2 is its own mirror) */
                    const double v = re[k] - X[k].im;
                    peak = fmax(peak, fabs(v));
                    ss += v * v;
                }
            }
            const double rms = sqrt(ss / (double)P);
            d->crest[(size_t)e * nu + i] = rms > 0.0 ? peak / rms : HUGE_VAL;
        }
    return MSID_OK;
}

/* Step: the configuration alone (before any memory is touched). */
static msid_status check_cfg(msid_design *d, const msid_design_cfg *c)
{
    if (c->period < MSID_MIN_PERIOD || c->period > MSID_MAX_PERIOD) return MSID_E_PERIOD;
    if (c->n_lines == 0) return MSID_E_NO_LINES;
    if (c->n_inputs == 0 || c->n_inputs > MSID_MAX_INPUTS ||
        c->n_experiments == 0 || c->n_experiments > MSID_MAX_EXPERIMENTS) return MSID_E_DIMS;
    if (c->n_experiments < c->n_inputs) return MSID_E_EXPERIMENTS;
    if (c->pattern != MSID_PATTERN_DFT && c->pattern != MSID_PATTERN_HADAMARD) return MSID_E_PATTERN;
    if (c->pattern == MSID_PATTERN_HADAMARD && !msid__is_pow2(c->n_experiments)) return MSID_E_PATTERN;
    if (c->phase_mode != MSID_PHASE_RANDOM && c->phase_mode != MSID_PHASE_SCHROEDER &&
        c->phase_mode != MSID_PHASE_USER) return MSID_E_ARG;
    if (c->phase_mode == MSID_PHASE_USER && !c->phases) return MSID_E_NULL;
    if (!c->bins && !c->omega) return MSID_E_NULL;
    if (!c->twiddle) return MSID_E_NULL;
    if (c->twiddle->period != c->period) return MSID_E_PERIOD;
    if (c->n_lines > c->period / 2u + 1u) return fail(d, MSID_E_LINE_DUP, -1, -1, -1);
    if (c->crest == MSID_CREST_FFT && (!c->fft || !c->fft->r2c)) return MSID_E_NULL;
    if (c->crest == MSID_CREST_FFT && c->fft->period != c->period) return MSID_E_BACKEND;
    return MSID_OK;
}

/* Step: discrete-time lines, each bin in [0, P/2) once. */
static msid_status dt_lines(msid_design *d, const msid_design_cfg *c, uint8_t *bitmap)
{
    const uint32_t P = d->period;
    d->is_ct = 0;
    d->sample_time = 0.0;
    for (uint32_t l = 0; l < d->n_lines; ++l) {
        const uint32_t b = c->bins[l];
        if ((uint64_t)b * 2u >= P) return fail(d, MSID_E_LINE_RANGE, (int32_t)l, -1, b);
        if (bit_get(bitmap, b)) {
            int32_t first = -1;
            for (uint32_t j = 0; j < l; ++j) if (c->bins[j] == b) { first = (int32_t)j; break; }
            return fail(d, MSID_E_LINE_DUP, first, (int32_t)l, b);
        }
        bit_set(bitmap, b);
        d->bins[l] = b;
        d->folded[l] = 0;
        d->omega[l] = TWO_PI * (double)b / (double)P;
    }
    return MSID_OK;
}

/* Step: continuous-time lines and the aliasing map (González et al. 2025, Assumptions 1-2, eqs. 2-5):
 * omega P h / (2 pi) must be an integer r; the line sits at bin r mod P, folded to P - b above P/2. */
static msid_status ct_lines(msid_design *d, const msid_design_cfg *c, uint8_t *bitmap)
{
    const uint32_t P = d->period;
    const double h = c->sample_time;
    if (!msid__finite(h) || !(h > 0.0)) return MSID_E_SAMPLE_TIME;
    d->is_ct = 1;
    d->sample_time = h;
    const double tol = c->ct_tol > 0.0 ? c->ct_tol : 1e-6;
    const double span = (double)P * h;           /* P*h seconds */
    if (!msid__finite(span)) return MSID_E_SAMPLE_TIME;   /* P h overflows: 0 * inf would be a NaN line */
    for (uint32_t l = 0; l < d->n_lines; ++l) {
        const double w = c->omega[l];
        if (!msid__finite(w) || w < 0.0) return fail(d, MSID_E_ARG, (int32_t)l, -1, -1);
        const double cyc = w * span / TWO_PI;     /* cycles of line l in P*h */
        const double r = floor(cyc + 0.5);
        if (!(fabs(cyc - r) <= tol) || !(r <= 9.0e15))   /* NaN-safe: a NaN is never periodic */
            return fail(d, MSID_E_CT_NOT_PERIODIC, (int32_t)l, -1, -1);
        uint32_t b = (uint32_t)((uint64_t)r % P);
        uint8_t fold = 0;
        if (w != 0.0 && b == 0u) return fail(d, MSID_E_ALIAS_EDGE, (int32_t)l, -1, 0);
        if ((uint64_t)b * 2u == P) return fail(d, MSID_E_ALIAS_EDGE, (int32_t)l, -1, b);
        if ((uint64_t)b * 2u > P) { b = P - b; fold = 1; }
        if (bit_get(bitmap, b)) {
            int32_t first = -1;
            for (uint32_t j = 0; j < l; ++j) if (d->bins[j] == b) { first = (int32_t)j; break; }
            return fail(d, MSID_E_ALIAS_COLLISION, first, (int32_t)l, b);
        }
        bit_set(bitmap, b);
        d->bins[l] = b;
        d->folded[l] = fold;
        d->omega[l] = w;
    }
    return MSID_OK;
}

/* Step: amplitudes A_{i,l} in [MSID_MIN_AMPLITUDE, MSID_MAX_AMPLITUDE] (all 1 without a table). */
static msid_status amplitudes(msid_design *d, const msid_design_cfg *c)
{
    const uint32_t L = d->n_lines;
    for (uint32_t i = 0; i < d->n_inputs; ++i) {
        for (uint32_t l = 0; l < L; ++l) {
            double A = 1.0;
            if (c->amplitudes) A = c->amp_per_input ? c->amplitudes[(size_t)i * L + l] : c->amplitudes[l];
            if (!msid__finite(A) || !(A >= MSID_MIN_AMPLITUDE && A <= MSID_MAX_AMPLITUDE)) return fail(d, MSID_E_AMPLITUDE, (int32_t)l, -1, d->bins[l]);
            d->amp[(size_t)i * L + l] = A;
        }
    }
    return MSID_OK;
}

/* Step: base phases in turns (random, Schroeder or the user's); DC has none. */
static msid_status base_phases(msid_design *d, const msid_design_cfg *c)
{
    const uint32_t L = d->n_lines;
    msid_rng rng;
    msid_rng_seed(&rng, c->seed);
    for (uint32_t i = 0; i < d->n_inputs; ++i) {
        double *ph = d->phase + (size_t)i * L;
        const double *A = d->amp + (size_t)i * L;
        if (c->phase_mode == MSID_PHASE_RANDOM) {
            for (uint32_t l = 0; l < L; ++l) ph[l] = msid_rng_uniform(&rng);
        } else if (c->phase_mode == MSID_PHASE_SCHROEDER) {
            /* Schroeder (1970): phi_l = -2 pi sum_{j<l} (l - j) p_j, p_j = A_j^2 / sum A^2.
             * Incrementally: phi_l = phi_{l-1} - S_l, S_l = sum_{j<l} p_j (turns). */
            double tot = 0.0;
            for (uint32_t l = 0; l < L; ++l) tot += A[l] * A[l];
            /* Amplitudes whose squares overflow (A ~ 1e160) made p_j = inf/inf = NaN and the phase
             * NaN (found by fuzz_can_config): then the same p_j from A / max A. Otherwise unchanged. */
            double k = 1.0;
            if (!msid__finite(tot)) {
                double amax = 0.0;
                for (uint32_t l = 0; l < L; ++l) if (A[l] > amax) amax = A[l];
                k = 1.0 / amax; tot = 0.0;
                for (uint32_t l = 0; l < L; ++l) tot += (k * A[l]) * (k * A[l]);
            }
            double S = 0.0, phi = 0.0;
            for (uint32_t l = 0; l < L; ++l) {
                if (l > 0) { S += (k * A[l - 1]) * (k * A[l - 1]) / tot; phi -= S; phi -= floor(phi); }
                ph[l] = phi;
            }
        } else {
            for (uint32_t l = 0; l < L; ++l) {
                const double p = c->phases[(size_t)i * L + l];
                if (!msid__finite(p)) return fail(d, MSID_E_PHASE, (int32_t)l, -1, d->bins[l]);
                ph[l] = p - floor(p);
            }
        }
        for (uint32_t l = 0; l < L; ++l) if (d->bins[l] == 0u) ph[l] = 0.0;   /* DC has no phase */
    }
    return MSID_OK;
}

/* Step: coefficients c_{e,i,l} = A e^{j2pi(phi + tau_ie)} (conjugated if folded; eq. 2). */
static void coefficients(msid_design *d)
{
    const uint32_t L = d->n_lines, nu = d->n_inputs, m = d->n_experiments;
    for (uint32_t e = 0; e < m; ++e) {
        for (uint32_t i = 0; i < nu; ++i) {
            const double tau = pattern_turns(d->pattern, i, e, m);
            for (uint32_t l = 0; l < L; ++l) {
                const double A = d->amp[(size_t)i * L + l];
                double cr, ci;
                if (d->bins[l] == 0u) {
                    cr = dc_pattern(d->pattern, i, e, m);   /* DC: a real orthogonal pattern */
                    ci = 0.0;
                } else {
                    msid_cis_turns(d->phase[(size_t)i * L + l] + tau, &cr, &ci);
                    if (d->folded[l]) ci = -ci;
                }
                d->coef[((size_t)e * nu + i) * L + l] = msid__c(A * cr, A * ci);
            }
        }
    }
}

/* Step: condition number of each line's input matrix (Assumption 1). */
static msid_status line_conditions(msid_design *d, msid_cplx *lm, double *work)
{
    const uint32_t L = d->n_lines, nu = d->n_inputs, m = d->n_experiments;
    d->cond_max = 0.0;
    for (uint32_t l = 0; l < L; ++l) {
        /* U^H is m x nu: row e, column i holds conj(c_{e,i,l}). */
        for (uint32_t e = 0; e < m; ++e)
            for (uint32_t i = 0; i < nu; ++i)
                lm[e * nu + i] = msid__cconj(d->coef[((size_t)e * nu + i) * L + l]);
        double smin, smax;
        msid__csv_minmax((int)m, (int)nu, lm, work, &smin, &smax);
        const double cond = smin > 0.0 ? smax / smin : HUGE_VAL;
        d->cond[l] = cond;
        if (cond > d->cond_max) d->cond_max = cond;
        if (!(smin > 1e-12 * smax)) return fail(d, MSID_E_SINGULAR, (int32_t)l, -1, d->bins[l]);
    }
    return MSID_OK;
}

/* Step: crest factors by direct synthesis of the exact generated samples, O(m nu P L). */
static void crest_direct(msid_design *d, const msid_cplx *w, uint32_t *idx)
{
    const uint32_t P = d->period, L = d->n_lines, nu = d->n_inputs, m = d->n_experiments;
    for (uint32_t e = 0; e < m; ++e) {
        for (uint32_t i = 0; i < nu; ++i) {
            const msid_cplx *cf = d->coef + ((size_t)e * nu + i) * L;
            for (uint32_t l = 0; l < L; ++l) idx[l] = 0;
            double peak = 0.0, ss = 0.0;
            for (uint32_t n = 0; n < P; ++n) {
                double u = 0.0;
                for (uint32_t l = 0; l < L; ++l) {
                    const msid_cplx t = w[idx[l]];
                    u += cf[l].re * t.re + cf[l].im * t.im;
                    idx[l] += d->bins[l];
                    if (idx[l] >= P) idx[l] -= P;
                }
                if (fabs(u) > peak) peak = fabs(u);
                ss += u * u;
            }
            const double rms = sqrt(ss / (double)P);
            d->crest[(size_t)e * nu + i] = rms > 0.0 ? peak / rms : HUGE_VAL;
        }
    }
}

msid_status msid_design_init(msid_design *d, const msid_design_cfg *c, void *mem, size_t len)
{
    if (!d) return MSID_E_NULL;
    d->diag.line_a = d->diag.line_b = -1;
    d->diag.bin = -1;
    if (!c) return MSID_E_NULL;
    msid_status st = check_cfg(d, c);
    if (st != MSID_OK) return st;
    const size_t need = msid_design_mem_size(c);
    if (need == 0) return MSID_E_DIMS;
    st = msid__mem_check(mem, len, need);
    if (st != MSID_OK) return st;
    design_scratch w;
    (void)layout(d, &w, c, mem);
    d->period = c->period; d->n_lines = c->n_lines; d->n_inputs = c->n_inputs;
    d->n_experiments = c->n_experiments;
    d->phase_mode = c->phase_mode; d->pattern = c->pattern; d->seed = c->seed;
    for (uint32_t k = 0; k < c->period / 16u + 8u; ++k) w.bitmap[k] = 0;

    st = c->bins ? dt_lines(d, c, w.bitmap) : ct_lines(d, c, w.bitmap);
    if (st == MSID_OK) st = amplitudes(d, c);
    if (st == MSID_OK) st = base_phases(d, c);
    if (st != MSID_OK) return st;
    coefficients(d);
    st = line_conditions(d, w.lm, w.work);
    if (st != MSID_OK) return st;
    if (c->crest == MSID_CREST_NONE) {
        for (size_t k = 0; k < (size_t)d->n_experiments * d->n_inputs; ++k) d->crest[k] = NAN;
        return MSID_OK;
    }
    if (c->crest == MSID_CREST_FFT) return crest_fft(d, c->fft, w.fx, w.fX, w.fre);
    crest_direct(d, c->twiddle->w, w.idx);
    return MSID_OK;
}

msid_design_diag_t msid_design_diag(const msid_design *d)
{
    msid_design_diag_t z = {-1, -1, -1};
    return d ? d->diag : z;
}

msid_cplx msid_design_coef(const msid_design *d, uint32_t e, uint32_t i, uint32_t l)
{
    if (!d || e >= d->n_experiments || i >= d->n_inputs || l >= d->n_lines) return msid__c(NAN, NAN);
    return d->coef[((size_t)e * d->n_inputs + i) * d->n_lines + l];
}

msid_cplx msid_design_input_dft(const msid_design *d, uint32_t e, uint32_t i, uint32_t l)
{
    const msid_cplx c = msid_design_coef(d, e, i, l);
    if (!d || l >= d->n_lines) return c;
    if (d->bins[l] == 0u) return msid__c((double)d->period * c.re, 0.0);
    return msid__cscale(c, 0.5 * (double)d->period);
}

double msid_design_crest_factor(const msid_design *d, uint32_t e, uint32_t i)
{
    if (!d || e >= d->n_experiments || i >= d->n_inputs) return NAN;
    return d->crest[(size_t)e * d->n_inputs + i];
}

double msid_design_cond(const msid_design *d, uint32_t l)
{
    if (!d || l >= d->n_lines) return NAN;
    return d->cond[l];
}

double msid_design_sample(const msid_design *d, const msid_twiddle *tw, uint32_t e, uint32_t i, uint32_t n)
{
    if (!d || !tw || tw->period != d->period || e >= d->n_experiments || i >= d->n_inputs) return NAN;
    const uint32_t P = d->period;
    const msid_cplx *cf = d->coef + ((size_t)e * d->n_inputs + i) * d->n_lines;
    double u = 0.0;
    n %= P;
    for (uint32_t l = 0; l < d->n_lines; ++l) {
        const msid_cplx t = tw->w[(uint64_t)d->bins[l] * n % P];
        u += cf[l].re * t.re + cf[l].im * t.im;
    }
    return u;
}
