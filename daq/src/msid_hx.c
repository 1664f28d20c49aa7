/* Host-timed excitation of a described device (msid_hx.h): the phases of an experiment, the limit checks before
 * any write, the tick loop that writes, reads and streams into the core, the safe values on the way out. */
#include "msid_daq/msid_hx.h"
#include "msid_hx_internal.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ---- memory -------------------------------------------------------------------------------------- */

static size_t up(size_t n) { return (n + MSID_MEM_ALIGN - 1) / MSID_MEM_ALIGN * MSID_MEM_ALIGN; }

static msid_gen_cfg gen_cfg(const msid_hx_cfg *c, uint32_t e)
{
    msid_gen_cfg g;
    memset(&g, 0, sizeof g);
    g.design = c->design;
    g.twiddle = c->twiddle;
    g.experiment = e;
    g.waveform_table = 1;
    return g;
}

static msid_stream_cfg stream_cfg(const msid_hx_cfg *c)
{
    msid_stream_cfg s;
    memset(&s, 0, sizeof s);
    s.n_channels = c->design->n_inputs + c->n_outputs;
    s.block = 64;
    s.meas = c->meas;
    return s;
}

/* The one layout of the runner's memory: the generator, the stream, a row, the measured values. With base NULL
 * it only sums the sizes. */
static size_t layout(msid_hx *h, const msid_hx_cfg *c, uint8_t *base)
{
    const msid_gen_cfg gc = gen_cfg(c, 0);
    const msid_stream_cfg sc = stream_cfg(c);
    const size_t ng = msid_gen_mem_size(&gc), ns = msid_stream_mem_size(&sc);
    const size_t nr = up(sizeof(double) * sc.n_channels), nm = up(sizeof(double) * c->n_measure);
    if (!ng || !ns) return 0;
    if (base) {
        h->gen_mem = base;
        h->gen_len = ng;
        h->st.rows = (double *)(void *)(base + ng);   /* placed again by msid_stream_init */
        h->row = (double *)(void *)(base + ng + ns);
        h->meas_v = (double *)(void *)(base + ng + ns + nr);
    }
    return ng + ns + nr + nm;
}

static int cfg_ok(const msid_hx_cfg *c)
{
    if (!c || !c->design || !c->twiddle || !c->io || !c->io->be || !c->meas) return 0;
    const uint32_t nu = c->design->n_inputs;
    if (c->periods < 1 || c->fade_periods > 8 || c->n_measure < 1 || c->n_measure > MSID_HX_MAX_MEASURE) return 0;
    if (c->n_outputs < 1 || c->n_outputs > MSID_MAX_OUTPUTS || nu + c->n_outputs > MSID_MAX_CHANNELS) return 0;
    for (uint32_t i = 0; i < nu; ++i)
        if (c->input_of[i] >= (int32_t)c->n_measure) return 0;
    for (uint32_t j = 0; j < c->n_outputs; ++j)
        if (c->output_of[j] >= c->n_measure) return 0;
    return c->counter < (int32_t)c->n_measure;
}

size_t msid_hx_mem_size(const msid_hx_cfg *c)
{
    if (!cfg_ok(c)) return 0;
    return layout(NULL, c, NULL);
}

/* ---- the phases of an experiment ----------------------------------------------------------------- */

int msid__hx_fail(msid_hx *h, int rc, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(h->err, sizeof h->err, fmt, ap);
    va_end(ap);
    return rc;
}

/* Ticks of a linear ramp from a to b: max_step per tick, or one period without a max_step. */
static uint64_t ramp_ticks(const msid_hx_drive *d, double a, double b, uint32_t P)
{
    if (a == b) return 0;
    if (isnan(d->max_step)) return P;
    return (uint64_t)ceil(fabs(b - a) / d->max_step * (1.0 - 1e-12));
}

/* Ticks of the approach of experiment e (only the first starts away from the operating point). */
static uint64_t approach_ticks(const msid_hx_cfg *c, uint32_t e)
{
    if (e > 0) return 0;
    uint64_t a = 0;
    for (uint32_t i = 0; i < c->design->n_inputs; ++i) {
        const msid_hx_drive *d = &c->drive[i];
        const uint64_t t = ramp_ticks(d, d->safe, d->op, c->design->period);
        if (t > a) a = t;
    }
    return a;
}

