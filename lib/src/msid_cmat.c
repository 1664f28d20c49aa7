/* Small dense matrix kernels (private to the core). */
#include "msid_cmat.h"
#include <math.h>

msid_cplx msid__cdiv(msid_cplx a, msid_cplx b)
{
    /* Smith's algorithm: avoids overflow in |b|^2. */
    if (fabs(b.re) >= fabs(b.im)) {
        const double r = b.im / b.re, d = b.re + b.im * r;
        return msid__c((a.re + a.im * r) / d, (a.im - a.re * r) / d);
    }
    const double r = b.re / b.im, d = b.re * r + b.im;
    return msid__c((a.re * r + a.im) / d, (a.im * r - a.re) / d);
}

void msid__sym_eig(int n, double *a, double *eig)
{
    for (int sweep = 0; sweep < 60; ++sweep) {
        double off = 0.0, dia = 0.0;
        for (int i = 0; i < n; ++i) {
            dia += a[i * n + i] * a[i * n + i];
            for (int j = i + 1; j < n; ++j) off += a[i * n + j] * a[i * n + j];
        }
        if (off <= 1e-32 * dia || off == 0.0) break;
        for (int p = 0; p < n; ++p) {
            for (int q = p + 1; q < n; ++q) {
                const double apq = a[p * n + q];
                if (apq == 0.0) continue;
                const double app = a[p * n + p], aqq = a[q * n + q];
                const double theta = (aqq - app) / (2.0 * apq);
                const double t = (theta >= 0.0 ? 1.0 : -1.0) /
                                 (fabs(theta) + sqrt(theta * theta + 1.0));
                const double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < n; ++k) {
                    const double akp = a[k * n + p], akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; ++k) {
                    const double apk = a[p * n + k], aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
            }
        }
    }
    for (int i = 0; i < n; ++i) eig[i] = a[i * n + i];
}

void msid__csv_minmax(int r, int c, const msid_cplx *a, double *work, double *smin, double *smax)
{
    /* H = A^H A (c x c Hermitian) embedded as [[Re H, -Im H], [Im H, Re H]];
     * each eigenvalue of H appears twice in the embedding. */
    const int n2 = 2 * c;
    double *e = work;              /* n2 x n2 */
    double *eig = work + n2 * n2;  /* n2 */
    for (int i = 0; i < c; ++i) {
        for (int j = 0; j < c; ++j) {
            double hr = 0.0, hi = 0.0;
            for (int k = 0; k < r; ++k) {
                const msid_cplx x = a[k * c + i], y = a[k * c + j];
                /* conj(x) * y */
                hr += x.re * y.re + x.im * y.im;
                hi += x.re * y.im - x.im * y.re;
            }
            e[i * n2 + j] = hr;
            e[(i + c) * n2 + (j + c)] = hr;
            e[i * n2 + (j + c)] = -hi;
            e[(i + c) * n2 + j] = hi;
        }
    }
    msid__sym_eig(n2, e, eig);
    double lo = eig[0], hi = eig[0];
    for (int i = 1; i < n2; ++i) {
        if (eig[i] < lo) lo = eig[i];
        if (eig[i] > hi) hi = eig[i];
    }
    *smin = lo > 0.0 ? sqrt(lo) : 0.0;
    *smax = hi > 0.0 ? sqrt(hi) : 0.0;
}

int msid__cqr(int r, int c, msid_cplx *a, msid_cplx *rr, double tol)
{
    double maxnorm = 0.0;
    for (int j = 0; j < c; ++j) {
        double s = 0.0;
        for (int k = 0; k < r; ++k) s += msid__cabs2(a[k * c + j]);
        if (s > maxnorm) maxnorm = s;
    }
    maxnorm = sqrt(maxnorm);
    for (int i = 0; i < c * c; ++i) rr[i] = msid__c(0.0, 0.0);
    int ok = 1;
    for (int j = 0; j < c; ++j) {
        for (int pass = 0; pass < 2; ++pass) {
            for (int i = 0; i < j; ++i) {
                /* proj = q_i^H a_j */
                msid_cplx p = msid__c(0.0, 0.0);
                for (int k = 0; k < r; ++k) p = msid__cadd(p, msid__cmulc(a[k * c + j], a[k * c + i]));
                /* p computed as sum a_j * conj(q_i) = conj(q_i^H a_j)?  a*conj(b): sum a_kj conj(q_ki) = q_i^H a_j */
                for (int k = 0; k < r; ++k) a[k * c + j] = msid__csub(a[k * c + j], msid__cmul(p, a[k * c + i]));
                rr[i * c + j] = msid__cadd(rr[i * c + j], p);
            }
        }
        double nrm = 0.0;
        for (int k = 0; k < r; ++k) nrm += msid__cabs2(a[k * c + j]);
        nrm = sqrt(nrm);
        rr[j * c + j] = msid__c(nrm, 0.0);
        if (!(nrm > tol * maxnorm) || maxnorm == 0.0) {
            ok = 0;
            nrm = nrm > 0.0 ? nrm : 1.0;
        }
        const double inv = 1.0 / nrm;
        for (int k = 0; k < r; ++k) a[k * c + j] = msid__cscale(a[k * c + j], inv);
    }
    return ok;
}

int msid__csolve(int n, msid_cplx *a, int nrhs, msid_cplx *b)
{
    for (int k = 0; k < n; ++k) {
        int piv = k;
        double best = msid__cabs2(a[k * n + k]);
        for (int i = k + 1; i < n; ++i) {
            const double v = msid__cabs2(a[i * n + k]);
            if (v > best) { best = v; piv = i; }
        }
        if (!(best > 0.0)) return 0;
        if (piv != k) {
            for (int j = 0; j < n; ++j) { msid_cplx t = a[k * n + j]; a[k * n + j] = a[piv * n + j]; a[piv * n + j] = t; }
            for (int j = 0; j < nrhs; ++j) { msid_cplx t = b[k * nrhs + j]; b[k * nrhs + j] = b[piv * nrhs + j]; b[piv * nrhs + j] = t; }
        }
        for (int i = k + 1; i < n; ++i) {
            const msid_cplx f = msid__cdiv(a[i * n + k], a[k * n + k]);
            if (f.re == 0.0 && f.im == 0.0) continue;
            for (int j = k; j < n; ++j) a[i * n + j] = msid__csub(a[i * n + j], msid__cmul(f, a[k * n + j]));
            for (int j = 0; j < nrhs; ++j) b[i * nrhs + j] = msid__csub(b[i * nrhs + j], msid__cmul(f, b[k * nrhs + j]));
        }
    }
    for (int k = n - 1; k >= 0; --k) {
        for (int j = 0; j < nrhs; ++j) {
            msid_cplx s = b[k * nrhs + j];
            for (int i = k + 1; i < n; ++i) s = msid__csub(s, msid__cmul(a[k * n + i], b[i * nrhs + j]));
            b[k * nrhs + j] = msid__cdiv(s, a[k * n + k]);
        }
    }
    return 1;
}
