/* Two-mass mechanics, discretized once by the exponential of the augmented matrix [F G; 0 0] T. */
#include "sim_twomass.h"

#include <math.h>
#include <string.h>

sim_twomass_par sim_twomass_default(void)
{
    const sim_twomass_par p = {1e-4, 2e-4, 50.0, 2e-3, 1e-4, 1e-4};
    return p;
}

static void mul5(double r[5][5], double x[5][5], double y[5][5])
{
    double t[5][5];
    for (int i = 0; i < 5; ++i)
        for (int j = 0; j < 5; ++j) {
            double s = 0;
            for (int k = 0; k < 5; ++k) s += x[i][k] * y[k][j];
            t[i][j] = s;
        }
    memcpy(r, t, sizeof t);
}

int sim_twomass_init(sim_twomass *m, const sim_twomass_par *p, double ts)
{
    if (!(p->jm > 0) || !(p->jl > 0) || !(p->k >= 0) || !(p->d >= 0) || !(p->bm >= 0) || !(p->bl >= 0) || !(ts > 0) ||
        !isfinite(p->jm + p->jl + p->k + p->d + p->bm + p->bl + ts))
        return -1;
    memset(m, 0, sizeof *m);
    m->p = *p;
    m->ts = ts;
    /* M = [F G; 0 0] ts; e^M = [A B; 0 1] */
    double mm[5][5] = {{0}};
    mm[0][1] = 1;
    mm[1][0] = -p->k / p->jm, mm[1][1] = -(p->d + p->bm) / p->jm, mm[1][2] = p->k / p->jm, mm[1][3] = p->d / p->jm;
    mm[1][4] = 1 / p->jm;
    mm[2][3] = 1;
    mm[3][0] = p->k / p->jl, mm[3][1] = p->d / p->jl, mm[3][2] = -p->k / p->jl, mm[3][3] = -(p->d + p->bl) / p->jl;
    double nrm = 0;
    for (int i = 0; i < 5; ++i) {
        double r = 0;
        for (int j = 0; j < 5; ++j) r += fabs(mm[i][j] *= ts);
        if (r > nrm) nrm = r;
    }
    /* scaling and squaring: Taylor of e^(M / 2^s) to order 18 with ||M / 2^s|| <= 0.5 */
    int s = 0;
    while (nrm > 0.5 && s < 60) nrm /= 2, ++s;
    const double sc = ldexp(1.0, -s);
    double e[5][5] = {{0}}, term[5][5] = {{0}}, ms[5][5];
    for (int i = 0; i < 5; ++i) {
        e[i][i] = term[i][i] = 1;
        for (int j = 0; j < 5; ++j) ms[i][j] = mm[i][j] * sc;
    }
    for (int n = 1; n <= 18; ++n) {
        mul5(term, term, ms);
        for (int i = 0; i < 5; ++i)
            for (int j = 0; j < 5; ++j) e[i][j] += (term[i][j] /= n);
    }
    for (int k = 0; k < s; ++k) mul5(e, e, e);
    for (int i = 0; i < 4; ++i) {
        for (int j = 0; j < 4; ++j) m->a[i][j] = e[i][j];
        m->b[i] = e[i][4];
    }
    return 0;
}

void sim_twomass_step(sim_twomass *m, double tau)
{
    double y[4];
    for (int i = 0; i < 4; ++i)
        y[i] = m->a[i][0] * m->x[0] + m->a[i][1] * m->x[1] + m->a[i][2] * m->x[2] + m->a[i][3] * m->x[3] + m->b[i] * tau;
    memcpy(m->x, y, sizeof y);
}
