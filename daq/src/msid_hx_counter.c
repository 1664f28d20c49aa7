/* msid_hx on the device's cycles (a counter channel): the excitation and the samples are indexed by the cycle
 * the device counts, so that the host's jitter, a late or missed tick and the device's clock offset change only
 * when a value is written, never which cycle applies which sample.
 *
 * Every exchange writes first and reads second (one FC 23 transaction, or a write followed by a read): its read
 * returns the last cycle j the device ran, and its write reaches the device before cycle j + 1. So at each tick
 * the host writes the sample of cycle (last cycle read) + 2, which is j + 1 when the device ran one cycle since
 * the last read. When it ran another number (the read landed on a cycle boundary, a tick was late, the clocks
 * drift), the cycles whose applied value is not their sample are marked and become missing samples, and the
 * timeline follows the device's count. Where the write and the counter's read are two transactions (no FC 23,
 * or a counter FC 23 does not read), a cycle that falls between them may or may not have taken the write, and
 * the read after it looks the same either way (a cycle boundary that stays there would shift every sample by
 * one without a glitch): the backend then reads the counter just before the write too, and a counter that
 * moved between the two reads marks the cycles that may have run on the wrong value. A read that lands on a boundary from an on-time tick moves the ticks by
 * half a period (at most once a period); with follow_counter the ticks also take the counter's rate once a
 * period. */
#include "msid_hx_internal.h"

#include <math.h>
#include <string.h>

/* A window of the cycles ahead whose applied value is not their sample (bit c - base). */
typedef struct off_window {
    double base;        /* cycle of bit 0 */
    uint64_t bits;
} off_window;

static void off_mark(off_window *w, double cycle)
{
    const double d = cycle - w->base;
    if (d >= 0 && d < 64) w->bits |= (uint64_t)1 << (int)d;
}


/* The check that the device cycles once a tick, over windows of RATE_WINDOW reads: the cycles per tick elapsed (the
   ticks a loaded host slept through included: per read, every missed tick looked like a device cycling twice as
   fast; a read late within its tick moves the ratio by at most 1 / RATE_WINDOW). A window off the rate starts
   another, and RATE_WINDOWS windows off in a row refuse the device: one starved window of a loaded machine (a
   device that catches up its cycles in a burst) is not a device at another rate. */
#define RATE_WINDOW 32u
#define RATE_WINDOWS 3u
typedef struct rate_window {
    uint64_t n0;      /* the window's first tick */
    double j0;        /* the cycle count read at it */
    uint64_t reads0;  /* reads before the window */
    unsigned off;     /* windows off the rate in a row */
    int done;         /* a window at the rate was seen: no more checks */
} rate_window;

static int check_cycles_per_tick(msid_hx *h, rate_window *w, uint64_t n, double j)
{
    if (w->done) return 0;
    const uint64_t *cs = h->cnt.counter_steps;
    const uint64_t reads = cs[0] + cs[1] + cs[2] + cs[3];
    if (reads - w->reads0 < RATE_WINDOW) return 0;
    const double per_tick = n > w->n0 ? (j - w->j0) / (double)(n - w->n0) : 1.0;
    if (per_tick > 0.75 && per_tick < 1.25) {
        w->done = 1;
        return 0;
    }
    if (++w->off >= RATE_WINDOWS)
        return msid__hx_fail(h, -MSID_DAQ_E_DEVICE, "the device's counter advanced by %.2f per tick over %llu ticks "
                             "(once a tick expected; %u windows of %u reads in a row): it does not cycle at the tick "
                             "rate (about %.0f Hz); state its cycle_hz in the description (the samples are then placed "
                             "by tick), or tick at its rate", per_tick, (unsigned long long)(n - w->n0), RATE_WINDOWS,
                             RATE_WINDOW, per_tick * h->cfg.tick.rate_hz);
    w->n0 = n;
    w->j0 = j;
    w->reads0 = reads;
    return 0;
}

static int off_test(const off_window *w, double cycle)
{
    const double d = cycle - w->base;
    return d >= 0 && d < 64 && ((w->bits >> (int)d) & 1u);
}

/* Slide the window so that its first bit is `cycle`. */
static void off_slide(off_window *w, double cycle)
{
    const double d = cycle - w->base;
    if (d <= 0) return;
    w->bits = d >= 64 ? 0 : w->bits >> (int)d;
    w->base = cycle;
}

typedef struct counter_run {
    const msid__hx_phase *p;
    uint64_t m0;            /* first measured sample of the timeline */
    double j0;              /* the cycle of timeline sample 0 */
    double j_last;          /* the last cycle read */
    double j_row;           /* the last cycle streamed (or -1) */
    uint64_t next_meas;     /* index of the next measured sample the stream expects */
    int resync;             /* the last exchange failed: the next read re-anchors */
    uint64_t last_shift;    /* tick of the last half-period shift */
    uint64_t last_glitch;   /* tick of the last glitch on an on-time tick */
    uint64_t last_phase;    /* tick of the last move to mid-cycle (keep_mid_cycle) */
    uint64_t next_retime;
    int anchored;           /* the anchor was confirmed by the read after it, or moved once */
    off_window off;
} counter_run;

