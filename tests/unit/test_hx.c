/* msid_hx, the host-timed excitation runner, against an in-memory device on the real tick clock:
 *  - the rows reach the core in order: the period means give the device's FIR response exactly at every line,
 *    with the read-back input and with the commanded one;
 *  - only the measured periods reach the core (fade-in and fade-out do not), and the values written follow the
 *    phases: the approach from the safe value, the fade-in, the measured periods, the fade-out, the ramp to safe;
 *  - an exchange that fails is a missing sample: counted, and its period rejected, never averaged in;
 *  - a value beyond a limit is refused by msid_hx_init before anything is written;
 *  - a stop request ends the run with the complete periods kept; the safe values are written last.
 * The tick clock runs at 1 kHz under SCHED_FIFO where permitted: a loaded machine may still miss ticks, which
 * the runner records; the checks that need every tick say so and judge by what was recorded, never by the
 * clock. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "msid/msid.h"
#include "msid_daq/msid_hx.h"

#define P 64u
#define NL 3u
static const uint32_t BINS[NL] = {1, 5, 11};
static uint8_t TWM[1 << 14] __attribute__((aligned(64)));
static uint8_t DMEM[1 << 16] __attribute__((aligned(64)));
static uint8_t MMEM[1 << 20] __attribute__((aligned(64)));
static uint8_t HMEM[1 << 20] __attribute__((aligned(64)));

/* ---- the device: y[n] = 0.5 u[n] + 0.3 u[n-1], the input read back as applied ------------------------ */
typedef struct fake {
    const msid_hx *h;
    double u_prev, last_written;
    uint64_t last_tick, exchanges, writes;
    uint64_t fail_from, fail_to;        /* the exchanges of ticks [from, to) fail */
    uint64_t failed;                    /* exchanges failed on purpose */
    double wmin, wmax, max_step_seen;
    int first;
} fake;

static int fx_exchange(void *ctx, const double *drive, double *meas, msid_devio_times *t)
{
    fake *f = ctx;
    f->exchanges++;
    const uint64_t tick = f->h->tick.next - 1;
    t->w0 = t->r0 = msid_now_ns();
    t->w1 = t->r1 = t->w0 + 1000;
    if (tick >= f->fail_from && tick < f->fail_to) {
        f->failed++;
        return -MSID_DAQ_E_TIMEOUT;
    }
    const double u = drive[0];
    if (!f->first && fabs(u - f->last_written) > f->max_step_seen) f->max_step_seen = fabs(u - f->last_written);
    f->first = 0;
    if (u < f->wmin) f->wmin = u;
    if (u > f->wmax) f->wmax = u;
    f->last_written = u;
    meas[0] = u;                              /* input read back */
    meas[1] = 0.5 * u + 0.3 * f->u_prev;      /* output */
    f->u_prev = u;
    return 0;
}

static int fx_write(void *ctx, const double *drive, msid_devio_times *t)
{
    fake *f = ctx;
    (void)t;
    f->writes++;
    if (!f->first && fabs(drive[0] - f->last_written) > f->max_step_seen) f->max_step_seen = fabs(drive[0] - f->last_written);
    f->last_written = drive[0];
    return 0;
}

static int fx_read(void *ctx, double *meas, msid_devio_times *t)
{
    (void)ctx; (void)meas; (void)t;
    return 0;
}
static const char *fx_error(void *ctx) { (void)ctx; return "injected timeout"; }
static const msid_devio_backend FAKE = {"fake", fx_exchange, fx_write, fx_read, NULL, fx_error, NULL};

/* ---- the bench ----------------------------------------------------------------------------------- */
typedef struct bench {
    msid_twiddle tw;
    msid_design d;
    msid_meas ms;
    msid_hx h;
    msid_devio io;
    fake dev;
    msid_hx_cfg c;
} bench;

