#include "mc.h"
#include <math.h>
#include <stdio.h>
#include <string.h>

void mc_clean_dt(const mc_case *c, const tsim_design *t, uint32_t e, double *rows)
{
    tsim_bench b;
    tsim_bench_make(&b, c->plant, 200 * t->d.period > 20000 ? 200 * t->d.period : 20000);
    msid_rng rng;
    msid_rng_seed(&rng, 1);   /* sigma = 0: rng unused */
    tsim_run(&b, t, e, c->K, &rng, rows);
    tsim_bench_free(&b);
}

void mc_clean_dt_from_rest(const mc_case *c, const tsim_design *t, uint32_t e, double *rows)
{
    tsim_bench b;
    tsim_bench_make(&b, c->plant, 0);
    msid_rng rng;
    msid_rng_seed(&rng, 1);
    tsim_run(&b, t, e, c->K, &rng, rows);
    tsim_bench_free(&b);
}

void mc_truth_dt(const mc_case *c, const tsim_design *t, uint32_t l, msid_cplx *G)
{
    size_t n = msid_plant_mem_size(c->plant);
    void *m = tsim_alloc(n);
    msid_plant p;
    msid_plant_init(&p, c->plant, m, n);
    msid_plant_frf(&p, (double)t->d.bins[l] / t->d.period, G);
    tsim_free(m);
}

