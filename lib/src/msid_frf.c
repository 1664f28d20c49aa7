/* MIMO LS FRF per line and its covariance (González et al. 2025 Thm 1-2,
 * eqs. 23, 29, 37; Pintelon 2002 eqs. 25, 31-32). */
#include "msid/msid_frf.h"
#include "msid_internal.h"
#include "msid_cmat.h"
#include <float.h>
#include <math.h>

static size_t work_cplx(uint32_t nu, uint32_t ny, uint32_t m)
{
    const size_t q = (size_t)nu + ny;
    return (size_t)m * nu * 2u + (size_t)nu * nu * 2u + (size_t)ny * m + ny * q + 2u * ny * ny +
           (4u * nu * nu + 2u * nu) / 2u + 2u;
}

/* The one memory layout (see msid__layout): per-line results, the time-domain
 * noise covariance, detection-line results, and the solver's workspace. */
static size_t layout(msid_frf *f, const msid_frf_cfg *c, void *mem)
{
    const size_t L = c->n_lines, nu = c->n_inputs, ny = c->n_outputs, m = c->n_experiments;
    const size_t g = ny * nu, D = c->n_detect;
    msid__layout y = msid__layout_begin(mem);
    f->folded = (uint8_t *)msid__lay(&y, L, 1);
    f->G = (msid_cplx *)msid__lay(&y, L * g, sizeof(msid_cplx));
    f->cov = (msid_cplx *)msid__lay(&y, msid__mul(L, g * g), sizeof(msid_cplx));
    f->cov_ki = (msid_cplx *)msid__lay(&y, msid__mul(L, g * g), sizeof(msid_cplx));
    f->dof = (double *)msid__lay(&y, L, sizeof(double));
    f->dof_ki = (double *)msid__lay(&y, L, sizeof(double));
    f->noise = (msid_cplx *)msid__lay(&y, L * ny * ny, sizeof(msid_cplx));
    f->snr = (double *)msid__lay(&y, L * ny, sizeof(double));
    f->cond = (double *)msid__lay(&y, L, sizeof(double));
    f->urel = (double *)msid__lay(&y, L, sizeof(double));
    f->usnr = (double *)msid__lay(&y, L, sizeof(double));
    f->line_status = (uint8_t *)msid__lay(&y, L, 1);
    f->noise_time = (msid_cplx *)msid__lay(&y, ny * ny, sizeof(msid_cplx));
    f->dmean = 0; f->dvar = 0; f->dpval = 0;
    if (D) {
        f->dmean = (msid_cplx *)msid__lay(&y, D * m * ny, sizeof(msid_cplx));
        f->dvar = (double *)msid__lay(&y, D * ny, sizeof(double));
        f->dpval = (double *)msid__lay(&y, D * ny, sizeof(double));
    }
    f->work = (msid_cplx *)msid__lay(&y, work_cplx(c->n_inputs, c->n_outputs, c->n_experiments),
                                     sizeof(msid_cplx));
    return y.size;
}

size_t msid_frf_mem_size(const msid_frf_cfg *c)
{
    if (!c || c->n_lines == 0) return 0;
    if (c->n_inputs == 0 || c->n_inputs > MSID_MAX_INPUTS || c->n_outputs == 0 ||
        c->n_outputs > MSID_MAX_OUTPUTS || c->n_experiments == 0 ||
        c->n_experiments > MSID_MAX_EXPERIMENTS) return 0;
    msid_frf tmp;
    return layout(&tmp, c, 0);
}

