/* On-device estimation: lib/'s msid_meas fed sample by sample, msid_frf on SOLVE.
 * The same core calls with the same settings as the host's FRF job
 * (tools/msid/pipeline.cpp FrfJob), so on the same samples the results are
 * bit-identical (the streaming DFT path; docs/target.md). */
#include "sim_estimate.h"

#include <string.h>

static void fail(sim_est *e, msid_status s)
{
    if (!e->status) e->status = s;
    e->on = 0;
}

msid_status sim_est_setup(sim_est *e, sim_device *d, const sim_est_cfg *c)
{
    memset(e, 0, sizeof *e);
    e->bad = -1;
    const msid_design *des = &d->des;
    const uint32_t P = des->period, L = des->n_lines, nu = d->pd.nu, ny = d->pd.ny, m = des->n_experiments;
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P;
    mc.n_inputs = nu;
    mc.n_outputs = ny;
    mc.n_experiments = m;
    mc.n_lines = L;
    mc.bins = des->bins;
    mc.twiddle = &d->tw;
    mc.path = MSID_DFT_STREAM;                 /* no FFT on the device */
    mc.skip_periods = c->skip_periods;
    /* as FrfJob: the transient test needs skip + 3 periods; history 4 K + 8 */
    mc.transient = (uint64_t)c->periods >= (uint64_t)c->skip_periods + 3 ? c->transient : MSID_TRANSIENT_OFF;
    mc.max_periods = mc.transient != MSID_TRANSIENT_OFF ? 4u * c->periods + 8u : 0;
    mc.alpha = c->alpha;
    msid_frf_cfg fc;
    memset(&fc, 0, sizeof fc);
    fc.period = P;
    fc.n_inputs = nu;
    fc.n_outputs = ny;
    fc.n_experiments = m;
    fc.n_lines = L;
    fc.folded = des->is_ct ? des->folded : NULL;
    const size_t nm = msid_meas_mem_size(&mc), nf = msid_frf_mem_size(&fc);
    if (nm == 0 || nf == 0) { fail(e, MSID_E_DIMS); return e->status; }
    /* both chunks are 64-byte rounded by sim_take */
    e->need = (nm + 63u) / 64u * 64u + (nf + 63u) / 64u * 64u;
    e->have = d->o.est_mem ? (size_t)d->o.est_mem : SIM_EST_DEFAULT_MEM;
    if (e->need > e->have) { fail(e, MSID_E_MEM_SIZE); return e->status; }
    d->arena_used = d->arena_mark;             /* the estimator's memory follows the design's */
    void *mm = sim_take(d, nm), *mf = sim_take(d, nf);
    if (!mm || !mf) { fail(e, MSID_E_MEM_SIZE); return e->status; }
    msid_status st = msid_meas_init(&e->ms, &mc, mm, nm);
    if (st == MSID_OK) st = msid_frf_init(&e->f, &fc, mf, nf);
    if (st != MSID_OK) { fail(e, st); return st; }
    e->on = 1;
    return MSID_OK;
}

void sim_est_begin(sim_est *e, uint32_t x)
{
    if (!e->on) return;
    if (e->ms.current >= 0) sim_est_end(e);
    const msid_status st = msid_meas_begin(&e->ms, x);
    if (st) fail(e, st);
}

void sim_est_push(sim_est *e, const double *row)
{
    if (!e->on || e->ms.current < 0) return;
    const msid_pstats *ps = msid_meas_stats(&e->ms, (uint32_t)e->ms.current);
    const uint32_t before = msid_pstats_get_counts(ps).used;
    const msid_status st = msid_meas_push(&e->ms, row, 1);
    if (st) { fail(e, st); return; }
    e->periods += msid_pstats_get_counts(ps).used - before;
}

void sim_est_end(sim_est *e)
{
    if (!e->on || e->ms.current < 0) return;
    const msid_status st = msid_meas_end(&e->ms, NULL);
    if (st) fail(e, st);
}

msid_status sim_est_solve(sim_est *e)
{
    if (!e->on) return e->status ? e->status : MSID_E_STATE;
    sim_est_end(e);
    if (!e->on) return e->status;
    const uint32_t m = e->ms.n_experiments;
    const msid_pstats *ps[MSID_MAX_EXPERIMENTS];
    for (uint32_t x = 0; x < m; ++x) ps[x] = msid_meas_stats(&e->ms, x);
    const msid_status st = msid_frf_compute(&e->f, ps);
    e->bad = st == MSID_E_FEW_PERIODS ? e->f.bad_experiment : st ? e->f.bad_line : -1;
    e->solved = 1;
    return st;
}