static void setup(bench *b, uint32_t K, uint32_t fade, int readback, double max, double max_step)
{
    memset(b, 0, sizeof *b);
    assert_int_equal(msid_twiddle_init(&b->tw, P, TWM, sizeof TWM), MSID_OK);
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = P; dc.n_lines = NL; dc.bins = BINS; dc.phase_mode = MSID_PHASE_SCHROEDER; dc.n_inputs = 1;
    dc.n_experiments = 1; dc.twiddle = &b->tw;
    assert_true(msid_design_mem_size(&dc) <= sizeof DMEM);
    assert_int_equal(msid_design_init(&b->d, &dc, DMEM, sizeof DMEM), MSID_OK);
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = 1; mc.n_lines = NL; mc.bins = BINS;
    mc.twiddle = &b->tw; mc.path = MSID_DFT_STREAM; mc.transient = MSID_TRANSIENT_OFF; mc.max_periods = 4 * K;
    assert_true(msid_meas_mem_size(&mc) <= sizeof MMEM);
    assert_int_equal(msid_meas_init(&b->ms, &mc, MMEM, sizeof MMEM), MSID_OK);
    b->dev.first = 1;
    b->dev.wmin = INFINITY;
    b->dev.wmax = -INFINITY;
    b->dev.fail_from = b->dev.fail_to = UINT64_MAX;
    b->io.be = &FAKE;
    b->io.ctx = &b->dev;
    msid_hx_cfg *c = &b->c;
    c->design = &b->d; c->twiddle = &b->tw; c->periods = K; c->fade_periods = fade; c->n_measure = 2;
    c->drive[0] = (msid_hx_drive){.op = 0.25, .gain = 1.0, .min = -10, .max = max, .max_step = max_step,
                                  .safe = 0.0, .name = "u"};
    c->input_of[0] = readback ? 0 : -1;
    c->n_outputs = 1;
    c->output_of[0] = 1;
    c->counter = -1;
    c->io = &b->io;
    c->meas = &b->ms;
    c->tick.rate_hz = 1000;
    c->tick.realtime = 1;   /* SCHED_FIFO where permitted (CI runs as root): the exact checks then run */
    b->dev.h = &b->h;
}

static int init(bench *b)
{
    const size_t need = msid_hx_mem_size(&b->c);
    assert_true(need > 0 && need <= sizeof HMEM);
    return msid_hx_init(&b->h, &b->c, HMEM, sizeof HMEM);
}

/* G of every line from the period means: Y / U against 0.5 + 0.3 e^{-j w}. */
static double worst_error(const msid_meas *ms)
{
    double worst = 0;
    for (uint32_t l = 0; l < NL; ++l) {
        const msid_cplx *mu = msid_pstats_mean(msid_meas_stats(ms, 0), l);
        const double den = mu[0].re * mu[0].re + mu[0].im * mu[0].im;
        const double gre = (mu[1].re * mu[0].re + mu[1].im * mu[0].im) / den;
        const double gim = (mu[1].im * mu[0].re - mu[1].re * mu[0].im) / den;
        const double w = 6.283185307179586 * BINS[l] / P;
        const double tre = 0.5 + 0.3 * cos(w), tim = -0.3 * sin(w);
        const double e = hypot(gre - tre, gim - tim);
        if (e > worst) worst = e;
    }
    return worst;
}

static void rows_give_the_device_response(void **st)
{
    (void)st;
    for (int readback = 0; readback <= 1; ++readback) {
        static bench b;
        setup(&b, 4, 1, readback, 10, NAN);
        assert_int_equal(init(&b), 0);
        assert_int_equal(msid_hx_run(&b.h, 0), 0);
        const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(&b.ms, 0));
        /* every measured tick is a row, a missed tick or a failure: nothing else */
        assert_true(b.h.cnt.measured_ticks + b.h.cnt.missed >= 4 * P);   /* plus late-landing jumps */
        assert_int_equal(b.h.cnt.samples + b.h.cnt.missed + b.h.cnt.failed, 4 * P);
        assert_int_equal(k.offered, 4);
        /* the approach (0.25 at one period: no max_step) and both fades ran: P + 2 P + 4 P ticks; a loaded machine's
           last wait may sleep through ticks past the end too, which the tick clock counts as missed */
        if (b.h.tick.missed == 0) assert_int_equal(b.h.cnt.ticks, 7 * P);
        else assert_true(b.h.cnt.ticks + b.h.tick.missed >= 7 * P);
        if (b.h.tick.missed == 0) {
            assert_int_equal(k.used, 4);
            const double e = worst_error(&b.ms);
            if (e > 1e-12) fail_msg("readback %d: G off by %g", readback, e);
        } else {
            print_message("note: %llu tick(s) missed on this machine: the exact response is not checked\n",
                          (unsigned long long)b.h.tick.missed);
        }
        assert_int_equal(msid_hx_finish(&b.h), 0);
        assert_true(b.dev.last_written == 0.0);   /* the safe value, last */
        msid_hx_release(&b.h);
    }
}

