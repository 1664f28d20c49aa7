#define _POSIX_C_SOURCE 200112L
#include "msid_test_sim.h"
#include <math.h>
#include <string.h>

void *tsim_alloc(size_t n)
{
    void *p = 0;
    if (n == 0) n = MSID_MEM_ALIGN;
    if (posix_memalign(&p, MSID_MEM_ALIGN, (n + MSID_MEM_ALIGN - 1) & ~(size_t)(MSID_MEM_ALIGN - 1))) return 0;
    memset(p, 0, n);
    return p;
}
void tsim_free(void *p) { free(p); }

msid_status tsim_design_make(tsim_design *t, const msid_design_cfg *c0)
{
    memset(t, 0, sizeof(*t));
    size_t n = msid_twiddle_mem_size(c0->period);
    t->mem_tw = tsim_alloc(n);
    msid_status st = msid_twiddle_init(&t->tw, c0->period, t->mem_tw, n);
    if (st != MSID_OK) return st;
    msid_design_cfg c = *c0;
    c.twiddle = &t->tw;
    n = msid_design_mem_size(&c);
    t->mem_d = tsim_alloc(n);
    return msid_design_init(&t->d, &c, t->mem_d, n);
}
void tsim_design_free(tsim_design *t) { tsim_free(t->mem_tw); tsim_free(t->mem_d); }

msid_status tsim_bench_make(tsim_bench *b, const msid_plant_cfg *pc, uint32_t warmup)
{
    memset(b, 0, sizeof(*b));
    size_t n = msid_plant_mem_size(pc);
    b->mem_plant = tsim_alloc(n);
    b->warmup = warmup;
    return msid_plant_init(&b->plant, pc, b->mem_plant, n);
}

msid_status tsim_bench_color(tsim_bench *b, double a)
{
    const double A[1] = {a}, B[1] = {1.0}, C[1] = {a}, D[1] = {1.0};
    /* y(n) = e(n) + a y(n-1): x(n+1) = a x + e, y = a x + e  => y = e/(1 - a q^-1) */
    msid_plant_cfg c = {1, 1, 1, A, B, C, D};
    for (uint32_t i = 0; i < b->plant.ny; ++i) {
        size_t n = msid_plant_mem_size(&c);
        b->mem_noise[i] = tsim_alloc(n);
        msid_status st = msid_plant_init(&b->noise[i], &c, b->mem_noise[i], n);
        if (st != MSID_OK) return st;
    }
    b->colored = 1;
    return MSID_OK;
}

void tsim_bench_free(tsim_bench *b)
{
    tsim_free(b->mem_plant);
    for (uint32_t i = 0; i < MSID_MAX_OUTPUTS; ++i) if (b->mem_noise[i]) tsim_free(b->mem_noise[i]);
}

void tsim_run(tsim_bench *b, const tsim_design *t, uint32_t e, uint32_t K, msid_rng *rng, double *rows)
{
    const uint32_t nu = b->plant.nu, ny = b->plant.ny, P = t->d.period, C = nu + ny;
    msid_gen g;
    msid_gen_cfg gc = {&t->d, &t->tw, e, 0};
    size_t n = msid_gen_mem_size(&gc);
    void *mem = tsim_alloc(n);
    msid_gen_init(&g, &gc, mem, n);
    double u[MSID_MAX_INPUTS], y[MSID_MAX_OUTPUTS];
    msid_plant_set_state(&b->plant, 0);
    for (uint32_t i = 0; i < ny && b->colored; ++i) msid_plant_set_state(&b->noise[i], 0);
    /* warm-up: start the generator so that recording begins at period phase 0 */
    const uint64_t w = b->warmup;
    msid_gen_seek(&g, (P - (uint32_t)(w % P)) % P);
    for (uint64_t k = 0; k < w; ++k) {
        msid_gen_next(&g, u);
        msid_plant_step(&b->plant, u, y);
        for (uint32_t i = 0; i < ny && b->colored; ++i) {
            double ev = msid_rng_normal(rng) * b->sigma_y[i], v;
            msid_plant_step(&b->noise[i], &ev, &v);
        }
    }
    for (uint64_t k = 0; k < (uint64_t)K * P; ++k) {
        double *row = rows + k * C;
        msid_gen_next(&g, u);
        msid_plant_step(&b->plant, u, y);
        for (uint32_t j = 0; j < nu; ++j) row[j] = u[j] + (b->sigma_u[j] > 0 ? b->sigma_u[j] * msid_rng_normal(rng) : 0.0);
        for (uint32_t i = 0; i < ny; ++i) {
            double ev = msid_rng_normal(rng) * b->sigma_y[i], v = ev;
            if (b->colored) msid_plant_step(&b->noise[i], &ev, &v);
            row[nu + i] = y[i] + v;
        }
    }
    tsim_free(mem);
}

/* P(F(2a,2b) > f) = I_x(b, a), x = b/(b + a f); I_x(p, q) for integer p, q:
 * sum_{j=p}^{p+q-1} C(p+q-1, j) x^j (1-x)^{p+q-1-j}. */
double tsim_ftail(uint32_t a, uint32_t b, double f)
{
    if (!(f > 0)) return 1.0;
    const double x = (double)b / ((double)b + (double)a * f);
    const uint32_t p = b, q = a, N = p + q - 1;
    double s = 0.0;
    for (uint32_t j = p; j <= N; ++j) {
        const double lc = lgamma((double)N + 1) - lgamma((double)j + 1) - lgamma((double)(N - j) + 1);
        s += exp(lc + j * log(x) + (N - j) * log1p(-x));
    }
    return s > 1 ? 1 : s;
}

double tsim_fquant(uint32_t a, uint32_t b, double alpha)
{
    double lo = 0.0, hi = 1.0;
    while (tsim_ftail(a, b, hi) > alpha) hi *= 2.0;
    for (int it = 0; it < 200; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (tsim_ftail(a, b, mid) > alpha) lo = mid; else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* Student t density integrated with Simpson's rule on [0, sqrt(f)]: independent of
 * the closed forms used in the library. */
double tsim_f1tail(uint32_t n, double f)
{
    if (!(f > 0)) return 1.0;
    const double t = sqrt(f), nn = (double)n;
    const double c = exp(lgamma((nn + 1) / 2) - lgamma(nn / 2)) / sqrt(nn * M_PI);
    const int N = 20000;
    const double hs = t / N;
    double sum = 0.0;
    for (int k = 0; k <= N; ++k) {
        const double x = k * hs, w = (k == 0 || k == N) ? 1.0 : (k % 2 ? 4.0 : 2.0);
        sum += w * c * pow(1.0 + x * x / nn, -(nn + 1) / 2);
    }
    const double p = 1.0 - 2.0 * sum * hs / 3.0;
    return p < 0 ? 0 : p;
}

double tsim_f1quant(uint32_t n, double alpha)
{
    double lo = 0.0, hi = 1.0;
    while (tsim_f1tail(n, hi) > alpha) hi *= 2.0;
    for (int it = 0; it < 60; ++it) {
        const double mid = 0.5 * (lo + hi);
        if (tsim_f1tail(n, mid) > alpha) lo = mid; else hi = mid;
    }
    return 0.5 * (lo + hi);
}