/* Where tick n of experiment e's timeline lies. */

msid__hx_phase msid__hx_phases(const msid_hx_cfg *c, uint32_t e)
{
    msid__hx_phase p;
    const uint64_t P = c->design->period;
    p.A = approach_ticks(c, e);
    p.F = (uint64_t)c->fade_periods * P;
    p.K = (uint64_t)c->periods * P;
    p.total = p.A + 2 * p.F + p.K;
    return p;
}

/* Raised-cosine fade-in weight of excitation sample k < F: 0 < w, and w = 1 at the last sample, so that the
 * first measured sample follows one at full amplitude (the plant's longer memory is the skip periods' job). */
static double fade_in(uint64_t k, uint64_t F) { return 0.5 * (1.0 - cos(M_PI * (double)(k + 1) / (double)F)); }

/* The excitation envelope at excitation sample k of a phase p (1 in the measured periods). */
static double envelope(const msid__hx_phase *p, uint64_t k)
{
    if (k < p->F) return fade_in(k, p->F);
    if (k < p->F + p->K) return 1.0;
    return fade_in(p->F + p->K + p->F - 1 - k, p->F);
}

/* The values of tick n of experiment e into v[nu]; the generator g is experiment e's. */
void msid__hx_values_at(const msid_hx_cfg *c, const msid__hx_phase *p, msid_gen *g, uint64_t n, double *v)
{
    const uint32_t nu = c->design->n_inputs;
    if (n < p->A) {
        for (uint32_t i = 0; i < nu; ++i) {
            const msid_hx_drive *d = &c->drive[i];
            /* every channel reaches its operating point by the end of the approach */
            const uint64_t own = ramp_ticks(d, d->safe, d->op, c->design->period);
            const double fi = own == 0 ? 1.0 : fmin(1.0, (double)(n + 1) / (double)own);
            v[i] = d->safe + (d->op - d->safe) * fi;
        }
        return;
    }
    const uint64_t k = n - p->A;
    double x[MSID_MAX_INPUTS];
    msid_gen_seek(g, k);
    msid_gen_next(g, x);
    const double w = envelope(p, k);
    for (uint32_t i = 0; i < nu; ++i) v[i] = c->drive[i].op + w * c->drive[i].gain * x[i];
}

/* A value against a channel's range and the step from the last value. */
static int breaks_limit(const msid_hx_drive *d, double prev, double v)
{
    if (!isfinite(v)) return 1;
    if (!isnan(d->min) && v < d->min) return 1;
    if (!isnan(d->max) && v > d->max) return 1;
    if (!isnan(d->max_step) && fabs(v - prev) > d->max_step * (1.0 + 1e-9)) return 1;
    return 0;
}

static const char *phase_name(const msid__hx_phase *p, uint64_t n)
{
    if (n < p->A) return "the approach to the operating point";
    const uint64_t k = n - p->A;
    if (k < p->F) return "the fade-in";
    if (k < p->F + p->K) return "the measured periods";
    return "the fade-out";
}

