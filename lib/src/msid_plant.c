/* Discrete-time state-space simulator. */
#include "msid/msid_plant.h"
#include "msid/msid_dmath.h"
#include "msid_internal.h"
#include "msid_cmat.h"

/* The one memory layout (see msid__layout): matrices (one spare element so that a
 * static gain, n = 0, still gets valid pointers), state, next state, workspace. */
static size_t layout(msid_plant *p, const msid_plant_cfg *c, void *mem)
{
    const size_t n = c->n_states, nu = c->n_inputs, ny = c->n_outputs;
    msid__layout y = msid__layout_begin(mem);
    p->A = (double *)msid__lay(&y, n * n + 1, sizeof(double));
    p->B = (double *)msid__lay(&y, n * nu + 1, sizeof(double));
    p->C = (double *)msid__lay(&y, ny * n + 1, sizeof(double));
    p->D = (double *)msid__lay(&y, ny * nu, sizeof(double));
    p->x = (double *)msid__lay(&y, n + 1, sizeof(double));
    p->xn = (double *)msid__lay(&y, n + 1, sizeof(double));
    p->work = (msid_cplx *)msid__lay(&y, n * (n + nu) + 1, sizeof(msid_cplx));
    return y.size;
}

size_t msid_plant_mem_size(const msid_plant_cfg *c)
{
    if (!c || c->n_states > MSID_MAX_STATES || c->n_inputs == 0 || c->n_inputs > MSID_MAX_CHANNELS ||
        c->n_outputs == 0 || c->n_outputs > MSID_MAX_CHANNELS) return 0;
    msid_plant tmp;
    return layout(&tmp, c, 0);
}

msid_status msid_plant_init(msid_plant *p, const msid_plant_cfg *c, void *mem, size_t len)
{
    if (!p || !c) return MSID_E_NULL;
    if (c->n_states > MSID_MAX_STATES || c->n_inputs == 0 || c->n_inputs > MSID_MAX_CHANNELS ||
        c->n_outputs == 0 || c->n_outputs > MSID_MAX_CHANNELS) return MSID_E_DIMS;
    const size_t n = c->n_states, nu = c->n_inputs, ny = c->n_outputs;
    if (n && (!c->A || !c->B || !c->C)) return MSID_E_NULL;
    const msid_status st = msid__mem_check(mem, len, msid_plant_mem_size(c));
    if (st != MSID_OK) return st;
    (void)layout(p, c, mem);
    p->n = (uint32_t)n; p->nu = (uint32_t)nu; p->ny = (uint32_t)ny;
    for (size_t k = 0; k < n * n; ++k) p->A[k] = c->A[k];
    for (size_t k = 0; k < n * nu; ++k) p->B[k] = c->B[k];
    for (size_t k = 0; k < ny * n; ++k) p->C[k] = c->C[k];
    for (size_t k = 0; k < ny * nu; ++k) p->D[k] = c->D ? c->D[k] : 0.0;
    for (size_t k = 0; k < n * n; ++k) if (!msid__finite(p->A[k])) return MSID_E_NOT_FINITE;
    for (size_t k = 0; k < n * nu; ++k) if (!msid__finite(p->B[k])) return MSID_E_NOT_FINITE;
    for (size_t k = 0; k < ny * n; ++k) if (!msid__finite(p->C[k])) return MSID_E_NOT_FINITE;
    for (size_t k = 0; k < ny * nu; ++k) if (!msid__finite(p->D[k])) return MSID_E_NOT_FINITE;
    msid_plant_set_state(p, 0);
    return MSID_OK;
}

void msid_plant_set_state(msid_plant *p, const double *x)
{
    for (uint32_t k = 0; k < p->n; ++k) p->x[k] = x ? x[k] : 0.0;
}

void msid_plant_step(msid_plant *p, const double *u, double *y)
{
    const uint32_t n = p->n, nu = p->nu, ny = p->ny;
    for (uint32_t i = 0; i < ny; ++i) {
        double s = 0.0;
        for (uint32_t k = 0; k < n; ++k) s += p->C[i * n + k] * p->x[k];
        for (uint32_t j = 0; j < nu; ++j) s += p->D[i * nu + j] * u[j];
        y[i] = s;
    }
    for (uint32_t i = 0; i < n; ++i) {
        double s = 0.0;
        for (uint32_t k = 0; k < n; ++k) s += p->A[i * n + k] * p->x[k];
        for (uint32_t j = 0; j < nu; ++j) s += p->B[i * nu + j] * u[j];
        p->xn[i] = s;
    }
    for (uint32_t i = 0; i < n; ++i) p->x[i] = p->xn[i];
}

msid_status msid_plant_frf(msid_plant *p, double f, msid_cplx *G)
{
    const uint32_t n = p->n, nu = p->nu, ny = p->ny;
    double zc, zs;
    msid_cis_turns(f, &zc, &zs);
    msid_cplx *M = p->work;            /* zI - A */
    msid_cplx *X = p->work + (size_t)n * n;  /* B, then (zI-A)^{-1} B */
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t k = 0; k < n; ++k)
            M[i * n + k] = msid__c((i == k ? zc : 0.0) - p->A[i * n + k], i == k ? zs : 0.0);
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t j = 0; j < nu; ++j) X[i * nu + j] = msid__c(p->B[i * nu + j], 0.0);
    if (n && !msid__csolve((int)n, M, (int)nu, X)) return MSID_E_SINGULAR;
    for (uint32_t i = 0; i < ny; ++i)
        for (uint32_t j = 0; j < nu; ++j) {
            msid_cplx s = msid__c(p->D[i * nu + j], 0.0);
            for (uint32_t k = 0; k < n; ++k) s = msid__cadd(s, msid__cscale(X[k * nu + j], p->C[i * n + k]));
            G[i * nu + j] = s;
        }
    return MSID_OK;
}
