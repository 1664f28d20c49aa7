/**
 * @file msid_hx.h
 * @brief Host-timed excitation of a described device: the host generates the
 *        multisine with lib/ (the same samples as the design file), writes it
 *        to the device's drive channels once per tick of ::msid_tick, reads the
 *        measure channels in the same tick, and streams [u; y] into
 *        ::msid_meas through ::msid_stream.
 *
 * Each experiment runs in phases: an approach from the safe value (which the
 * caller has written before, e.g. while it measured the round trip) to the
 * operating point (at most max_step per tick; over one period without one), `fade_periods` whole
 * periods in which the excitation fades in (raised cosine), the `periods`
 * periods the core measures, and as many periods of fade-out. Only the
 * measured periods reach the core. After the last experiment the drive
 * channels ramp to their safe values and the safe values are written.
 *
 * Safety: every value of every phase is computed and checked against min,
 * max and max_step by ::msid_hx_init, before anything is written; each write
 * is checked again. ::msid_hx_safe writes the safe values (a few attempts);
 * a caller calls it on every way out (the end, a stop, an error).
 *
 * The FRF's inputs are the read-back input channels when the description has
 * them (errors-in-variables: the input the device applied, measured), else the
 * commanded values. A missed tick (::msid_tick) or an exchange that read
 * nothing is a missing sample (::msid_stream_lost): every period it touches is
 * rejected and counted, never interpolated.
 *
 * Timing, for the file and the bias report of a commanded input: per tick the
 * lateness, the round trip of the exchange, and the instants at which the
 * device was written and read (the middle of each transaction, relative to the
 * tick's deadline), as statistics (::msid_tstats, Welford moments).
 *
 * No allocation: memory comes from the caller (::msid_hx_mem_size). Errors are
 * the daq error space (msid_daq.h); h->err says what and why.
 */
#ifndef MSID_HX_H
#define MSID_HX_H

#include "msid/msid.h"
#include "msid_devio.h"
#include "msid_stream.h"
#include "msid_tick.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MSID_HX_MAX_MEASURE 40u

/** A drive channel as the runner sees it (physical units; NAN: no limit). */
typedef struct msid_hx_drive {
    double op;        /**< operating point: the value between excitation phases */
    double gain;      /**< value = op + envelope * gain * x, x the design's sample of this input */
    double min, max, max_step;
    double safe;      /**< written on every way out */
    const char *name; /**< for messages */
} msid_hx_drive;

/** Configuration. */
typedef struct msid_hx_cfg {
    const msid_design *design;     /**< the excitation (n_inputs drive channels, m experiments) */
    const msid_twiddle *twiddle;   /**< the design's period */
    uint32_t periods;              /**< periods per experiment that the core sees (skip periods included), >= 1 */
    uint32_t fade_periods;         /**< periods of fade-in and of fade-out, 0..8 */
    uint32_t n_measure;            /**< measure channels the device returns, 1..MSID_HX_MAX_MEASURE */
    msid_hx_drive drive[MSID_MAX_INPUTS];   /**< design->n_inputs of them */
    int32_t input_of[MSID_MAX_INPUTS];      /**< FRF input i: the measure channel reading it back, -1: commanded */
    uint32_t n_outputs;
    uint32_t output_of[MSID_MAX_OUTPUTS];   /**< FRF output j: its measure channel */
    int32_t counter;               /**< measure channel of the device's cycle counter (-1: none) */
    double counter_modulus;        /**< counts after which the counter wraps (2^16 for a uint16 register, ...) */
    int index_by_counter;          /**< place each read at the device cycle its counter names (a device that cycles
                                        at the tick rate, its input read back): a cycle read twice is dropped, a
                                        cycle not read is a missing sample */
    int follow_counter;            /**< the tick clock follows the device's counter: its rate from the counter's
                                        least squares once a period (implies index_by_counter). In both modes a read
                                        that lands on a cycle boundary (a count step of 0 or 2 between ticks) shifts
                                        the ticks by half a period, at most once a period */
    msid_devio *io;
    msid_meas *meas;               /**< n_inputs + n_outputs channels, the design's lines */
    msid_tick_cfg tick;
    uint32_t silence_ms;           /**< give up when no exchange succeeded for this long (0: 5000) */
    /** Called after every tick (NULL: none); a non-zero return stops the run: see ::msid_hx_run. */
    int (*on_tick)(void *user);
    void *user;
} msid_hx_cfg;