/* Every value of every experiment and of the final ramp checked before anything is written. */
static int check_all(msid_hx *h)
{
    const msid_hx_cfg *c = &h->cfg;
    const uint32_t nu = c->design->n_inputs;
    double prev[MSID_MAX_INPUTS], v[MSID_MAX_INPUTS];
    for (uint32_t i = 0; i < nu; ++i) prev[i] = c->drive[i].safe;
    for (uint32_t e = 0; e < c->design->n_experiments; ++e) {
        const msid_gen_cfg gc = gen_cfg(c, e);
        const msid_status st = msid_gen_init(&h->gen, &gc, h->gen_mem, h->gen_len);
        if (st != MSID_OK) return msid__hx_fail(h, msid_daq_core(st), "excitation generator: %s", msid_strerror(st));
        const msid__hx_phase p = msid__hx_phases(c, e);
        for (uint64_t n = 0; n < p.total; ++n) {
            msid__hx_values_at(c, &p, &h->gen, n, v);
            for (uint32_t i = 0; i < nu; ++i) {
                const msid_hx_drive *d = &c->drive[i];
                if (!breaks_limit(d, prev[i], v[i])) continue;
                const char *what = !isnan(d->min) && v[i] < d->min   ? "below min"
                                   : !isnan(d->max) && v[i] > d->max ? "above max"
                                                                     : "a step beyond max_step";
                return msid__hx_fail(h, -MSID_DAQ_E_ARG,
                            "the excitation of '%s' would reach %.6g (%s: min %g, max %g, max_step %g; the step from "
                            "%.6g) at tick %llu of experiment %u, in %s; nothing was written: lower the amplitude "
                            "(now %.6g peak around %.6g), excite fewer or lower lines, or add fade periods",
                            d->name ? d->name : "drive", v[i], what, d->min, d->max, d->max_step, prev[i],
                            (unsigned long long)n, e + 1, phase_name(&p, n), d->gain * h->peak[i], d->op);
            }
            memcpy(prev, v, sizeof(double) * nu);
        }
    }
    return 0;
}

/* ---- set-up -------------------------------------------------------------------------------------- */

int msid_hx_peaks(const msid_design *d, const msid_twiddle *tw, void *gen_mem, size_t gen_len, double *peak)
{
    msid_gen g;
    double x[MSID_MAX_INPUTS];
    for (uint32_t i = 0; i < d->n_inputs; ++i) peak[i] = 0;
    for (uint32_t e = 0; e < d->n_experiments; ++e) {
        msid_gen_cfg gc;
        memset(&gc, 0, sizeof gc);
        gc.design = d;
        gc.twiddle = tw;
        gc.experiment = e;
        gc.waveform_table = 1;
        const msid_status st = msid_gen_init(&g, &gc, gen_mem, gen_len);
        if (st != MSID_OK) return msid_daq_core(st);
        for (uint32_t n = 0; n < d->period; ++n) {
            msid_gen_next(&g, x);
            for (uint32_t i = 0; i < d->n_inputs; ++i)
                if (fabs(x[i]) > peak[i]) peak[i] = fabs(x[i]);
        }
    }
    return 0;
}

int msid_hx_init(msid_hx *h, const msid_hx_cfg *c, void *mem, size_t len)
{
    if (!h || !mem) return -MSID_DAQ_E_ARG;
    memset(h, 0, sizeof *h);
    if (!cfg_ok(c)) return msid__hx_fail(h, -MSID_DAQ_E_ARG, "host excitation: invalid configuration");
    const size_t need = layout(NULL, c, NULL);
    if (((uintptr_t)mem) % MSID_MEM_ALIGN) return msid_daq_core(MSID_E_MEM_ALIGN);
    if (len < need) return msid_daq_core(MSID_E_MEM_SIZE);
    h->cfg = *c;
    if (!h->cfg.silence_ms) h->cfg.silence_ms = 5000;
    layout(h, c, mem);
    const msid_stream_cfg sc = stream_cfg(c);
    msid_status st = msid_stream_init(&h->st, &sc, h->st.rows, msid_stream_mem_size(&sc));
    if (st != MSID_OK) return msid_daq_core(st);
    int rc = msid_hx_peaks(c->design, c->twiddle, h->gen_mem, h->gen_len, h->peak);
    if (rc < 0) return msid__hx_fail(h, rc, "excitation generator: %s", msid_daq_message(rc));
    for (uint32_t i = 0; i < c->design->n_inputs; ++i) h->cur[i] = c->drive[i].safe;
    if ((rc = check_all(h)) < 0) return rc;
    if (msid_tick_init(&h->tick, &c->tick) != 0)
        return msid__hx_fail(h, -MSID_DAQ_E_ARG, "the tick rate %g Hz is out of range (0, 100000]", c->tick.rate_hz);
    msid_tstats_reset(&h->tim.rtt);
    msid_tstats_reset(&h->tim.apply);
    msid_tstats_reset(&h->tim.sample);
    h->ready = 1;
    return 0;
}

void msid_hx_release(msid_hx *h) { msid_tick_release(&h->tick); }

/* ---- the tick loop ------------------------------------------------------------------------------- */