msid_status msid_frf_init(msid_frf *f, const msid_frf_cfg *c, void *mem, size_t len)
{
    if (!f || !c) return MSID_E_NULL;
    if (c->n_lines == 0) return MSID_E_NO_LINES;
    if (c->period < MSID_MIN_PERIOD || c->period > MSID_MAX_PERIOD) return MSID_E_PERIOD;
    if (c->n_inputs == 0 || c->n_inputs > MSID_MAX_INPUTS || c->n_outputs == 0 ||
        c->n_outputs > MSID_MAX_OUTPUTS || c->n_experiments == 0 ||
        c->n_experiments > MSID_MAX_EXPERIMENTS) return MSID_E_DIMS;
    if (c->n_experiments < c->n_inputs) return MSID_E_EXPERIMENTS;
    const msid_status st = msid__mem_check(mem, len, msid_frf_mem_size(c));
    if (st != MSID_OK) return st;
    (void)layout(f, c, mem);
    const size_t L = c->n_lines;
    f->period = c->period; f->n_inputs = c->n_inputs; f->n_outputs = c->n_outputs;
    f->n_experiments = c->n_experiments; f->n_lines = c->n_lines; f->n_detect = c->n_detect;
    for (size_t l = 0; l < L; ++l) f->folded[l] = c->folded ? (c->folded[l] ? 1u : 0u) : 0u;
    f->bad_line = -1;
    f->bad_experiment = -1;
    f->K_total = 0;
    return MSID_OK;
}

/* P(F(2m, 2n) > fstat) = I_x(n, m), x = n / (n + m fstat), for integers n, m >= 1:
 * I_x(a, b) = sum_{j=a}^{a+b-1} C(a+b-1, j) x^j (1-x)^{a+b-1-j}, in the log domain. */
static double f_tail_2m_2n(uint32_t m, uint32_t n, double fstat)
{
    if (!(fstat > 0.0)) return 1.0;
    if (fstat == HUGE_VAL) return 0.0;
    const double x = (double)n / ((double)n + (double)m * fstat);
    if (!(x > 0.0)) return 0.0;
    if (!(x < 1.0)) return 1.0;
    const uint32_t a = n, b = m, N = a + b - 1u;
    double lc = 0.0;                               /* log C(N, a) = sum_{i=1}^{b-1} log((a+i)/i) */
    for (uint32_t i = 1; i < b; ++i) lc += log((double)(a + i) / (double)i);
    const double lx = log(x), l1x = log1p(-x);
    double lt[MSID_MAX_EXPERIMENTS];
    double mx = -HUGE_VAL;
    double cur = lc + (double)a * lx + (double)(N - a) * l1x;
    for (uint32_t k = 0; k < b; ++k) {
        const uint32_t j = a + k;
        if (k > 0) cur += log((double)(N - j + 1u) / (double)j) + lx - l1x;
        lt[k] = cur;
        if (cur > mx) mx = cur;
    }
    double s = 0.0;
    for (uint32_t k = 0; k < b; ++k) s += exp(lt[k] - mx);
    const double p = exp(mx + log(s));
    return p > 1.0 ? 1.0 : p;
}

/* Scratch of one line's solve, carved from f->work (work_cplx() complex values). */
typedef struct frf_scratch {
    msid_cplx *A;    /* m x nu : Ubar^H, then Q */
    msid_cplx *R;    /* nu x nu */
    msid_cplx *W;    /* m x nu : Ubar^+ */
    msid_cplx *Rc;   /* nu x nu copy for cond */
    msid_cplx *Y;    /* ny x m */
    msid_cplx *T;    /* ny x q */
    msid_cplx *S;    /* ny x ny */
    msid_cplx *Sp;   /* ny x ny */
    double *dw;      /* singular-value workspace */
} frf_scratch;

/* Step: scratch layout. */
static frf_scratch scratch_layout(const msid_frf *f)
{
    const size_t nu = f->n_inputs, ny = f->n_outputs, m = f->n_experiments, q = nu + ny;
    frf_scratch w;
    w.A = f->work;
    w.R = w.A + m * nu;
    w.W = w.R + nu * nu;
    w.Rc = w.W + m * nu;
    w.Y = w.Rc + nu * nu;
    w.T = w.Y + ny * m;
    w.S = w.T + ny * q;
    w.Sp = w.S + ny * ny;
    w.dw = (double *)(w.Sp + ny * ny);
    return w;
}