int mc_run(const mc_case *c, mc_result *res)
{
    memset(res, 0, sizeof(*res));
    tsim_design t;
    if (tsim_design_make(&t, &c->design) != MSID_OK) { printf("%s: design failed\n", c->name); return 1; }
    const uint32_t P = t.d.period, L = t.d.n_lines, nu = t.d.n_inputs, ny = c->ny, m = t.d.n_experiments;
    const uint32_t C = nu + ny, g = nu * ny, K = c->K;
    if (L > MC_MAXL || g > MC_MAXG) return 1;
    res->L = L; res->g = g; res->ny = ny; res->nu = nu; res->R = c->R;
    const size_t nrow = (size_t)K * P * C;
    double *clean = tsim_alloc(sizeof(double) * nrow * m), *rows = tsim_alloc(sizeof(double) * nrow);
    for (uint32_t e = 0; e < m; ++e) c->clean(c, &t, e, clean + e * nrow);
    for (uint32_t l = 0; l < L; ++l) c->truth(c, &t, l, res->line[l].G0);

    msid_meas_cfg mc = {0};
    mc.period = P; mc.n_inputs = nu; mc.n_outputs = ny; mc.n_experiments = m;
    mc.n_lines = L; mc.bins = t.d.bins; mc.twiddle = &t.tw; mc.path = MSID_DFT_STREAM;
    mc.skip_periods = c->skip; mc.transient = c->transient; mc.max_periods = c->max_periods;
    size_t nm = msid_meas_mem_size(&mc);
    void *mm = tsim_alloc(nm);
    msid_frf_cfg fc = {P, nu, ny, m, L, 0, t.d.folded};
    size_t nf = msid_frf_mem_size(&fc);
    void *fm = tsim_alloc(nf);
    msid_meas ms;
    msid_frf f;

    /* thresholds */
    msid_rng rng;
    msid_rng_seed(&rng, c->seed);
    const double a_sd = c->ar != 0.0 ? c->sigma_y / sqrt(1.0 - c->ar * c->ar) : 0.0;
    double *acc_sum = tsim_alloc(sizeof(double) * 2 * L * g);            /* sum of Ghat */
    double *acc_sq = tsim_alloc(sizeof(double) * 2 * L * g * g);        /* sum of Ghat Ghat^H */
    uint64_t in_a = 0, in_b = 0, in_row = 0, in_naive = 0, n_elem = 0, n_row = 0;
    uint64_t dropped = 0;
    uint32_t fq1_n = 0;
    double fq1 = 0.0;
    for (uint32_t r = 0; r < c->R; ++r) {
        msid_meas_init(&ms, &mc, mm, nm);
        for (uint32_t e = 0; e < m; ++e) {
            const double *cl = clean + e * nrow;
            double xs[MSID_MAX_OUTPUTS];
            for (uint32_t i = 0; i < ny; ++i) xs[i] = a_sd * msid_rng_normal(&rng);   /* stationary AR(1) start */
            for (size_t k = 0; k < (size_t)K * P; ++k) {
                double nuv[MSID_MAX_INPUTS];
                for (uint32_t j = 0; j < nu; ++j) {
                    nuv[j] = c->sigma_u > 0 ? c->sigma_u * msid_rng_normal(&rng) : 0.0;
                    rows[k * C + j] = cl[k * C + j] + nuv[j];
                }
                for (uint32_t i = 0; i < ny; ++i) {
                    double ev = c->sigma_y * msid_rng_normal(&rng);
                    if (c->rho_uy != 0.0 && c->sigma_u > 0)   /* output noise partly driven by input noise */
                        ev = c->rho_uy * (c->sigma_y / c->sigma_u) * nuv[i % nu] + sqrt(1 - c->rho_uy * c->rho_uy) * ev;
                    double v = ev;
                    if (c->ar != 0.0) { v = c->ar * xs[i] + ev; xs[i] = v; }
                    rows[k * C + nu + i] = cl[k * C + nu + i] + v;
                }
            }
            msid_meas_begin(&ms, e);
            msid_meas_push(&ms, rows, (size_t)K * P);
            msid_meas_end(&ms, 0);
            dropped += msid_pstats_get_counts(msid_meas_stats(&ms, e)).transient_dropped;
        }
        msid_frf_init(&f, &fc, fm, nf);
        const msid_pstats *ps[MSID_MAX_EXPERIMENTS];
        for (uint32_t e = 0; e < m; ++e) ps[e] = msid_meas_stats(&ms, e);
        msid_status st = msid_frf_compute(&f, ps);
        if (st == MSID_E_SINGULAR) { res->n_singular++; continue; }
        if (st != MSID_OK) { res->n_fail++; continue; }
        for (uint32_t l = 0; l < L; ++l) {
            mc_line *ln = &res->line[l];
            const msid_cplx *G = msid_frf_G(&f, l), *Ca = msid_frf_cov(&f, l), *Cb = msid_frf_cov_known_input(&f, l);
            const double na = msid_frf_dof(&f, l), nb = msid_frf_dof_known_input(&f, l);
            ln->dof_a += na; ln->dof_b += nb;
            msid_cplx v[MC_MAXG];
            for (uint32_t j = 0; j < nu; ++j)
                for (uint32_t i = 0; i < ny; ++i) v[i + ny * j] = G[i * nu + j];
            for (uint32_t a = 0; a < g; ++a) {
                acc_sum[2 * (l * g + a)] += v[a].re;
                acc_sum[2 * (l * g + a) + 1] += v[a].im;
                for (uint32_t b = 0; b < g; ++b) {
                    /* v_a conj(v_b) */
                    acc_sq[2 * ((l * g + a) * g + b)] += v[a].re * v[b].re + v[a].im * v[b].im;
                    acc_sq[2 * ((l * g + a) * g + b) + 1] += v[a].im * v[b].re - v[a].re * v[b].im;
                    ln->rep_a[a * g + b].re += Ca[a * g + b].re; ln->rep_a[a * g + b].im += Ca[a * g + b].im;
                    ln->rep_b[a * g + b].re += Cb[a * g + b].re; ln->rep_b[a * g + b].im += Cb[a * g + b].im;
                }
            }
            /* coverage: scalar elements */
            double fa = na * (pow(0.05, -1.0 / na) - 1.0), fb = nb * (pow(0.05, -1.0 / nb) - 1.0);
            if (t.d.bins[l] == 0u) {   /* DC line: real, (Ghat - G)^2 / v ~ F(1, n) */
                if (!fq1_n || fq1_n != (uint32_t)(na + 0.5)) { fq1_n = (uint32_t)(na + 0.5); fq1 = tsim_f1quant(fq1_n, 0.05); }
                fa = fb = fq1;
            }
            const double chi = -log(0.05);   /* |e|^2/v ~ Exp(1) asymptotically */
            for (uint32_t a = 0; a < g; ++a) {
                const uint32_t i = a % ny, j = a / ny;
                const double er = v[a].re - ln->G0[i * nu + j].re, ei = v[a].im - ln->G0[i * nu + j].im;
                const double e2 = er * er + ei * ei;
                in_a += e2 <= fa * Ca[a * g + a].re;
                in_b += e2 <= fb * Cb[a * g + a].re;
                in_naive += e2 <= chi * Ca[a * g + a].re;
                n_elem++;
            }
            /* coverage: output rows with the known-input covariance, F(2nu, 2nb) */
            const uint32_t nbi = (uint32_t)(nb + 0.5);
            const double frow = tsim_fquant(nu, nbi, 0.05);
            for (uint32_t i = 0; i < ny; ++i) {
                /* Q = x S^{-1} x^H with S = row block of Cb (nu x nu) */
                msid_cplx S[MSID_MAX_INPUTS * MSID_MAX_INPUTS], x[MSID_MAX_INPUTS];
                for (uint32_t j = 0; j < nu; ++j) {
                    x[j].re = v[i + ny * j].re - ln->G0[i * nu + j].re;
                    x[j].im = v[i + ny * j].im - ln->G0[i * nu + j].im;
                    for (uint32_t jp = 0; jp < nu; ++jp) S[j * nu + jp] = Cb[(i + ny * j) * g + (i + ny * jp)];
                }
                /* solve S y = x (Gaussian elimination, small) then Q = x^H y */
                msid_cplx yv[MSID_MAX_INPUTS];
                for (uint32_t j = 0; j < nu; ++j) yv[j] = x[j];
                for (uint32_t k = 0; k < nu; ++k) {
                    const msid_cplx pk = S[k * nu + k];
                    const double den = pk.re * pk.re + pk.im * pk.im;
                    for (uint32_t r2 = k + 1; r2 < nu; ++r2) {
                        const msid_cplx a2 = S[r2 * nu + k];
                        const msid_cplx fct = {(a2.re * pk.re + a2.im * pk.im) / den, (a2.im * pk.re - a2.re * pk.im) / den};
                        for (uint32_t cc = k; cc < nu; ++cc) {
                            const msid_cplx s = S[k * nu + cc];
                            S[r2 * nu + cc].re -= fct.re * s.re - fct.im * s.im;
                            S[r2 * nu + cc].im -= fct.re * s.im + fct.im * s.re;
                        }
                        yv[r2].re -= fct.re * yv[k].re - fct.im * yv[k].im;
                        yv[r2].im -= fct.re * yv[k].im + fct.im * yv[k].re;
                    }
                }
                for (int k = (int)nu - 1; k >= 0; --k) {
                    msid_cplx s = yv[k];
                    for (uint32_t cc = (uint32_t)k + 1; cc < nu; ++cc) {
                        s.re -= S[k * nu + cc].re * yv[cc].re - S[k * nu + cc].im * yv[cc].im;
                        s.im -= S[k * nu + cc].re * yv[cc].im + S[k * nu + cc].im * yv[cc].re;
                    }
                    const msid_cplx pk = S[k * nu + k];
                    const double den = pk.re * pk.re + pk.im * pk.im;
                    yv[k].re = (s.re * pk.re + s.im * pk.im) / den;
                    yv[k].im = (s.im * pk.re - s.re * pk.im) / den;
                }
                double Q = 0.0;
                for (uint32_t j = 0; j < nu; ++j) Q += x[j].re * yv[j].re + x[j].im * yv[j].im;
                in_row += Q <= nu * frow;
                n_row++;
            }
        }
    }
    const double Rn = (double)(c->R - res->n_singular - res->n_fail);
    for (uint32_t l = 0; l < L; ++l) {
        mc_line *ln = &res->line[l];
        ln->dof_a /= Rn; ln->dof_b /= Rn;
        for (uint32_t a = 0; a < g; ++a) {
            ln->mean[a].re = acc_sum[2 * (l * g + a)] / Rn;
            ln->mean[a].im = acc_sum[2 * (l * g + a) + 1] / Rn;
        }
        for (uint32_t a = 0; a < g; ++a)
            for (uint32_t b = 0; b < g; ++b) {
                const msid_cplx ma = ln->mean[a], mb = ln->mean[b];
                /* E[v_a conj v_b] - m_a conj m_b, with the R-1 correction */
                double re = acc_sq[2 * ((l * g + a) * g + b)] / Rn - (ma.re * mb.re + ma.im * mb.im);
                double im = acc_sq[2 * ((l * g + a) * g + b) + 1] / Rn - (ma.im * mb.re - ma.re * mb.im);
                ln->emp[a * g + b].re = re * Rn / (Rn - 1);
                ln->emp[a * g + b].im = im * Rn / (Rn - 1);
                ln->rep_a[a * g + b].re /= Rn; ln->rep_a[a * g + b].im /= Rn;
                ln->rep_b[a * g + b].re /= Rn; ln->rep_b[a * g + b].im /= Rn;
            }
    }
    res->cov_elem_a = (double)in_a / n_elem;
    res->cov_elem_b = (double)in_b / n_elem;
    res->cov_naive_a = (double)in_naive / n_elem;
    res->cov_row_b = (double)in_row / n_row;
    res->mean_dropped = (double)dropped / ((double)c->R * m);
    tsim_free(acc_sum); tsim_free(acc_sq); tsim_free(mm); tsim_free(fm);
    tsim_free(clean); tsim_free(rows);
    tsim_design_free(&t);
    return 0;
}

