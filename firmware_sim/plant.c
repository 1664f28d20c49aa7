/* Plant definitions of the simulator: the built-in plant, a small text file
 * format, and the exact frequency response (complex Gaussian elimination). */
#define _GNU_SOURCE
#include "sim_plant.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sim_builtin_plant(sim_plant_def *p)
{
    /* tests/integration/helpers.py dt_plant_2x2: two modes, |z| = 0.9 and 0.8 */
    const double r1 = 0.9, t1 = 2 * M_PI * 0.03, r2 = 0.8, t2 = 2 * M_PI * 0.12;
    const double A[16] = {r1 * cos(t1), -r1 * sin(t1), 0, 0, r1 * sin(t1), r1 * cos(t1), 0, 0,
                          0, 0, r2 * cos(t2), -r2 * sin(t2), 0, 0, r2 * sin(t2), r2 * cos(t2)};
    const double B[8] = {0.3, 0.05, 0.0, 0.2, 0.1, 0.4, 0.25, 0.0};
    const double C[8] = {1.0, 0.2, 0.5, 0.0, 0.1, 0.7, 0.0, 1.0};
    const double D[4] = {0.1, 0.0, 0.05, 0.2};
    memset(p, 0, sizeof *p);
    p->n = 4; p->nu = 2; p->ny = 2;
    memcpy(p->A, A, sizeof A); memcpy(p->B, B, sizeof B); memcpy(p->C, C, sizeof C); memcpy(p->D, D, sizeof D);
}

void sim_builtin_siso_plant(sim_plant_def *p)
{
    /* a two-mass drive as seen from its torque input: a lightly damped mode (|z| = 0.99, 0.05 cycles per sample:
       zeta about 3 %) and a better damped one (|z| = 0.93 at 0.15), no feedthrough */
    const double r1 = 0.99, t1 = 2 * M_PI * 0.05, r2 = 0.93, t2 = 2 * M_PI * 0.15;
    const double A[16] = {r1 * cos(t1), -r1 * sin(t1), 0, 0, r1 * sin(t1), r1 * cos(t1), 0, 0,
                          0, 0, r2 * cos(t2), -r2 * sin(t2), 0, 0, r2 * sin(t2), r2 * cos(t2)};
    const double B[4] = {0.1, 0.05, 0.2, 0.0};
    const double C[4] = {0.5, 0.3, 0.4, 0.2};
    memset(p, 0, sizeof *p);
    p->n = 4; p->nu = 1; p->ny = 1;
    memcpy(p->A, A, sizeof A); memcpy(p->B, B, sizeof B); memcpy(p->C, C, sizeof C);
}

/* File format (whitespace separated, '#' comments):
 *   type dt|ct     states N   inputs NU   outputs NY
 *   A <N*N numbers, row-major>  B <N*NU>  C <NY*N>  D <NY*NU>
 *   h <seconds>    (optional: the sample time of a CT plant driven by a DT design) */
int sim_parse_plant(const char *path, sim_plant_def *p, char *err, size_t errlen)
{
    FILE *f = fopen(path, "r");
    if (!f) { snprintf(err, errlen, "cannot open plant file '%s'", path); return -1; }
    static char text[1 << 20];
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    if (n == sizeof text - 1) { snprintf(err, errlen, "plant file '%s' is too large", path); return -1; }
    text[n] = 0;
    for (char *c = text; *c; ++c) if (*c == '#') while (*c && *c != '\n') *c++ = ' ';
    memset(p, 0, sizeof *p);
    int have[8] = {0};
    char *save = NULL;
    for (char *tok = strtok_r(text, " \t\r\n", &save); tok; tok = strtok_r(NULL, " \t\r\n", &save)) {
        const int matrix = !strcmp(tok, "A") || !strcmp(tok, "B") || !strcmp(tok, "C") || !strcmp(tok, "D");
        char *v = matrix ? NULL : strtok_r(NULL, " \t\r\n", &save);
        if (!matrix && !v) { snprintf(err, errlen, "%s: '%s' has no value", path, tok); return -1; }
        if (!strcmp(tok, "type")) {
            if (!strcmp(v, "dt")) p->ct = 0; else if (!strcmp(v, "ct")) p->ct = 1;
            else { snprintf(err, errlen, "%s: type must be dt or ct", path); return -1; }
            have[0] = 1;
            continue;
        }
        uint32_t *dim = !strcmp(tok, "states") ? &p->n : !strcmp(tok, "inputs") ? &p->nu : !strcmp(tok, "outputs") ? &p->ny : NULL;
        if (dim) {
            char *e;
            unsigned long x = strtoul(v, &e, 10);
            if (*e || x > 64) { snprintf(err, errlen, "%s: bad %s '%s'", path, tok, v); return -1; }
            *dim = (uint32_t)x;
            have[dim == &p->n ? 1 : dim == &p->nu ? 2 : 3] = 1;
            continue;
        }
        if (!strcmp(tok, "h")) {
            char *e;
            p->h = strtod(v, &e);
            if (*e || !(p->h > 0) || !isfinite(p->h)) { snprintf(err, errlen, "%s: h must be positive", path); return -1; }
            continue;
        }
        double *M = NULL;
        size_t cnt = 0;
        int which = -1;
        if (!have[1] || !have[2] || !have[3]) { snprintf(err, errlen, "%s: give states, inputs and outputs before the matrices", path); return -1; }
        if (p->n > SIM_MAX_STATES || p->nu == 0 || p->nu > MSID_MAX_INPUTS || p->ny == 0 || p->ny > MSID_MAX_OUTPUTS) {
            snprintf(err, errlen, "%s: dimensions out of range (states <= %u, 1..%u inputs, 1..%u outputs)", path,
                     SIM_MAX_STATES, MSID_MAX_INPUTS, MSID_MAX_OUTPUTS);
            return -1;
        }
        if (!strcmp(tok, "A")) { M = p->A; cnt = (size_t)p->n * p->n; which = 4; }
        else if (!strcmp(tok, "B")) { M = p->B; cnt = (size_t)p->n * p->nu; which = 5; }
        else if (!strcmp(tok, "C")) { M = p->C; cnt = (size_t)p->ny * p->n; which = 6; }
        else if (!strcmp(tok, "D")) { M = p->D; cnt = (size_t)p->ny * p->nu; which = 7; }
        else { snprintf(err, errlen, "%s: unknown key '%s'", path, tok); return -1; }
        for (size_t i = 0; i < cnt; ++i) {
            v = strtok_r(NULL, " \t\r\n", &save);
            char *e;
            if (!v) { snprintf(err, errlen, "%s: %s needs %zu numbers", path, tok, cnt); return -1; }
            M[i] = strtod(v, &e);
            if (*e || !isfinite(M[i])) { snprintf(err, errlen, "%s: %s: '%s' is not a finite number", path, tok, v); return -1; }
        }
        have[which] = 1;
    }
    if (!have[0] || !have[1] || !have[2] || !have[3] || (p->n && (!have[4] || !have[5] || !have[6]))) {
        snprintf(err, errlen, "%s: needs type, states, inputs, outputs and A, B, C (D optional)", path);
        return -1;
    }
    return 0;
}