/* Step: the statistics match the configuration and every experiment has K >= 2;
 * *dofk = sum_e (K_e - 1). */
static msid_status check_stats(msid_frf *f, const msid_pstats *const *stats, uint32_t *dofk)
{
    const uint32_t q = f->n_inputs + f->n_outputs;
    *dofk = 0;
    for (uint32_t e = 0; e < f->n_experiments; ++e) {
        if (!stats[e]) return MSID_E_NULL;
        if (stats[e]->n_channels != q || stats[e]->n_lines != f->n_lines + f->n_detect) return MSID_E_DIMS;
        const uint32_t K = msid_pstats_count(stats[e]);
        if (K < 2) { f->bad_experiment = (int32_t)e; return MSID_E_FEW_PERIODS; }
        f->K_total += K;
        *dofk += K - 1u;
    }
    return MSID_OK;
}

/* Step: scale of the excitation, the largest |Ubar|_F^2 over the lines; MSID_E_RANGE when
 * |U|^2 overflowed or underflowed (every product below would too). */
static msid_status input_scale(msid_frf *f, const msid_pstats *const *stats, double *uscale)
{
    const uint32_t nu = f->n_inputs, m = f->n_experiments;
    *uscale = 0.0;
    for (uint32_t l = 0; l < f->n_lines; ++l) {
        double s2 = 0.0;
        for (uint32_t e = 0; e < m; ++e) {
            const msid_cplx *z = msid_pstats_mean(stats[e], l);
            for (uint32_t j = 0; j < nu; ++j) s2 += msid__cabs2(z[j]);
        }
        if (s2 > *uscale) *uscale = s2;
        double amax = 0.0;
        for (uint32_t e = 0; e < m; ++e)
            for (uint32_t j = 0; j < nu; ++j) {
                const msid_cplx z = msid_pstats_mean(stats[e], l)[j];
                amax = fmax(amax, fmax(fabs(z.re), fabs(z.im)));
            }
        if (!(s2 <= DBL_MAX) || (s2 < DBL_MIN && amax > 0.0)) { f->bad_line = (int32_t)l; return MSID_E_RANGE; }
    }
    return MSID_OK;
}

/* Step: Ubar^H (m x nu) into A and Ybar (ny x m) into Y from the experiment means of line l. */
static void line_means(const msid_frf *f, const msid_pstats *const *stats, uint32_t l, const frf_scratch *w)
{
    const uint32_t nu = f->n_inputs, ny = f->n_outputs, m = f->n_experiments;
    for (uint32_t e = 0; e < m; ++e) {
        const msid_cplx *z = msid_pstats_mean(stats[e], l);
        for (uint32_t j = 0; j < nu; ++j) w->A[e * nu + j] = msid__cconj(z[j]);
        for (uint32_t i = 0; i < ny; ++i) w->Y[i * m + e] = z[nu + i];
    }
}

/* Step: pooled output noise Sigma_p = sum_e S_yy,e / sum_e (K_e - 1) (known input, per-period DFT
 * units) into Sp and the line's noise covariance; added to the time-domain sum (at +omega). */
