/* Monte Carlo harness for the FRF estimator: noiseless periodic records are
 * built once, fresh noise is added per run, every run goes through the real
 * core (msid_meas -> msid_frf), and the spread of the estimates is compared
 * with what the estimator reports. */
#ifndef MSID_MC_H
#define MSID_MC_H

#include "msid_test_sim.h"

#define MC_MAXG 16      /* ny*nu */
#define MC_MAXL 64

typedef struct mc_case mc_case;

/* Fill the noiseless rows [u; y] (K*P rows) of experiment e, and the true FRF (ny x nu) at line l. */
typedef void (*mc_clean_fn)(const mc_case *c, const tsim_design *t, uint32_t e, double *rows);
typedef void (*mc_truth_fn)(const mc_case *c, const tsim_design *t, uint32_t l, msid_cplx *G);

struct mc_case {
    const char *name;
    msid_design_cfg design;       /* twiddle filled by the harness */
    uint32_t ny, K, skip, R;
    uint64_t seed;
    double sigma_y, ar;           /* output innovation std; AR(1) pole (0: white) */
    double sigma_u;               /* input measurement noise std (0: exact) */
    double rho_uy;                /* correlation of input and output noise (EIV in a loop), 0..1 */
    mc_clean_fn clean;
    mc_truth_fn truth;
    const msid_plant_cfg *plant;  /* for the DT helpers */
    void *user;
    msid_transient_mode transient;
    uint32_t max_periods;
};

typedef struct mc_line {
    msid_cplx G0[MC_MAXG];
    msid_cplx mean[MC_MAXG];
    msid_cplx emp[MC_MAXG * MC_MAXG];     /* empirical covariance of vec(Ghat) around its mean */
    msid_cplx rep_a[MC_MAXG * MC_MAXG];   /* average reported nonparametric covariance */
    msid_cplx rep_b[MC_MAXG * MC_MAXG];   /* average reported known-input covariance */
    double dof_a, dof_b;                  /* average reported dof */
} mc_line;

typedef struct mc_result {
    uint32_t L, g, ny, nu, R;
    mc_line line[MC_MAXL];
    /* coverage of 95% regions, fraction over runs x lines x elements */
    double cov_elem_a, cov_elem_b;        /* scalar F(2, 2 dof) regions */
    double cov_row_b;                     /* per output row, F(2 nu, 2 dof) regions (known input) */
    double cov_naive_a;                   /* scalar chi2 (asymptotic) regions, for a negative control */
    uint32_t n_singular, n_fail;
    double mean_dropped;                  /* average transient-dropped periods per experiment */
} mc_result;

/* DT helpers: plant from c->plant, steady state by warm-up. */
void mc_clean_dt(const mc_case *c, const tsim_design *t, uint32_t e, double *rows);
void mc_truth_dt(const mc_case *c, const tsim_design *t, uint32_t l, msid_cplx *G);
/* Same plant started from rest: the first period carries the transient. */
void mc_clean_dt_from_rest(const mc_case *c, const tsim_design *t, uint32_t e, double *rows);

/* Run the Monte Carlo. Returns 0 on success. */
int mc_run(const mc_case *c, mc_result *res);

/* Checks with tolerances from Monte Carlo standard errors; print and count failures.
 * zmax: allowed |z| for bias and covariance checks. Returns the number of failures. */
int mc_check_bias(const mc_result *r, double zmax);
int mc_check_cov(const mc_result *r, int which /* 0: cov, 1: cov_known_input */, double zmax);
void mc_print(const char *name, const mc_result *r);

#endif
