/* Inside msid_hx (daq/src/msid_hx.c, msid_hx_counter.c): the phases of an experiment, the values of its
 * timeline, the limit checks, one exchange, the bookkeeping of a read. Not a public header. */
#ifndef MSID_HX_INTERNAL_H
#define MSID_HX_INTERNAL_H

#include "msid_daq/msid_hx.h"

/* Where sample k of an experiment's timeline lies: approach [0, A), fade-in [A, A + F), measured
 * [A + F, A + F + K), fade-out up to total. */
typedef struct msid__hx_phase {
    uint64_t A, F, K, total;
} msid__hx_phase;

msid__hx_phase msid__hx_phases(const msid_hx_cfg *c, uint32_t e);
/* The values v[nu] of sample k of the timeline (g: the experiment's generator). */
void msid__hx_values_at(const msid_hx_cfg *c, const msid__hx_phase *p, msid_gen *g, uint64_t k, double *v);
/* At most max_step from the last values written (*off = 1 when v was moved: not the designed value). */
void msid__hx_limited(msid_hx *h, double *v, int *off);
/* 0, or -MSID_DAQ_E_ARG with err when v breaks a limit (nothing is written then). */
int msid__hx_check_write(msid_hx *h, const double *v);
/* One exchange writing v: 0 when it read, 1 when it failed (recovered), < 0 when the device has been silent
 * for silence_ms (err). */
int msid__hx_exchange(msid_hx *h, const double *v, msid_devio_times *t, int measured);
/* A read of the counter at t_ns into the clock's least squares (consecutive: the previous tick read too). */
void msid__hx_note_counter(msid_hx *h, double raw, int64_t t_ns, int consecutive);
/* The timing of a used read relative to its tick's deadline. */
void msid__hx_note_timing(msid_hx *h, const msid_devio_times *t, int64_t deadline);
/* h->row from the read values (read-back inputs) or the values written v (commanded inputs). */
void msid__hx_make_row(msid_hx *h, const double *v);
double msid__hx_mid_ns(int64_t a, int64_t b);
/* n samples of the measured timeline missing (the core marks the gap; the count is cnt.samples_lost). */
void msid__hx_lose(msid_hx *h, uint64_t n);
int msid__hx_fail(msid_hx *h, int rc, const char *fmt, ...);
/* The experiment on the device's cycles (msid_hx_counter.c). */
int msid__hx_run_counter(msid_hx *h, const msid__hx_phase *p);

#endif