double msid__hx_mid_ns(int64_t a, int64_t b) { return 0.5 * ((double)a + (double)b); }

/* The counter read at instant t_ns: unwrapped, into the least-squares sums of the device's clock. */
void msid__hx_note_counter(msid_hx *h, double raw, int64_t t_ns, int consecutive)
{
    msid_hx_timing *T = &h->tim;
    const double M = h->cfg.counter_modulus > 0 ? h->cfg.counter_modulus : 65536.0;
    if (!isfinite(raw)) return;
    if (T->cs_n == 0) {
        T->c_t0 = t_ns;
        T->c_first = T->c_last = raw;
        T->c_unwrapped = 0;
    } else {
        double d = fmod(raw - T->c_last, M);
        if (d < 0) d += M;
        T->c_unwrapped += d;
        if (consecutive) h->cnt.counter_steps[d == 0 ? 0 : d == 1 ? 1 : d == 2 ? 2 : 3]++;
        T->c_last = raw;
    }
    const double t = 1e-9 * (double)(t_ns - T->c_t0), y = T->c_unwrapped;
    T->cs_n += 1;
    T->cs_t += t;
    T->cs_c += y;
    T->cs_tt += t * t;
    T->cs_tc += t * y;
}

double msid_hx_counter_rate(const msid_hx *h)
{
    const msid_hx_timing *T = &h->tim;
    if (h->cfg.counter < 0 || T->cs_n < 16) return NAN;
    const double n = T->cs_n, den = n * T->cs_tt - T->cs_t * T->cs_t;
    if (!(den > 0)) return NAN;
    return (n * T->cs_tc - T->cs_t * T->cs_c) / den;
}

void msid__hx_lose(msid_hx *h, uint64_t n)
{
    h->cnt.samples_lost += n;
    msid_stream_lost(&h->st, n);
}

/* The timing of a successful measured tick. */
void msid__hx_note_timing(msid_hx *h, const msid_devio_times *t, int64_t deadline)
{
    msid_hx_timing *T = &h->tim;
    /* a status frame taken from the queue may have arrived before the write (CAN): the exchange ends with
       whichever came last */
    const int64_t first = t->w0 ? t->w0 : t->r0, last = t->r1 > t->w1 ? t->r1 : t->w1;
    msid_tstats_add(&T->rtt, last - first);
    if (t->w0) {
        msid_tstats_add(&T->apply, (int64_t)(msid__hx_mid_ns(t->w0, t->w1) - (double)deadline));
        const double hw = 0.5 * (double)(t->w1 - t->w0);
        T->half_write_sq += hw * hw;
    }
    if (t->r0) {
        msid_tstats_add(&T->sample, (int64_t)(msid__hx_mid_ns(t->r0, t->r1) - (double)deadline));
        const double hr = 0.5 * (double)(t->r1 - t->r0);
        T->half_read_sq += hr * hr;
    }
    T->n_half++;
}

/* The row [u; y] of a measured tick: read-back inputs or the commanded values, then the outputs. */
void msid__hx_make_row(msid_hx *h, const double *v)
{
    const msid_hx_cfg *c = &h->cfg;
    const uint32_t nu = c->design->n_inputs;
    for (uint32_t i = 0; i < nu; ++i) h->row[i] = c->input_of[i] >= 0 ? h->meas_v[c->input_of[i]] : v[i];
    for (uint32_t j = 0; j < c->n_outputs; ++j) h->row[nu + j] = h->meas_v[c->output_of[j]];
}

/* The values to write at this tick: v, or a step of max_step towards v when missed ticks left the last value
 * written too far from it (that tick is then not the designed value: *off = 1). */
void msid__hx_limited(msid_hx *h, double *v, int *off)
{
    const msid_hx_cfg *c = &h->cfg;
    *off = 0;
    for (uint32_t i = 0; i < c->design->n_inputs; ++i) {
        const double s = c->drive[i].max_step, d = v[i] - h->cur[i];
        if (!isnan(s) && fabs(d) > s * (1.0 + 1e-9)) {
            v[i] = h->cur[i] + (d > 0 ? s : -s);
            *off = 1;
        }
    }
}