static void failed_exchanges_are_missing_samples(void **st)
{
    (void)st;
    static bench b;
    setup(&b, 5, 1, 1, 10, NAN);
    /* the ticks 3P + 10 .. 3P + 13: inside the second measured period (approach P, fade-in P) */
    b.dev.fail_from = 3 * P + 10;
    b.dev.fail_to = 3 * P + 14;
    assert_int_equal(init(&b), 0);
    assert_int_equal(msid_hx_run(&b.h, 0), 0);
    /* every failure the device made is a counted missing sample (a tick of them the loop slept through is a
       missed one instead) */
    assert_int_equal(b.h.cnt.failed, b.dev.failed);
    assert_true(b.dev.failed <= 4);
    const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(&b.ms, 0));
    assert_true(k.gap >= 1);   /* the period they touch is rejected (and any with a missed tick) */
    assert_int_equal(k.used + k.gap, 5);
    assert_int_equal(b.h.cnt.samples + b.h.cnt.missed + b.h.cnt.failed, 5 * P);
    msid_hx_safe(&b.h, 1);
    msid_hx_release(&b.h);
}

static void limits_refused_before_any_write(void **st)
{
    (void)st;
    static bench b;
    setup(&b, 4, 1, 1, 0.9, NAN);   /* op 0.25 + the multisine's peak (about 1.4 for 3 Schroeder lines) > 0.9 */
    assert_int_equal(init(&b), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(b.h.err, "'u' would reach"));
    assert_non_null(strstr(b.h.err, "above max"));
    assert_int_equal(b.dev.exchanges + b.dev.writes, 0);
    setup(&b, 4, 0, 1, 10, 0.05);   /* no fade: the first excitation step is the multisine's first sample */
    assert_int_equal(init(&b), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(b.h.err, "max_step"));
    assert_int_equal(b.dev.exchanges + b.dev.writes, 0);
}

static void steps_and_range_hold_in_every_phase(void **st)
{
    (void)st;
    static bench b;
    setup(&b, 3, 2, 1, 10, 2.0);   /* a max_step the fades and the periods keep (checked by init) */
    assert_int_equal(init(&b), 0);
    assert_int_equal(msid_hx_run(&b.h, 0), 0);
    assert_int_equal(msid_hx_finish(&b.h), 0);
    assert_true(b.dev.max_step_seen <= 2.0 * (1 + 1e-9));
    assert_true(b.dev.wmax <= 10 && b.dev.wmin >= -10);
    assert_true(b.dev.last_written == 0.0);
    msid_hx_release(&b.h);
}

static int stop_after(void *user)
{
    const msid_hx *h = user;
    return h->tick.next >= 4 * P + P / 2;   /* tick index: in the third measured period */
}

static void a_stop_keeps_complete_periods(void **st)
{
    (void)st;
    static bench b;
    setup(&b, 6, 1, 1, 10, NAN);
    b.c.on_tick = stop_after;
    b.c.user = &b.h;
    assert_int_equal(init(&b), 0);
    assert_int_equal(msid_hx_run(&b.h, 0), -MSID_DAQ_E_STOPPED);
    const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(&b.ms, 0));
    assert_int_equal(k.offered, 2);   /* the third, incomplete period is left over, not used */
    assert_int_equal(msid_hx_finish(&b.h), 0);
    assert_true(b.dev.last_written == 0.0);
    msid_hx_release(&b.h);
}