/* The timeline from cycle j read at tick n: the first write of the timeline (sample 0) reaches cycle j + 1 at the
   next tick's exchange; the device runs one cycle per tick, so that exchange reads j + 1 and writes for j + 2. */
static void anchor_at(counter_run *r, rate_window *rw, uint64_t n, double j, uint64_t period)
{
    r->j_last = j;
    r->j0 = j + 2;
    r->off.base = j;
    r->off.bits = 0;
    r->next_retime = n + period;
    rw->n0 = n;
    rw->j0 = j;
}

/* Whether the read of cycle j, the first after the anchor, shows the anchor stale: a device that cycles once a
   tick cannot have run more than two cycles since (one more for a tick that ran late). A transport that queues the
   status (a CAN socket) returns at the run's first exchange what was queued before it, and a queue that filled
   while the host prepared the run holds only old frames: the anchor would then be many cycles behind the device,
   the timeline's samples would all have passed, and the run would end at once with every sample missing. */
static int anchor_stale(const counter_run *r, double j) { return !r->anchored && j - r->j_last > 2; }

/* follow_counter: the tick clock at the counter's rate, once a period from two periods of reads on. */
static void follow_rate(msid_hx *h, counter_run *r, uint64_t n)
{
    const uint64_t P = h->cfg.design->period;
    if (!h->cfg.follow_counter || n < r->next_retime || h->tim.cs_n < 2.0 * (double)P) return;
    r->next_retime = n + P;
    const double rate = msid_hx_counter_rate(h);
    if (!(rate > 0.99 * h->cfg.tick.rate_hz && rate < 1.01 * h->cfg.tick.rate_hz)) return;
    msid_tick_retime(&h->tick, 1e9 / rate, 0);
    h->cnt.retimes++;
}

/* A backend that sees the device's cycle begin (msid_devio_times::phase_ns): the ticks moved to the middle of the
   cycle when they are more than an eighth of a period off it, at most once every 16 ticks, so that each write has
   half a cycle before the next cycle takes it and each read half a cycle for the answers to come in. */
static void keep_mid_cycle(msid_hx *h, counter_run *r, uint64_t n, const msid_devio_times *t)
{
    if (!t->has_phase || n < r->last_phase + 16) return;
    const double T = h->tick.period_ns;
    double err = fmod((double)t->phase_ns, T) - 0.5 * T;
    if (err > 0.5 * T) err -= T;
    if (err < -0.5 * T) err += T;
    if (fabs(err) <= 0.125 * T) return;
    msid_tick_retime(&h->tick, T, (int64_t)-err);
    h->cnt.phase_shifts++;
    r->last_phase = n;
}

/* The cycles the device ran between the counter's read before the write and its read after it (0 when the
   write and the read were one transaction, or nothing ran between them); at most the cycles since the last read. */
static double straddled_cycles(const msid_hx *h, const msid_devio_times *t, double raw_after, double step)
{
    if (!t->has_counter_before || !isfinite(t->counter_before)) return 0;
    const double M = h->cfg.counter_modulus > 0 ? h->cfg.counter_modulus : 65536.0;
    double d = fmod(raw_after - t->counter_before, M);
    if (d < 0) d += M;
    return d < step ? d : step < 0 ? 0 : step;
}

/* The read of cycle j (after the write of `target`): which cycles got the wrong value, the row, the phase. */
static void account_read(msid_hx *h, counter_run *r, uint64_t n, double j, double target, int on_time,
                         double straddled, const msid_devio_times *t)
{
    const double step = j - r->j_last;
    if (step != 1 || r->resync || straddled > 0) {
        /* the write went to cycle j + 1, not to `target`; the cycles since the last read ran on values written for
           other cycles */
        if (step != 1 || r->resync)
            for (double c = r->j_last + 1; c <= j + 1; c += 1) off_mark(&r->off, c);
        /* the cycles that ran between the counter's read before the write and the read after it took the new
           value or the old one: either may not be theirs */
        for (double c = j - straddled + 1; c <= j; c += 1) off_mark(&r->off, c);
        if (straddled > 0) h->cnt.writes_straddled++;
        if (step < 1 && !r->resync) h->cnt.cycles_read_twice++;
        /* a read on a cycle boundary shows as glitches that repeat on ticks that ran on time; a late tick or a late
           answer is a one-off that must not move a good phase */
        if (on_time && !r->resync && step >= 0 && step <= 2) {
            if (n <= r->last_glitch + 32 && n >= r->last_shift + 16) {
                msid_tick_retime(&h->tick, h->tick.period_ns, (int64_t)(0.5 * h->tick.period_ns));
                h->cnt.phase_shifts++;
                r->last_shift = n;
            }
            r->last_glitch = n;
        }
        (void)target;
    }
    r->resync = 0;
    if (j > r->j_last) r->j_last = j;
    /* the row of cycle j, once, in the measured periods */
    if (j <= r->j_row) return;
    r->j_row = j;
    const double k = j - r->j0;
    if (k < (double)r->m0 || k >= (double)(r->m0 + r->p->K)) return;
    const uint64_t idx = (uint64_t)(k - (double)r->m0);
    if (idx > r->next_meas) {
        h->cnt.cycles_not_read += idx - r->next_meas;
        msid__hx_lose(h, idx - r->next_meas);
    }
    if (off_test(&r->off, j)) {
        h->cnt.cycles_not_read++;
        msid__hx_lose(h, 1);
    } else {
        /* the commanded value of cycle j is its sample */
        double v[MSID_MAX_INPUTS];
        msid__hx_values_at(&h->cfg, r->p, &h->gen, (uint64_t)k, v);
        msid__hx_note_timing(h, t, msid_tick_deadline(&h->tick, n));
        msid__hx_make_row(h, v);
        msid_stream_row(&h->st, h->row);
        h->cnt.samples++;
    }
    r->next_meas = idx + 1;
}