/* One write of values v, checked against the limits first. */
int msid__hx_check_write(msid_hx *h, const double *v)
{
    const msid_hx_cfg *c = &h->cfg;
    for (uint32_t i = 0; i < c->design->n_inputs; ++i)
        if (breaks_limit(&c->drive[i], h->cur[i], v[i]))
            return msid__hx_fail(h, -MSID_DAQ_E_ARG, "refused to write %.6g to '%s' (outside its limits, or a step beyond "
                        "max_step from %.6g)", v[i], c->drive[i].name ? c->drive[i].name : "drive", h->cur[i]);
    return 0;
}

/* A measured tick, placed by the tick's own index: a failed exchange or a value off the design is missing. */
static void stream_by_tick(msid_hx *h, uint64_t idx, uint64_t *next_meas, int ok, const double *v,
                           const msid_devio_times *t, int64_t deadline)
{
    if (idx > *next_meas) {
        h->cnt.missed += idx - *next_meas;
        msid__hx_lose(h, idx - *next_meas);
    }
    if (!ok) msid__hx_lose(h, 1);
    else {
        msid__hx_note_timing(h, t, deadline);
        msid__hx_make_row(h, v);
        msid_stream_row(&h->st, h->row);
        h->cnt.samples++;
    }
    *next_meas = idx + 1;
}

int msid__hx_exchange(msid_hx *h, const double *v, msid_devio_times *t, int measured)
{
    msid_hx_cfg *c = &h->cfg;
    memset(t, 0, sizeof *t);
    const int x = msid_devio_exchange(c->io, v, h->meas_v, t);
    memcpy(h->cur, v, sizeof(double) * c->design->n_inputs);
    h->written = 1;
    if (x >= 0) {
        h->last_ok_ns = t->r1 ? t->r1 : msid_now_ns();
        return 0;
    }
    if (measured) h->cnt.failed++;
    else h->cnt.failed_other++;
    h->cnt.recoveries++;
    msid_devio_recover(c->io);
    if (msid_now_ns() - h->last_ok_ns > (int64_t)c->silence_ms * 1000000)
        return msid__hx_fail(h, -MSID_DAQ_E_TIMEOUT, "the device did not answer for %u ms (%llu exchange(s) failed in "
                             "all): %s", c->silence_ms, (unsigned long long)(h->cnt.failed + h->cnt.failed_other),
                             msid_devio_error(c->io));
    return 1;
}

/* The experiment on the host's ticks: tick n writes sample n of the timeline and its read is sample n. */
static int run_by_tick(msid_hx *h, const msid__hx_phase *p)
{
    msid_hx_cfg *c = &h->cfg;
    const uint64_t m0 = p->A + p->F, m1 = m0 + p->K;   /* the measured ticks [m0, m1) */
    uint64_t next_meas = 0, prev_n = UINT64_MAX;
    int prev_ok = 0;
    double v[MSID_MAX_INPUTS];
    int rc = 0;
    for (;;) {
        const uint64_t n = msid_tick_wait(&h->tick, NULL, NULL);
        if (n >= p->total) break;
        h->cnt.ticks++;
        msid__hx_values_at(c, p, &h->gen, n, v);
        int off = 0;
        msid__hx_limited(h, v, &off);
        if ((rc = msid__hx_check_write(h, v)) < 0) break;
        msid_devio_times t;
        const int measured = n >= m0 && n < m1;
        if (measured) h->cnt.measured_ticks++;
        const int x = msid__hx_exchange(h, v, &t, measured);
        if (x < 0) { rc = x; break; }
        if (x == 0 && c->counter >= 0)   /* the device's clock, observed */
            msid__hx_note_counter(h, h->meas_v[c->counter], (int64_t)msid__hx_mid_ns(t.r0, t.r1), prev_ok && prev_n + 1 == n);
        prev_ok = x == 0;
        prev_n = n;
        if (measured) stream_by_tick(h, n - m0, &next_meas, x == 0 && !off, v, &t, msid_tick_deadline(&h->tick, n));
        if (c->on_tick && c->on_tick(c->user)) { rc = -MSID_DAQ_E_STOPPED; break; }
        if (h->st.err != MSID_OK) { rc = msid_daq_core(h->st.err); break; }
    }
    /* measured ticks never reached (the loop fell behind past their end) are missing too */
    if (rc == 0 && next_meas < p->K) {
        h->cnt.missed += p->K - next_meas;
        msid__hx_lose(h, p->K - next_meas);
    }
    return rc;
}