static void pooled_noise(msid_frf *f, const msid_pstats *const *stats, uint32_t l, uint32_t dofk,
                         const frf_scratch *w)
{
    const uint32_t nu = f->n_inputs, ny = f->n_outputs, q = nu + ny;
    msid_cplx *Sp = w->Sp, *N = f->noise + (size_t)l * ny * ny;
    for (uint32_t i = 0; i < ny * ny; ++i) Sp[i] = msid__c(0.0, 0.0);
    for (uint32_t e = 0; e < f->n_experiments; ++e) {
        const msid_cplx *M2 = msid_pstats_scatter(stats[e], l);
        for (uint32_t r = 0; r < ny; ++r)
            for (uint32_t c = 0; c < ny; ++c)
                Sp[r * ny + c] = msid__cadd(Sp[r * ny + c], M2[(nu + r) * q + nu + c]);
    }
    for (uint32_t i = 0; i < ny * ny; ++i) { Sp[i] = msid__cscale(Sp[i], 1.0 / (double)dofk); N[i] = Sp[i]; }
    /* reported at +omega: conjugated for a folded CT line */
    for (uint32_t i = 0; i < ny * ny; ++i)
        f->noise_time[i] = msid__cadd(f->noise_time[i], f->folded[l] ? msid__cconj(Sp[i]) : Sp[i]);
}

/* Step: SNR of the averaged output spectrum of line l, dB. */
static void output_snr(msid_frf *f, const msid_pstats *const *stats, uint32_t l, const frf_scratch *w)
{
    const uint32_t ny = f->n_outputs, m = f->n_experiments;
    for (uint32_t i = 0; i < ny; ++i) {
        double sig = 0.0, noi = 0.0;
        for (uint32_t e = 0; e < m; ++e) {
            sig += msid__cabs2(w->Y[i * m + e]);
            noi += w->Sp[i * ny + i].re / (double)msid_pstats_count(stats[e]);
        }
        f->snr[(size_t)l * ny + i] = noi > 0.0 ? 10.0 * log10(sig / noi) : HUGE_VAL;
    }
}

/* Step: thin QR of Ubar^H = Q R (Ubar^+ = Q R^{-H}, avoids forming Ubar Ubar^H), the smallest
 * singular value of R and its condition number. Returns 0 when the QR found a zero column. */
static int line_qr(const msid_frf *f, const frf_scratch *w, double *smin_out, double *cond_out)
{
    const uint32_t nu = f->n_inputs, m = f->n_experiments;
    const msid_cplx *R = w->R;
    const int ok = msid__cqr((int)m, (int)nu, w->A, w->R, 1e-13);
    double cond = 1.0, smin = R[0].re;       /* one input: a single column, |Ubar| */
    if (nu == 2u) {
        /* R = [a b; 0 d]: singular values^2 are the roots of s^2 - t s + |a|^2 |d|^2 */
        /* R scaled by a power of two 2^-ex (exact: same bits) so that |R|^4 cannot overflow for
           inputs near 1e78 */
        int ex = 0;
        (void)frexp(fmax(fmax(fabs(R[0].re), fabs(R[0].im)), fmax(fmax(fabs(R[1].re), fabs(R[1].im)),
                                                                 fmax(fabs(R[3].re), fabs(R[3].im)))), &ex);
        const msid_cplx r0 = msid__cscale(R[0], ldexp(1.0, -ex)), r1 = msid__cscale(R[1], ldexp(1.0, -ex));
        const msid_cplx r3 = msid__cscale(R[3], ldexp(1.0, -ex));
        const double aa = msid__cabs2(r0), bb = msid__cabs2(r1), dd = msid__cabs2(r3);
        const double t = aa + bb + dd, det = aa * dd;
        /* t^2 - 4 det written without cancellation */
        const double disc = sqrt((aa - dd) * (aa - dd) + bb * (bb + 2.0 * (aa + dd)));
        const double s2max = 0.5 * (t + disc), s2min = s2max > 0.0 ? det / s2max : 0.0;
        smin = ldexp(sqrt(s2min), ex);
        cond = s2min > 0.0 ? sqrt(s2max / s2min) : HUGE_VAL;
    } else if (nu > 2u) {
        for (uint32_t k = 0; k < nu * nu; ++k) w->Rc[k] = R[k];
        double smax;
        msid__csv_minmax((int)nu, (int)nu, w->Rc, w->dw, &smin, &smax);
        cond = smin > 0.0 ? smax / smin : HUGE_VAL;
    }
    /* sigma_max >= sigma_min, so cond >= 1; with orthogonal inputs of equal power the rounding of
       det / s2max can put s2min a last bit above s2max (0.9999999999999999 on AArch64) */
    *smin_out = smin;
    *cond_out = cond < 1.0 ? 1.0 : cond;
    return ok;
}

