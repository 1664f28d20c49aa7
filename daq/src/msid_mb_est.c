/* msid-modbus/1 extension estimate/1: the result block of on-device estimation
 * (layout, float64 register codec, device-side encoder). docs/modbus-registers.md. */
#include "msid_daq/msid_mb_est.h"

#include <math.h>
#include <string.h>

int msid_mb_est_layout_init(msid_mb_est_layout *lo, uint32_t nu, uint32_t ny, uint32_t m, uint32_t L)
{
    memset(lo, 0, sizeof *lo);
    if (nu == 0 || nu > MSID_MAX_INPUTS || ny == 0 || ny > MSID_MAX_OUTPUTS || m < nu || m > MSID_MAX_EXPERIMENTS ||
        L == 0 || L > 65536u)
        return -1;
    const uint32_t g = nu * ny;
    lo->nu = nu;
    lo->ny = ny;
    lo->m = m;
    lo->L = L;
    lo->noise = m * MSID_MB_EST_X_COUNT;
    lo->lines = lo->noise + 2u * ny * ny;
    uint32_t k = 0;
    lo->G = k; k += 2u * g;
    lo->cov = k; k += 2u * g * g;
    lo->dof = k; k += 1u;
    lo->cov_ki = k; k += 2u * g * g;
    lo->dof_ki = k; k += 1u;
    lo->lnoise = k; k += 2u * ny * ny;
    lo->snr = k; k += ny;
    lo->cond = k; k += 1u;
    lo->usnr = k; k += 1u;
    lo->status = k; k += 1u;
    lo->line = k;
    const uint64_t total = (uint64_t)lo->lines + (uint64_t)L * k;
    if (total * 4u > 0xFFFFFFFFull) return -1;
    lo->doubles = (uint32_t)total;
    return 0;
}

uint32_t msid_mb_est_regs(const msid_mb_est_layout *lo) { return 4u * lo->doubles; }

void msid_mb_put_f64(uint16_t *regs, double v)
{
    uint64_t b;
    memcpy(&b, &v, sizeof b);
    for (int i = 0; i < 4; ++i) regs[i] = (uint16_t)(b >> (48 - 16 * i));
}

double msid_mb_get_f64(const uint16_t *regs)
{
    uint64_t b = 0;
    for (int i = 0; i < 4; ++i) b = b << 16 | regs[i];
    double v;
    memcpy(&v, &b, sizeof v);
    return v;
}

double msid_mb_est_value(const uint16_t *regs, uint32_t k) { return msid_mb_get_f64(regs + 4u * (size_t)k); }

static void put_cplx(uint16_t *regs, uint32_t k, const msid_cplx *a, size_t n)
{
    for (size_t i = 0; i < n; ++i) {
        msid_mb_put_f64(regs + 4u * (k + 2u * i), a[i].re);
        msid_mb_put_f64(regs + 4u * (k + 2u * i + 1u), a[i].im);
    }
}

static void put(uint16_t *regs, uint32_t k, double v) { msid_mb_put_f64(regs + 4u * (size_t)k, v); }

void msid_mb_est_encode(uint16_t *regs, const msid_mb_est_layout *lo, const msid_meas *ms, const msid_frf *f)
{
    const uint32_t ny = lo->ny, g = lo->nu * lo->ny;
    for (uint32_t k = 0; k < lo->doubles; ++k) put(regs, k, NAN);
    for (uint32_t e = 0; e < lo->m; ++e) {
        const msid_pstats *ps = msid_meas_stats(ms, e);
        const msid_pstats_counts c = msid_pstats_get_counts(ps);
        const uint32_t b = e * MSID_MB_EST_X_COUNT;
        put(regs, b + MSID_MB_EST_X_OFFERED, c.offered);
        put(regs, b + MSID_MB_EST_X_SKIPPED, c.skipped);
        put(regs, b + MSID_MB_EST_X_GAP, c.gap);
        put(regs, b + MSID_MB_EST_X_NONFINITE, c.nonfinite);
        put(regs, b + MSID_MB_EST_X_FLAGGED, c.transient_flagged);
        put(regs, b + MSID_MB_EST_X_DROPPED, c.transient_dropped);
        put(regs, b + MSID_MB_EST_X_USED, c.used);
        put(regs, b + MSID_MB_EST_X_TESTED, c.tested);
        put(regs, b + MSID_MB_EST_X_DRIFT_TESTED, c.drift_tested);
        put(regs, b + MSID_MB_EST_X_DRIFT, c.drift);
        put(regs, b + MSID_MB_EST_X_DRIFT_P, msid_pstats_drift_pvalue(ps));
        put(regs, b + MSID_MB_EST_X_SAMPLES, (double)ms->samples[e]);
        put(regs, b + MSID_MB_EST_X_LEFTOVER, (double)msid_meas_leftover(ms, e));
        uint32_t n = 0;
        for (uint32_t k = 0; k < msid_pstats_history(ps) && n < MSID_MB_EST_FLAG_MAX; ++k) {
            double pv;
            const int st = msid_pstats_period_state(ps, k, &pv);
            if (st >= 1) put(regs, b + MSID_MB_EST_X_PERIODS + n++, 4.0 * (msid_pstats_period_number(ps, k) + 1u) + st);
        }
        while (n < MSID_MB_EST_FLAG_MAX) put(regs, b + MSID_MB_EST_X_PERIODS + n++, 0.0);
    }
    if (!f) return;
    put_cplx(regs, lo->noise, msid_frf_noise_cov_time(f), (size_t)ny * ny);
    for (uint32_t l = 0; l < lo->L; ++l) {
        const uint32_t b = lo->lines + l * lo->line;
        put(regs, b + lo->status, msid_frf_line_status(f, l));
        put_cplx(regs, b + lo->G, msid_frf_G(f, l), g);
        put_cplx(regs, b + lo->cov, msid_frf_cov(f, l), (size_t)g * g);
        put(regs, b + lo->dof, msid_frf_dof(f, l));
        put_cplx(regs, b + lo->cov_ki, msid_frf_cov_known_input(f, l), (size_t)g * g);
        put(regs, b + lo->dof_ki, msid_frf_dof_known_input(f, l));
        put_cplx(regs, b + lo->lnoise, msid_frf_noise_cov(f, l), (size_t)ny * ny);
        for (uint32_t i = 0; i < ny; ++i) put(regs, b + lo->snr + i, msid_frf_snr_db(f, l)[i]);
        put(regs, b + lo->cond, msid_frf_cond(f, l));
        put(regs, b + lo->usnr, msid_frf_input_snr_db(f, l));
    }
}

const char *msid_mb_est_state_name(uint32_t s)
{
    static const char *const n[] = {"off", "accumulating", "ready", "error"};
    return s < 4u ? n[s] : "?";
}
