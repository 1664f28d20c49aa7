/* Deterministic cos/sin in turns and natural log: only +,-,*,/ and exact
 * reductions, so every IEEE-754 double platform gives the same bits. */
#include "msid/msid_dmath.h"
#include <math.h>

#define MSID_PI_4 0.78539816339744830961566084581987572

/* sin(a), cos(a) for a in [0, pi/4]: Taylor series to degree 19/20 with
 * |error| below 1e-19 on this range, evaluated by Horner. */
static void sincos_q(double a, double *s, double *c)
{
    const double a2 = a * a;
    double ps = 1.0 / 121645100408832000.0;                 /* 1/19! */
    ps = 1.0 / 355687428096000.0 - a2 * ps;                 /* 1/17! */
    ps = 1.0 / 1307674368000.0 - a2 * ps;                   /* 1/15! */
    ps = 1.0 / 6227020800.0 - a2 * ps;                      /* 1/13! */
    ps = 1.0 / 39916800.0 - a2 * ps;                        /* 1/11! */
    ps = 1.0 / 362880.0 - a2 * ps;                          /* 1/9!  */
    ps = 1.0 / 5040.0 - a2 * ps;                            /* 1/7!  */
    ps = 1.0 / 120.0 - a2 * ps;                             /* 1/5!  */
    ps = 1.0 / 6.0 - a2 * ps;                               /* 1/3!  */
    *s = a - a * a2 * ps;

    double pc = 1.0 / 2432902008176640000.0;                /* 1/20! */
    pc = 1.0 / 6402373705728000.0 - a2 * pc;                /* 1/18! */
    pc = 1.0 / 20922789888000.0 - a2 * pc;                  /* 1/16! */
    pc = 1.0 / 87178291200.0 - a2 * pc;                     /* 1/14! */
    pc = 1.0 / 479001600.0 - a2 * pc;                       /* 1/12! */
    pc = 1.0 / 3628800.0 - a2 * pc;                         /* 1/10! */
    pc = 1.0 / 40320.0 - a2 * pc;                           /* 1/8!  */
    pc = 1.0 / 720.0 - a2 * pc;                             /* 1/6!  */
    pc = 1.0 / 24.0 - a2 * pc;                              /* 1/4!  */
    pc = 0.5 - a2 * pc;                                     /* 1/2!  */
    *c = 1.0 - a2 * pc;
}

void msid_cis_turns(double t, double *c, double *s)
{
    /* Exact reduction: frac in [0,1), u = 8*frac is exact (power of two). */
    double fr = t - floor(t);
    if (fr >= 1.0) fr = 0.0;             /* t slightly below an integer */
    const double u = fr * 8.0;
    const int o = (int)u;                /* octant 0..7 */
    const double r = u - (double)o;      /* exact, in [0,1) */
    double s0, c0;
    if ((o & 1) == 0) {
        sincos_q(r * MSID_PI_4, &s0, &c0);
    } else if (r == 0.0) {
        /* odd multiple of 1/8 turn: cos = sin = sqrt(1/2) exactly rounded
         * (the series at the rounded pi/4 gives sin one ulp low) */
        s0 = c0 = 0.70710678118654752440;
    } else {
        /* angle = q*pi/2 + pi/2 - (1-r)*pi/4 */
        double sa, ca;
        sincos_q((1.0 - r) * MSID_PI_4, &sa, &ca);
        s0 = ca;
        c0 = sa;
    }
    double ss, cc;
    switch (o >> 1) {
    case 0: ss = s0; cc = c0; break;
    case 1: ss = c0; cc = -s0; break;
    case 2: ss = -s0; cc = -c0; break;
    default: ss = -c0; cc = s0; break;
    }
    if (c) *c = cc;
    if (s) *s = ss;
}

double msid_sqrt(double x) { return sqrt(x); }

double msid_log(double x)
{
    if (!(x > 0.0)) return x == 0.0 ? -HUGE_VAL : NAN;
    if (x == HUGE_VAL) return x;
    int e;
    double m = frexp(x, &e);             /* exact: x = m * 2^e, m in [0.5,1) */
    if (m < 0.70710678118654752440) { m *= 2.0; e -= 1; }   /* m in [sqrt(1/2), sqrt(2)) */
    /* ln m = 2 atanh(s), s = f/(2+f), f = m-1 (exact), |s| <= 0.1716; series to s^27.
     * Written as f - (hfsq - s*(hfsq + R)) (the fdlibm form): 2s = f - s*f and
     * s*f = hfsq - s*hfsq, so the large term f is exact and the error stays < 1 ulp. */
    const double f = m - 1.0;
    const double hfsq = 0.5 * f * f;
    const double s = f / (2.0 + f);
    const double s2 = s * s;
    double p = 1.0 / 27.0;
    p = 1.0 / 25.0 + s2 * p;
    p = 1.0 / 23.0 + s2 * p;
    p = 1.0 / 21.0 + s2 * p;
    p = 1.0 / 19.0 + s2 * p;
    p = 1.0 / 17.0 + s2 * p;
    p = 1.0 / 15.0 + s2 * p;
    p = 1.0 / 13.0 + s2 * p;
    p = 1.0 / 11.0 + s2 * p;
    p = 1.0 / 9.0 + s2 * p;
    p = 1.0 / 7.0 + s2 * p;
    p = 1.0 / 5.0 + s2 * p;
    p = 1.0 / 3.0 + s2 * p;
    const double R = 2.0 * s2 * p;       /* ln m = 2s + s*R */
    /* ln2 split in two parts so e*LN2_HI is exact for |e| < 2^11. */
    const double LN2_HI = 6.93147180369123816490e-01;
    const double LN2_LO = 1.90821492927058770002e-10;
    return (double)e * LN2_HI - ((hfsq - (s * (hfsq + R) + (double)e * LN2_LO)) - f);
}