/* Step: excitation test. Is the line excited at all? Compare the weakest input direction with
 * the strongest line and with the noise power of the input means. Returns 1 if unexcited. */
static int excitation_test(msid_frf *f, const msid_pstats *const *stats, uint32_t l, double smin, double uscale)
{
    const uint32_t nu = f->n_inputs, q = nu + f->n_outputs;
    double unoise = 0.0;
    for (uint32_t e = 0; e < f->n_experiments; ++e) {
        const uint32_t Ke = msid_pstats_count(stats[e]);
        const msid_cplx *M2 = msid_pstats_scatter(stats[e], l);
        for (uint32_t j = 0; j < nu; ++j) unoise += M2[j * q + j].re / ((double)(Ke - 1u) * (double)Ke);
    }
    const double s2min = smin * smin;
    f->urel[l] = uscale > 0.0 ? s2min / uscale : 0.0;
    f->usnr[l] = unoise > 0.0 ? s2min / unoise : HUGE_VAL;
    return !(s2min > 1e-20 * uscale) || !(f->usnr[l] > 10.0);
}

/* Step: back substitution W^H = R^{-1} Q^H (nu x m), stored transposed-conjugated into W. */
static void back_substitution(const msid_frf *f, const frf_scratch *w)
{
    const uint32_t nu = f->n_inputs;
    const msid_cplx *A = w->A, *R = w->R;
    msid_cplx *W = w->W;
    for (uint32_t e = 0; e < f->n_experiments; ++e) {
        for (int j = (int)nu - 1; j >= 0; --j) {
            msid_cplx s = msid__cconj(A[e * nu + (uint32_t)j]);   /* (Q^H)[j][e] */
            for (uint32_t k = (uint32_t)j + 1u; k < nu; ++k)
                s = msid__csub(s, msid__cmul(R[(uint32_t)j * nu + k], msid__cconj(W[e * nu + k])));
            const msid_cplx wh = msid__cdiv(s, R[(uint32_t)j * nu + (uint32_t)j]);  /* (W^H)[j][e] */
            W[e * nu + (uint32_t)j] = msid__cconj(wh);
        }
    }
}

/* Step: Ghat = Ybar W (González et al. 2025 eq. 37). */
static void estimate_g(const msid_frf *f, const frf_scratch *w, msid_cplx *G)
{
    const uint32_t nu = f->n_inputs, ny = f->n_outputs, m = f->n_experiments;
    for (uint32_t i = 0; i < ny; ++i)
        for (uint32_t j = 0; j < nu; ++j) {
            msid_cplx s = msid__c(0.0, 0.0);
            for (uint32_t e = 0; e < m; ++e) s = msid__cadd(s, msid__cmul(w->Y[i * m + e], w->W[e * nu + j]));
            G[i * nu + j] = s;
        }
}

/* Step: both covariances of line l, sum_e (w_e^T conj w_e) (x) S_e with S_e = B M2 B^H / ((K-1) K),
 * B = [-G I] (Pintelon 2002 eqs. 31-32), and with Sigma_p / K_e (González Thm 2, eq. 29); index
 * (i + ny j, i' + ny j'), exactly Hermitian. Returns the dof of the nonparametric one,
 * (sum c_e)^2 / sum c_e^2/(K_e - 1), c_e = |w_e|^2 / K_e. */