/* ---- a device that counts its cycles, one per exchange, with no clock of its own ------------------------
 * Each exchange writes, then reads. A device cycle (y = 0.5 u[c] + 0.3 u[c-1], u[c] the setpoint cycle c ran
 * on) falls before the write, except on every 7th exchange, where it falls between the write and the read: that
 * cycle runs on the value written for the next one, and the counter read after it steps by one as always. Only
 * the counter's read before the write (msid_devio_times.counter_before) can tell the two apart. */
typedef struct cycler {
    double setpoint, u_prev, y, applied;
    uint64_t count, exchanges, straddles;
    int report_before;
} cycler;

static void cy_cycle(cycler *d)
{
    d->applied = d->setpoint;
    d->y = 0.5 * d->applied + 0.3 * d->u_prev;
    d->u_prev = d->applied;
    d->count++;
}

static int cy_exchange(void *ctx, const double *drive, double *meas, msid_devio_times *t)
{
    cycler *d = ctx;
    t->w0 = t->r0 = msid_now_ns();
    t->w1 = t->r1 = t->w0 + 1000;
    const uint64_t e = d->exchanges++;
    const int straddle = e >= 3 * P + 16 && e < 3 * P + 48 && e % 7 == 3;   /* within one measured period */
    if (!straddle) cy_cycle(d);
    const uint64_t before = d->count;
    d->setpoint = drive[0];
    if (straddle) {
        cy_cycle(d);
        d->straddles++;
    }
    t->has_counter_before = d->report_before;
    t->counter_before = (double)(before % 65536);
    meas[0] = d->applied;
    meas[1] = d->y;
    meas[2] = (double)(d->count % 65536);
    return 0;
}

static int cy_write(void *ctx, const double *drive, msid_devio_times *t)
{
    (void)t;
    ((cycler *)ctx)->setpoint = drive[0];
    return 0;
}

static const msid_devio_backend CYCLER = {"cycler", cy_exchange, cy_write, fx_read, NULL, fx_error, NULL};

static void a_cycle_between_write_and_read_is_a_missing_sample(void **st)
{
    (void)st;
    for (int report = 0; report <= 1; ++report) {
        static bench b;
        static cycler d;
        setup(&b, 6, 1, 0, 10, NAN);   /* the commanded input: the device's cycle decides what it applied */
        memset(&d, 0, sizeof d);
        d.report_before = report;
        b.io.be = &CYCLER;
        b.io.ctx = &d;
        b.c.n_measure = 3;
        b.c.counter = 2;
        b.c.counter_modulus = 65536;
        b.c.index_by_counter = 1;
        assert_int_equal(init(&b), 0);
        const int rc = msid_hx_run(&b.h, 0);
        const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(&b.ms, 0));
        if (report) {
            /* every straddled write is seen and its cycles are missing samples: a period holding one is
               rejected, and the periods used give the device's response exactly */
            assert_int_equal(rc, 0);
            assert_int_equal(b.h.cnt.writes_straddled, d.straddles);
            assert_true(b.h.cnt.cycles_not_read >= d.straddles);
            assert_int_equal(k.used, 5);
            if (worst_error(&b.ms) > 1e-12) fail_msg("G off by %g", worst_error(&b.ms));
        } else {
            /* the counter alone steps by one at every read: the straddled cycles ran on another cycle's value
               unseen, and the estimate is off (what the read before the write is there for) */
            assert_int_equal(rc, 0);
            assert_int_equal(b.h.cnt.writes_straddled, 0);
            assert_int_equal(k.used, 6);
            if (!(worst_error(&b.ms) > 1e-3)) fail_msg("unseen straddles left G within %g", worst_error(&b.ms));
        }
        msid_hx_safe(&b.h, 1);
        msid_hx_release(&b.h);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rows_give_the_device_response), cmocka_unit_test(failed_exchanges_are_missing_samples),
        cmocka_unit_test(limits_refused_before_any_write), cmocka_unit_test(steps_and_range_hold_in_every_phase),
        cmocka_unit_test(a_stop_keeps_complete_periods),
        cmocka_unit_test(a_cycle_between_write_and_read_is_a_missing_sample),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