int msid__hx_run_counter(msid_hx *h, const msid__hx_phase *p)
{
    msid_hx_cfg *c = &h->cfg;
    counter_run r;
    memset(&r, 0, sizeof r);
    r.p = p;
    r.m0 = p->A + p->F;
    r.j_row = -1;
    r.last_glitch = r.last_shift = 0;
    double v[MSID_MAX_INPUTS];
    int rc = 0, synced = 0;
    rate_window rw = {0, 0, 0, 0, 0};
    const int64_t on_time_ns = (int64_t)(0.1 * h->tick.period_ns);
    int64_t prev_late = 0;
    for (;;) {
        int64_t late = 0;
        const uint64_t n = msid_tick_wait(&h->tick, NULL, &late);
        h->cnt.ticks++;
        double target = 0;
        int off = 0;
        if (!synced) {
            memcpy(v, h->cur, sizeof(double) * c->design->n_inputs);   /* what the device holds: learn its cycle */
        } else {
            target = r.j_last + 2;
            const double k = target - r.j0;
            if (k >= (double)p->total) break;
            msid__hx_values_at(c, p, &h->gen, (uint64_t)k, v);
            msid__hx_limited(h, v, &off);
            if ((rc = msid__hx_check_write(h, v)) < 0) break;
            if (k >= (double)r.m0 && k < (double)(r.m0 + p->K)) h->cnt.measured_ticks++;
        }
        msid_devio_times t;
        const int x = msid__hx_exchange(h, v, &t, synced);
        if (x < 0) { rc = x; break; }
        if (x == 1) {
            r.resync = 1;
        } else {
            keep_mid_cycle(h, &r, n, &t);
            const double before = h->tim.c_unwrapped;
            const int first = h->tim.cs_n == 0;
            msid__hx_note_counter(h, h->meas_v[c->counter], (int64_t)msid__hx_mid_ns(t.r0, t.r1), 0);
            const double j = h->tim.c_unwrapped;   /* the cycle count since the run's first read */
            if (!first && j - before == 1) h->cnt.counter_steps[1]++;
            else if (!first) h->cnt.counter_steps[j - before == 0 ? 0 : j - before == 2 ? 2 : 3]++;
            if (!synced) {
                anchor_at(&r, &rw, n, j, c->design->period);
                synced = 1;
            } else if (anchor_stale(&r, j)) {
                /* this tick wrote sample 0 for the stale anchor: it reaches cycle j + 1, before the new timeline */
                anchor_at(&r, &rw, n, j, c->design->period);
                h->cnt.stale_anchors++;
                r.anchored = 1;   /* once: a device that runs faster than the ticks is refused by the rate check */
            } else {
                r.anchored = 1;
                if ((rc = check_cycles_per_tick(h, &rw, n, j)) < 0) break;
                off_slide(&r.off, r.j_last + 1 < j ? r.j_last + 1 : j);
                if (off) off_mark(&r.off, j + 1);
                account_read(h, &r, n, j, target, late < on_time_ns && prev_late < on_time_ns,
                             straddled_cycles(h, &t, h->meas_v[c->counter], j - r.j_last), &t);
                follow_rate(h, &r, n);
            }
        }
        prev_late = x == 0 ? late : INT64_MAX;
        if (c->on_tick && c->on_tick(c->user)) { rc = -MSID_DAQ_E_STOPPED; break; }
        if (h->st.err != MSID_OK) { rc = msid_daq_core(h->st.err); break; }
    }
    if (rc == 0 && r.next_meas < p->K) {
        h->cnt.cycles_not_read += p->K - r.next_meas;
        msid__hx_lose(h, p->K - r.next_meas);
    }
    return rc;
}