static double covariances(msid_frf *f, const msid_pstats *const *stats, uint32_t l, const frf_scratch *w)
{
    const uint32_t nu = f->n_inputs, ny = f->n_outputs, m = f->n_experiments, q = nu + ny, g = nu * ny;
    const msid_cplx *G = f->G + (size_t)l * g, *W = w->W, *Sp = w->Sp;
    msid_cplx *Ca = f->cov + (size_t)l * g * g, *Cb = f->cov_ki + (size_t)l * g * g, *T = w->T, *S = w->S;
    double cw[MSID_MAX_EXPERIMENTS], cmax = 0.0;   /* c_e = |w_e|^2 / K_e, for the dof */
    for (uint32_t e = 0; e < m; ++e) {
        const uint32_t Ke = msid_pstats_count(stats[e]);
        const msid_cplx *M2 = msid_pstats_scatter(stats[e], l);
        for (uint32_t i = 0; i < ny; ++i)
            for (uint32_t c = 0; c < q; ++c) {
                msid_cplx s = M2[(nu + i) * q + c];
                for (uint32_t j = 0; j < nu; ++j) s = msid__csub(s, msid__cmul(G[i * nu + j], M2[j * q + c]));
                T[i * q + c] = s;
            }
        const double sc = 1.0 / ((double)(Ke - 1u) * (double)Ke);
        for (uint32_t i = 0; i < ny; ++i)
            for (uint32_t k = 0; k < ny; ++k) {
                /* (T B^H)[i][k] = T[i][nu+k] - sum_j T[i][j] conj(G[k][j]) */
                msid_cplx s = T[i * q + nu + k];
                for (uint32_t j = 0; j < nu; ++j) s = msid__csub(s, msid__cmulc(T[i * q + j], G[k * nu + j]));
                S[i * ny + k] = msid__cscale(s, sc);
            }
        double wn = 0.0;
        for (uint32_t j = 0; j < nu; ++j) wn += msid__cabs2(W[e * nu + j]);
        cw[e] = wn / (double)Ke;
        cmax = fmax(cmax, cw[e]);
        /* upper triangle only (c >= r); mirrored below */
        for (uint32_t j = 0; j < nu; ++j)
            for (uint32_t jp = j; jp < nu; ++jp) {
                const msid_cplx ww = msid__cmulc(W[e * nu + j], W[e * nu + jp]);
                const msid_cplx wk = msid__cscale(ww, 1.0 / (double)Ke);
                for (uint32_t i = 0; i < ny; ++i)
                    for (uint32_t ip = (jp == j ? i : 0u); ip < ny; ++ip) {
                        const size_t r = i + (size_t)ny * j, c = ip + (size_t)ny * jp;
                        Ca[r * g + c] = msid__cadd(Ca[r * g + c], msid__cmul(ww, S[i * ny + ip]));
                        Cb[r * g + c] = msid__cadd(Cb[r * g + c], msid__cmul(wk, Sp[i * ny + ip]));
                    }
            }
    }
    /* exact Hermitian symmetry and real diagonal */
    for (uint32_t r = 0; r < g; ++r) {
        Ca[r * g + r].im = 0.0;
        Cb[r * g + r].im = 0.0;
        for (uint32_t c = r + 1u; c < g; ++c) {
            Ca[c * g + r] = msid__cconj(Ca[r * g + c]);
            Cb[c * g + r] = msid__cconj(Cb[r * g + c]);
        }
    }
    /* dof scale-free: formed from c_e / max c_e so that inputs scaled by 1e+-78 cannot overflow
       c_e^2 (the ratio is exact for one experiment) */
    double csum = 0.0, c2 = 0.0;
    for (uint32_t e = 0; e < m; ++e) {
        const double r = cmax > 0.0 ? cw[e] / cmax : 0.0;
        csum += r;
        c2 += r * r / (double)(msid_pstats_count(stats[e]) - 1u);
    }
    return csum * csum / c2;
}

