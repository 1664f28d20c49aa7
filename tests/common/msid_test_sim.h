/* Shared test helpers: simulate multisine experiments on a known plant and
 * run them through the core; F-distribution tails for coverage checks. */
#ifndef MSID_TEST_SIM_H
#define MSID_TEST_SIM_H

#include "msid/msid.h"
#include <stdlib.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846264338327950288
#endif

/* Aligned heap block for tests (the core itself never allocates). */
void *tsim_alloc(size_t n);
void tsim_free(void *p);

/* Owned design + twiddle. */
typedef struct tsim_design {
    msid_twiddle tw;
    msid_design d;
    void *mem_tw, *mem_d;
} tsim_design;
msid_status tsim_design_make(tsim_design *t, const msid_design_cfg *cfg_without_twiddle);
void tsim_design_free(tsim_design *t);

/* A simulated bench: plant, noise filters, input noise. */
typedef struct tsim_bench {
    msid_plant plant;          /* nu -> ny */
    void *mem_plant;
    int colored;               /* 1: output noise through `noise` filters */
    msid_plant noise[MSID_MAX_OUTPUTS];
    void *mem_noise[MSID_MAX_OUTPUTS];
    double sigma_y[MSID_MAX_OUTPUTS];   /* white innovation std per output */
    double sigma_u[MSID_MAX_INPUTS];    /* measurement noise std on each input (0: exact) */
    uint32_t warmup;           /* samples simulated before recording (steady state) */
} tsim_bench;
msid_status tsim_bench_make(tsim_bench *b, const msid_plant_cfg *plant, uint32_t warmup);
/* First-order AR colouring y = e / (1 - a q^-1) on every output. */
msid_status tsim_bench_color(tsim_bench *b, double a);
void tsim_bench_free(tsim_bench *b);

/* Produce the rows [u_meas; y] of K periods of experiment e into rows (K*P*(nu+ny)). */
void tsim_run(tsim_bench *b, const tsim_design *t, uint32_t e, uint32_t K, msid_rng *rng, double *rows);

/* Upper tail P(F(2a, 2b) > f) for integers a, b >= 1 (exact finite sum). */
double tsim_ftail(uint32_t a, uint32_t b, double f);
/* Quantile: f such that P(F(2a,2b) > f) = alpha. */
double tsim_fquant(uint32_t a, uint32_t b, double alpha);
/* Real case: P(F(1, n) > f) (two-sided Student t, by numerical integration) and its quantile. */
double tsim_f1tail(uint32_t n, double f);
double tsim_f1quant(uint32_t n, double alpha);

#endif
