/**
 * @file msid_tick.h
 * @brief The host's tick clock: absolute deadlines on CLOCK_MONOTONIC at a
 *        fixed rate, every tick's lateness recorded, missed ticks counted.
 *
 * Tick n is due at t0 + n / rate, computed from n (never accumulated), so the
 * rate does not drift however long the run. ::msid_tick_wait sleeps until the
 * next tick's deadline (clock_nanosleep, TIMER_ABSTIME). A caller that falls
 * behind by a whole period or more does not run the ticks it slept through:
 * they are missed, counted, and the caller declares their samples missing
 * (a gap the core marks, never an interpolated sample).
 *
 * Where permitted the calling thread runs under SCHED_FIFO and the process's
 * memory is locked (mlockall), which keeps page faults and other processes
 * from delaying a tick; where not, the tick clock still runs and
 * msid_tick::sched says what was refused. No allocation.
 */
#ifndef MSID_TICK_H
#define MSID_TICK_H

#include <stdint.h>
#include "msid_tstats.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Configuration. */
typedef struct msid_tick_cfg {
    double rate_hz;       /**< ticks per second, 0 < rate <= 100000 */
    int realtime;         /**< 1: try SCHED_FIFO and mlockall; 0: leave the scheduling as it is */
    int priority;         /**< SCHED_FIFO priority 1..99 (0: 40) */
    int64_t late_ns;      /**< a tick whose lateness exceeds this is late (0: half a period) */
} msid_tick_cfg;

/** The tick clock (caller-owned). */
typedef struct msid_tick {
    msid_tick_cfg cfg;
    double period_ns;         /**< 1e9 / rate */
    int64_t t0;               /**< deadline of tick 0 (CLOCK_MONOTONIC ns) */
    uint64_t next;            /**< index of the next tick */
    uint64_t ticks;           /**< ticks run */
    uint64_t missed;          /**< ticks slept through (not run) */
    uint64_t late;            /**< ticks run later than cfg.late_ns */
    msid_tstats lateness;     /**< of the ticks run, ns */
    msid_tstats wake;         /**< of the ticks the clock slept for (the caller was early): the clock's own
                                   precision, without the ticks a slow exchange made late */
    int64_t cpu_ns;           /**< CPU time of the calling thread between msid_tick_start and the last wait */
    int64_t cpu_user_ns;      /**< the part of it in user space (the rest is the kernel's: its network stack) */
    int64_t cpu_mark, user_mark;   /**< (at msid_tick_start and the last wait) */
    int fifo;                 /**< SCHED_FIFO obtained */
    int locked;               /**< memory locked */
    char sched[192];          /**< "SCHED_FIFO priority 40, memory locked", or what was refused and why */
    /* restored by msid_tick_release */
    int saved_policy, saved_prio, had_saved;
} msid_tick;

/** @brief The monotonic clock in ns. */
int64_t msid_now_ns(void);

/** @brief CLOCK_REALTIME in ns since the epoch: the clock of the kernel's receive timestamps (SO_TIMESTAMP). */
int64_t msid_realtime_ns(void);

/** @brief Set up (no clock started yet). @return 0, or -1 for a rate out of range. */
int msid_tick_init(msid_tick *t, const msid_tick_cfg *cfg);

/** @brief Start: tick 0 is due one period from now (or at t0_ns when t0_ns > 0); counts are kept. */
void msid_tick_start(msid_tick *t, int64_t t0_ns);

/** @brief Deadline of tick n (ns, CLOCK_MONOTONIC). */
int64_t msid_tick_deadline(const msid_tick *t, uint64_t n);

/**
 * @brief Sleep until the next tick is due and return its index. Ticks whose
 *        successor's deadline has passed already are skipped: *skipped gets
 *        their count (also added to t->missed); the returned tick is the
 *        latest one due. *lateness_ns: now - its deadline.
 */
uint64_t msid_tick_wait(msid_tick *t, uint64_t *skipped, int64_t *lateness_ns);

/**
 * @brief Follow another clock: from the next tick on, ticks are period_ns apart, and shifted by shift_ns; the
 *        next tick's deadline moves by shift_ns only (the rate changes without a jump).
 */
void msid_tick_retime(msid_tick *t, double period_ns, int64_t shift_ns);

/** @brief Give back what ::msid_tick_init obtained: the thread's scheduling policy, the memory lock. */
void msid_tick_release(msid_tick *t);

#ifdef __cplusplus
}
#endif
#endif