int mc_check_bias(const mc_result *r, double zmax)
{
    int bad = 0;
    double worst = 0;
    for (uint32_t l = 0; l < r->L; ++l)
        for (uint32_t a = 0; a < r->g; ++a) {
            const mc_line *ln = &r->line[l];
            const uint32_t i = a % r->ny, j = a / r->ny;
            const double se = sqrt(ln->emp[a * r->g + a].re / 2.0 / r->R);   /* per real component */
            const double zr = (ln->mean[a].re - ln->G0[i * r->nu + j].re) / se;
            const double zi = (ln->mean[a].im - ln->G0[i * r->nu + j].im) / se;
            if (fabs(zr) > worst) worst = fabs(zr);
            if (fabs(zi) > worst) worst = fabs(zi);
            if (fabs(zr) > zmax || fabs(zi) > zmax) {
                printf("  bias: line %u elem %u z = (%.2f, %.2f)\n", l, a, zr, zi);
                bad++;
            }
        }
    printf("  bias: worst |z| = %.2f (limit %.1f)\n", worst, zmax);
    return bad;
}

int mc_check_cov(const mc_result *r, int which, double zmax)
{
    int bad = 0;
    const uint32_t g = r->g;
    double worst = 0, pooled = 0;
    uint32_t npool = 0;
    for (uint32_t l = 0; l < r->L; ++l) {
        const mc_line *ln = &r->line[l];
        const msid_cplx *rep = which ? ln->rep_b : ln->rep_a;
        for (uint32_t a = 0; a < g; ++a)
            for (uint32_t b = a; b < g; ++b) {
                /* relative SE of a complex sample (co)variance from R runs ~ 1/sqrt(R),
                 * normalised by sqrt(var_a var_b) */
                const double sc = sqrt(rep[a * g + a].re * rep[b * g + b].re);
                const double dre = (ln->emp[a * g + b].re - rep[a * g + b].re) / sc;
                const double dim = (ln->emp[a * g + b].im - rep[a * g + b].im) / sc;
                const double z = sqrt((double)r->R) * (a == b ? fabs(dre) : sqrt(2.0) * fmax(fabs(dre), fabs(dim)));
                if (z > worst) worst = z;
                if (a == b) { pooled += ln->emp[a * g + a].re / rep[a * g + a].re; npool++; }
                if (z > zmax) {
                    printf("  cov%s: line %u (%u,%u) emp %.4g%+.4gj rep %.4g%+.4gj z %.2f\n", which ? "_ki" : "", l, a, b,
                           ln->emp[a * g + b].re, ln->emp[a * g + b].im, rep[a * g + b].re, rep[a * g + b].im, z);
                    bad++;
                }
            }
    }
    pooled /= npool;
    /* pooled ratio over independent lines: SE about 1/sqrt(R * lines) */
    const double zp = fabs(pooled - 1.0) * sqrt((double)r->R * r->L);
    printf("  cov%s: worst element z = %.2f (limit %.1f); pooled emp/reported variance = %.4f (z = %.2f)\n",
           which ? "_known_input" : "", worst, zmax, pooled, zp);
    if (zp > zmax) bad++;
    return bad;
}

void mc_print(const char *name, const mc_result *r)
{
    printf("[%s] R=%u lines=%u g=%u dof_a=%.2f dof_b=%.2f coverage: elem(cov)=%.4f elem(cov_ki)=%.4f "
           "row(cov_ki)=%.4f naive-chi2(cov)=%.4f singular=%u fail=%u dropped/exp=%.3f\n",
           name, r->R, r->L, r->g, r->line[0].dof_a, r->line[0].dof_b, r->cov_elem_a, r->cov_elem_b, r->cov_row_b,
           r->cov_naive_a, r->n_singular, r->n_fail, r->mean_dropped);
}