/* Step: anything that still overflowed is a range error, never a NaN in a result. */
static int line_finite(const msid_frf *f, uint32_t l)
{
    const size_t g = (size_t)f->n_inputs * f->n_outputs, ny = f->n_outputs;
    const msid_cplx *G = f->G + l * g, *Ca = f->cov + l * g * g, *Cb = f->cov_ki + l * g * g;
    const msid_cplx *N = f->noise + l * ny * ny;
    int fin = msid__finite(f->dof[l]);
    for (size_t k = 0; k < g && fin; ++k) fin = msid__finite(G[k].re) && msid__finite(G[k].im);
    for (size_t k = 0; k < g * g && fin; ++k)
        fin = msid__finite(Ca[k].re) && msid__finite(Ca[k].im) && msid__finite(Cb[k].re) && msid__finite(Cb[k].im);
    for (size_t k = 0; k < ny * ny && fin; ++k) fin = msid__finite(N[k].re) && msid__finite(N[k].im);
    return fin;
}

/* Step: folding. The DT bin of a folded CT line carries G(-j w) = conj(G(j w)): report the CT value. */
static void fold_line(msid_frf *f, uint32_t l)
{
    const size_t g = (size_t)f->n_inputs * f->n_outputs, ny = f->n_outputs;
    msid_cplx *G = f->G + l * g, *Ca = f->cov + l * g * g, *Cb = f->cov_ki + l * g * g;
    msid_cplx *N = f->noise + l * ny * ny;
    for (size_t k = 0; k < g; ++k) G[k] = msid__cconj(G[k]);
    for (size_t k = 0; k < g * g; ++k) { Ca[k] = msid__cconj(Ca[k]); Cb[k] = msid__cconj(Cb[k]); }
    for (size_t k = 0; k < ny * ny; ++k) N[k] = msid__cconj(N[k]);
}

/* Step: detection lines, mean output spectrum, pooled variance, F(2m, 2n) test. */
static void detection_lines(msid_frf *f, const msid_pstats *const *stats, uint32_t dofk)
{
    const uint32_t nu = f->n_inputs, ny = f->n_outputs, m = f->n_experiments, q = nu + ny;
    for (uint32_t d = 0; d < f->n_detect; ++d) {
        const uint32_t l = f->n_lines + d;
        for (uint32_t i = 0; i < ny; ++i) {
            double var = 0.0, num = 0.0;
            for (uint32_t e = 0; e < m; ++e) {
                const msid_cplx *z = msid_pstats_mean(stats[e], l);
                const msid_cplx *M2 = msid_pstats_scatter(stats[e], l);
                f->dmean[((size_t)d * m + e) * ny + i] = z[nu + i];
                var += M2[(nu + i) * q + nu + i].re;
                num += (double)msid_pstats_count(stats[e]) * msid__cabs2(z[nu + i]);
            }
            var /= (double)dofk;
            f->dvar[(size_t)d * ny + i] = var;
            const double fs = var > 0.0 ? (num / (double)m) / var : (num > 0.0 ? HUGE_VAL : 0.0);
            f->dpval[(size_t)d * ny + i] = f_tail_2m_2n(m, dofk, fs);
        }
    }
}