/* G = C (sI - A)^{-1} B + D with s = e^{jw} (DT) or j w (CT). */
int sim_plant_response(const sim_plant_def *p, double w, msid_cplx *G)
{
    const uint32_t n = p->n, nu = p->nu, ny = p->ny;
    static double Mr[SIM_MAX_STATES][SIM_MAX_STATES + MSID_MAX_INPUTS], Mi[SIM_MAX_STATES][SIM_MAX_STATES + MSID_MAX_INPUTS];
    const double sr = p->ct ? 0.0 : cos(w), si = p->ct ? w : sin(w);
    for (uint32_t r = 0; r < n; ++r) {
        for (uint32_t c = 0; c < n; ++c) { Mr[r][c] = (r == c ? sr : 0.0) - p->A[r * n + c]; Mi[r][c] = r == c ? si : 0.0; }
        for (uint32_t c = 0; c < nu; ++c) { Mr[r][n + c] = p->B[r * nu + c]; Mi[r][n + c] = 0.0; }
    }
    /* Gauss-Jordan with partial pivoting on [sI - A | B] */
    for (uint32_t k = 0; k < n; ++k) {
        uint32_t piv = k;
        double best = 0;
        for (uint32_t r = k; r < n; ++r) {
            const double m = hypot(Mr[r][k], Mi[r][k]);
            if (m > best) { best = m; piv = r; }
        }
        if (!(best > 1e-300)) return -1;
        if (piv != k)
            for (uint32_t c = 0; c < n + nu; ++c) {
                double t = Mr[k][c]; Mr[k][c] = Mr[piv][c]; Mr[piv][c] = t;
                t = Mi[k][c]; Mi[k][c] = Mi[piv][c]; Mi[piv][c] = t;
            }
        const double dr = Mr[k][k], di = Mi[k][k], dd = dr * dr + di * di;
        const double ir = dr / dd, ii = -di / dd;
        for (uint32_t c = 0; c < n + nu; ++c) {
            const double a = Mr[k][c], b = Mi[k][c];
            Mr[k][c] = a * ir - b * ii; Mi[k][c] = a * ii + b * ir;
        }
        for (uint32_t r = 0; r < n; ++r) {
            if (r == k) continue;
            const double fr = Mr[r][k], fi = Mi[r][k];
            if (fr == 0 && fi == 0) continue;
            for (uint32_t c = 0; c < n + nu; ++c) {
                Mr[r][c] -= fr * Mr[k][c] - fi * Mi[k][c];
                Mi[r][c] -= fr * Mi[k][c] + fi * Mr[k][c];
            }
        }
    }
    for (uint32_t i = 0; i < ny; ++i)
        for (uint32_t j = 0; j < nu; ++j) {
            double re = p->D[i * nu + j], im = 0;
            for (uint32_t k = 0; k < n; ++k) { re += p->C[i * n + k] * Mr[k][n + j]; im += p->C[i * n + k] * Mi[k][n + j]; }
            G[i * nu + j].re = re;
            G[i * nu + j].im = im;
        }
    return 0;
}
