/* Small dense complex/real matrix kernels used inside the core (private).
 * Row-major storage. All work memory is passed in by the caller. */
#ifndef MSID_CMAT_H
#define MSID_CMAT_H

#include "msid/msid_types.h"

static inline msid_cplx msid__c(double re, double im) { msid_cplx z; z.re = re; z.im = im; return z; }
static inline msid_cplx msid__cadd(msid_cplx a, msid_cplx b) { return msid__c(a.re + b.re, a.im + b.im); }
static inline msid_cplx msid__csub(msid_cplx a, msid_cplx b) { return msid__c(a.re - b.re, a.im - b.im); }
static inline msid_cplx msid__cmul(msid_cplx a, msid_cplx b)
{
    return msid__c(a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re);
}
/* a * conj(b) */
static inline msid_cplx msid__cmulc(msid_cplx a, msid_cplx b)
{
    return msid__c(a.re * b.re + a.im * b.im, a.im * b.re - a.re * b.im);
}
static inline msid_cplx msid__cconj(msid_cplx a) { return msid__c(a.re, -a.im); }
static inline double msid__cabs2(msid_cplx a) { return a.re * a.re + a.im * a.im; }
static inline msid_cplx msid__cscale(msid_cplx a, double s) { return msid__c(a.re * s, a.im * s); }
msid_cplx msid__cdiv(msid_cplx a, msid_cplx b);

/* Eigenvalues of a real symmetric n x n matrix by cyclic Jacobi.
 * a is overwritten; eig receives n values (unsorted). n <= 64. */
void msid__sym_eig(int n, double *a, double *eig);

/* Singular values of a complex r x c matrix A (r >= c), via the eigenvalues
 * of the 2c x 2c real embedding of A^H A. work: 4*c*c doubles + c doubles
 * for eig output separately. Returns smallest and largest singular value. */
void msid__csv_minmax(int r, int c, const msid_cplx *a, double *work, double *smin, double *smax);

/* Thin QR of the complex r x c matrix A (r >= c) by modified Gram-Schmidt
 * with one reorthogonalisation. Q (r x c) overwrites A; R (c x c, upper) is
 * written to r_out. Returns 0 if a column is numerically dependent
 * (|r_jj| <= tol * max column norm), else 1. */
int msid__cqr(int r, int c, msid_cplx *a, msid_cplx *r_out, double tol);

/* Solve A X = B in place for square complex A (n x n) with nrhs right-hand
 * sides in B (n x nrhs), Gaussian elimination with partial pivoting.
 * A is destroyed. Returns 0 if singular. */
int msid__csolve(int n, msid_cplx *a, int nrhs, msid_cplx *b);

#endif