msid_status msid_frf_compute(msid_frf *f, const msid_pstats *const *stats)
{
    if (!f || !stats) return MSID_E_NULL;
    const uint32_t ny = f->n_outputs, L = f->n_lines, g = f->n_inputs * ny;
    f->bad_line = -1;
    f->bad_experiment = -1;
    f->K_total = 0;
    uint32_t dofk = 0;
    msid_status ret = check_stats(f, stats, &dofk);
    if (ret != MSID_OK) return ret;
    const frf_scratch w = scratch_layout(f);
    for (uint32_t i = 0; i < ny * ny; ++i) f->noise_time[i] = msid__c(0.0, 0.0);
    double uscale;
    ret = input_scale(f, stats, &uscale);
    if (ret != MSID_OK) return ret;

    for (uint32_t l = 0; l < L; ++l) {
        msid_cplx *G = f->G + (size_t)l * g, *Ca = f->cov + (size_t)l * g * g, *Cb = f->cov_ki + (size_t)l * g * g;
        for (uint32_t k = 0; k < g * g; ++k) Ca[k] = Cb[k] = msid__c(0.0, 0.0);
        line_means(f, stats, l, &w);
        pooled_noise(f, stats, l, dofk, &w);
        output_snr(f, stats, l, &w);
        double smin, cond;
        const int ok = line_qr(f, &w, &smin, &cond);
        f->cond[l] = cond;
        const int unexcited = excitation_test(f, stats, l, smin, uscale);
        if (!ok || !(cond < 1e12) || unexcited) {
            f->line_status[l] = unexcited && ok ? MSID_LINE_UNEXCITED : MSID_LINE_SINGULAR;
            if (f->bad_line < 0) f->bad_line = (int32_t)l;
            ret = MSID_E_SINGULAR;
            for (uint32_t k = 0; k < g; ++k) G[k] = msid__c(NAN, NAN);
            f->dof[l] = f->dof_ki[l] = NAN;
            continue;
        }
        f->line_status[l] = MSID_LINE_OK;
        back_substitution(f, &w);
        estimate_g(f, &w, G);
        f->dof[l] = covariances(f, stats, l, &w);
        if (!line_finite(f, l) && ret == MSID_OK) { f->bad_line = (int32_t)l; ret = MSID_E_RANGE; }
        f->dof_ki[l] = (double)dofk;
        if (f->folded[l]) fold_line(f, l);
    }
    const double inv = 1.0 / ((double)L * (double)f->period);
    for (uint32_t i = 0; i < ny * ny; ++i) f->noise_time[i] = msid__cscale(f->noise_time[i], inv);
    detection_lines(f, stats, dofk);
    return ret;
}

const msid_cplx *msid_frf_G(const msid_frf *f, uint32_t l) { return f->G + (size_t)l * f->n_inputs * f->n_outputs; }
const msid_cplx *msid_frf_cov(const msid_frf *f, uint32_t l)
{
    const size_t g = (size_t)f->n_inputs * f->n_outputs;
    return f->cov + (size_t)l * g * g;
}
const msid_cplx *msid_frf_cov_known_input(const msid_frf *f, uint32_t l)
{
    const size_t g = (size_t)f->n_inputs * f->n_outputs;
    return f->cov_ki + (size_t)l * g * g;
}
double msid_frf_dof(const msid_frf *f, uint32_t l) { return f->dof[l]; }
double msid_frf_dof_known_input(const msid_frf *f, uint32_t l) { return f->dof_ki[l]; }
const msid_cplx *msid_frf_noise_cov(const msid_frf *f, uint32_t l) { return f->noise + (size_t)l * f->n_outputs * f->n_outputs; }
const double *msid_frf_snr_db(const msid_frf *f, uint32_t l) { return f->snr + (size_t)l * f->n_outputs; }
double msid_frf_cond(const msid_frf *f, uint32_t l) { return f->cond[l]; }
int msid_frf_line_status(const msid_frf *f, uint32_t l) { return f->line_status[l]; }
double msid_frf_input_snr_db(const msid_frf *f, uint32_t l) { return 10.0 * log10(f->usnr[l]); }
double msid_frf_input_rel_db(const msid_frf *f, uint32_t l) { return 10.0 * log10(f->urel[l]); }
const msid_cplx *msid_frf_noise_cov_time(const msid_frf *f) { return f->noise_time; }
const msid_cplx *msid_frf_detect_mean(const msid_frf *f, uint32_t d) { return f->dmean + (size_t)d * f->n_experiments * f->n_outputs; }
const double *msid_frf_detect_var(const msid_frf *f, uint32_t d) { return f->dvar + (size_t)d * f->n_outputs; }
const double *msid_frf_detect_pvalue(const msid_frf *f, uint32_t d) { return f->dpval + (size_t)d * f->n_outputs; }