/** Counters (cumulative over the experiments). */
typedef struct msid_hx_counters {
    uint64_t ticks;            /**< ticks run (every phase) */
    uint64_t measured_ticks;   /**< ticks of the measured periods, missed ones included */
    uint64_t missed;           /**< ticks of the measured periods not run (the loop fell behind): missing samples */
    uint64_t failed;           /**< exchanges of the measured periods that read nothing: missing samples */
    uint64_t failed_other;     /**< exchanges of the other phases that failed */
    uint64_t recoveries;       /**< recover() calls after failures */
    uint64_t samples;          /**< rows pushed */
    uint64_t samples_lost;     /**< samples of the measured periods marked missing in the core, whatever the
                                    cause (a missed tick, a failed exchange, a value moved by max_step, a device
                                    cycle not read or run on another cycle's value): samples + samples_lost is
                                    every measured sample */
    uint64_t counter_steps[4]; /**< counter increments between successive read ticks: 0, 1, 2, more */
    uint64_t cycles_read_twice;   /**< index_by_counter: reads of a cycle already read (dropped) */
    uint64_t cycles_not_read;     /**< index_by_counter: device cycles of the measured periods no read returned,
                                       or whose applied value is not their sample */
    uint64_t writes_straddled;    /**< index_by_counter: exchanges whose write a device cycle may have taken or
                                       not (the counter moved between the reads before and after the write) */
    uint64_t stale_anchors;       /**< index_by_counter: first reads of a run that the next read showed stale (the
                                       device had run more than two cycles in one tick: a queue that held status
                                       from before the run); the timeline restarted from the next read */
    uint64_t retimes, phase_shifts;   /**< follow_counter: rate updates, half-period shifts */
} msid_hx_counters;

/** Timing statistics of the measured ticks (ns). */
typedef struct msid_hx_timing {
    msid_tstats rtt;           /**< round trip of each exchange (first request sent .. last answer) */
    msid_tstats apply;         /**< write instant - deadline (the middle of the write transaction) */
    msid_tstats sample;        /**< read instant - deadline (the middle of the read transaction) */
    double half_write_sq, half_read_sq;   /**< sums of (transaction duration / 2)^2: the instants' uncertainty */
    uint64_t n_half;
    /* the device's clock from its counter: least squares of the unwrapped count on the read instant */
    double cs_n, cs_t, cs_c, cs_tt, cs_tc;   /**< sums (t in s from the first read, c in counts from the first) */
    int64_t c_t0;              /**< first read instant (ns) */
    double c_first, c_last, c_unwrapped;     /**< raw first and last counts, unwrapped total */
} msid_hx_timing;

/** The runner (caller-owned). */
typedef struct msid_hx {
    msid_hx_cfg cfg;
    msid_tick tick;
    msid_stream st;
    msid_gen gen;
    void *gen_mem;
    size_t gen_len;
    double *row;               /**< [nu + ny] */
    double *meas_v;            /**< [n_measure] */
    double cur[MSID_MAX_INPUTS];   /**< the last values written */
    int written;               /**< something was written */
    double peak[MSID_MAX_INPUTS];  /**< largest |x| of each input over every experiment */
    msid_hx_counters cnt;
    msid_hx_timing tim;
    int64_t last_ok_ns;
    int ready;                 /**< msid_hx_init succeeded */
    char err[320];
} msid_hx;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_hx_mem_size(const msid_hx_cfg *cfg);

/**
 * @brief Set up: the stream, the generator, the tick clock (real-time where
 *        permitted), and every value of every phase checked against the limits.
 * @return 0; -MSID_DAQ_E_ARG with err naming the channel, the value, the limit and the phase when a value
 *         would break a limit; or a core status (::msid_daq_core).
 */
int msid_hx_init(msid_hx *h, const msid_hx_cfg *cfg, void *mem, size_t len);

/**
 * @brief The largest |x| of each input over the design's experiments (the design's own units), so that a
 *        caller can set gain = amplitude / peak before ::msid_hx_init.
 * @param gen_mem  msid_gen_mem_size() bytes of a table-mode generator of the design (MSID_MEM_ALIGN aligned)
 * @param peak     [n_inputs]
 * @return 0 or a core status (::msid_daq_core)
 */
int msid_hx_peaks(const msid_design *d, const msid_twiddle *tw, void *gen_mem, size_t gen_len, double *peak);

/**
 * @brief Run experiment e: approach, fade-in, the measured periods into the core, fade-out. The tick clock
 *        starts with the experiment.
 * @return 0; -MSID_DAQ_E_STOPPED when on_tick asked to stop (the complete periods are kept; the drive holds
 *         the last value written: call ::msid_hx_safe); -MSID_DAQ_E_TIMEOUT when the device did not answer for
 *         silence_ms; another negative code on a failure (err). On every failure the caller writes the safe
 *         values.
 */
int msid_hx_run(msid_hx *h, uint32_t e);

/**
 * @brief The end of a run: ramp from the last values written to the safe values (max_step per tick, on the
 *        tick clock) and write them.
 * @return 0, or a negative code when the safe values could not be confirmed (err)
 */
int msid_hx_finish(msid_hx *h);

/**
 * @brief Write the safe values now (no ramp): up to `attempts` writes until one is confirmed (recovering the
 *        link between them). For every way out that is not the end.
 * @return 0, or a negative code when none was confirmed (err)
 */
int msid_hx_safe(msid_hx *h, uint32_t attempts);

/** @brief Release the tick clock's real-time scheduling and memory lock. */
void msid_hx_release(msid_hx *h);

/**
 * @brief The rate of the device's counter against the host's clock (counts per second, least squares of the
 *        unwrapped count on the read instants). NAN without a counter or with fewer than 16 reads.
 */
double msid_hx_counter_rate(const msid_hx *h);

#ifdef __cplusplus
}
#endif
#endif