int msid_hx_run(msid_hx *h, uint32_t e)
{
    if (!h->ready) return -MSID_DAQ_E_ARG;
    msid_hx_cfg *c = &h->cfg;
    if (e >= c->design->n_experiments)
        return msid__hx_fail(h, -MSID_DAQ_E_ARG, "experiment %u of %u", e + 1, c->design->n_experiments);
    const msid_gen_cfg gc = gen_cfg(c, e);
    msid_status st = msid_gen_init(&h->gen, &gc, h->gen_mem, h->gen_len);
    if (st != MSID_OK) return msid_daq_core(st);
    const msid__hx_phase p = msid__hx_phases(c, e);
    st = msid_stream_begin(&h->st, e);
    if (st != MSID_OK) return msid_daq_core(st);
    msid_tick_start(&h->tick, 0);   /* a followed device's rate is kept (period_ns) */
    h->last_ok_ns = msid_now_ns();
    const int by_counter = c->counter >= 0 && (c->index_by_counter || c->follow_counter);
    int rc = by_counter ? msid__hx_run_counter(h, &p) : run_by_tick(h, &p);
    st = msid_stream_end(&h->st);
    if (rc == 0 && st != MSID_OK) rc = msid_daq_core(st);
    return rc;
}

int msid_hx_finish(msid_hx *h)
{
    if (!h->ready) return -MSID_DAQ_E_ARG;
    const msid_hx_cfg *c = &h->cfg;
    const uint32_t nu = c->design->n_inputs;
    uint64_t T = 0;
    double from[MSID_MAX_INPUTS], v[MSID_MAX_INPUTS];
    memcpy(from, h->cur, sizeof(double) * nu);
    for (uint32_t i = 0; i < nu; ++i) {
        const uint64_t t = ramp_ticks(&c->drive[i], from[i], c->drive[i].safe, c->design->period);
        if (t > T) T = t;
    }
    if (T > 1) {
        msid_tick_start(&h->tick, 0);
        for (;;) {
            const uint64_t n = msid_tick_wait(&h->tick, NULL, NULL);
            if (n + 1 >= T) break;
            for (uint32_t i = 0; i < nu; ++i) {
                const msid_hx_drive *d = &c->drive[i];
                const uint64_t own = ramp_ticks(d, from[i], d->safe, c->design->period);
                const double f = own == 0 ? 1.0 : fmin(1.0, (double)(n + 1) / (double)own);
                v[i] = from[i] + (d->safe - from[i]) * f;
            }
            int off = 0;
            msid__hx_limited(h, v, &off);
            msid_devio_times t;
            memset(&t, 0, sizeof t);
            if (msid_devio_write(c->io, v, &t) == 0) memcpy(h->cur, v, sizeof(double) * nu);
            else msid_devio_recover(c->io);
        }
    }
    return msid_hx_safe(h, 5);
}

int msid_hx_safe(msid_hx *h, uint32_t attempts)
{
    if (!h->ready) return -MSID_DAQ_E_ARG;
    const msid_hx_cfg *c = &h->cfg;
    const uint32_t nu = c->design->n_inputs;
    double v[MSID_MAX_INPUTS];
    for (uint32_t i = 0; i < nu; ++i) v[i] = c->drive[i].safe;
    int rc = -MSID_DAQ_E_IO;
    for (uint32_t a = 0; a < (attempts ? attempts : 1); ++a) {
        msid_devio_times t;
        memset(&t, 0, sizeof t);
        if ((rc = msid_devio_write(c->io, v, &t)) == 0) {
            memcpy(h->cur, v, sizeof(double) * nu);
            return 0;
        }
        msid_devio_recover(c->io);
    }
    return msid__hx_fail(h, rc, "the safe values could not be written: %s", msid_devio_error(c->io));
}
