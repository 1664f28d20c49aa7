/* The host's tick clock (msid_tick.h): absolute deadlines, lateness, missed ticks, SCHED_FIFO where permitted. */
#define _GNU_SOURCE
#include "msid_daq/msid_tick.h"

#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <time.h>

/* The calling thread's CPU time, and its user-space part, in ns. */
static int64_t thread_cpu_ns(int64_t *user)
{
    struct rusage ru;
    getrusage(RUSAGE_THREAD, &ru);
    *user = (int64_t)ru.ru_utime.tv_sec * 1000000000 + (int64_t)ru.ru_utime.tv_usec * 1000;
    return *user + (int64_t)ru.ru_stime.tv_sec * 1000000000 + (int64_t)ru.ru_stime.tv_usec * 1000;
}

int64_t msid_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

int64_t msid_realtime_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* SCHED_FIFO for this thread and the memory locked, each where permitted; what was obtained into t->sched. */
static void go_realtime(msid_tick *t)
{
    struct sched_param sp;
    int pol = 0;
    if (pthread_getschedparam(pthread_self(), &pol, &sp) == 0) {
        t->saved_policy = pol;
        t->saved_prio = sp.sched_priority;
        t->had_saved = 1;
    }
    memset(&sp, 0, sizeof sp);
    sp.sched_priority = t->cfg.priority ? t->cfg.priority : 40;
    const int e1 = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    t->fifo = e1 == 0;
    const int e2 = mlockall(MCL_CURRENT) == 0 ? 0 : errno;
    t->locked = e2 == 0;
    char a[72], b[72];
    if (t->fifo) snprintf(a, sizeof a, "SCHED_FIFO priority %d", sp.sched_priority);
    else snprintf(a, sizeof a, "SCHED_OTHER (SCHED_FIFO refused: %s)", strerror(e1));
    if (t->locked) snprintf(b, sizeof b, "memory locked");
    else snprintf(b, sizeof b, "memory not locked (mlockall: %s)", strerror(e2));
    snprintf(t->sched, sizeof t->sched, "%s, %s", a, b);
}

int msid_tick_init(msid_tick *t, const msid_tick_cfg *cfg)
{
    memset(t, 0, sizeof *t);
    if (!cfg || !(cfg->rate_hz > 0 && cfg->rate_hz <= 100000)) return -1;
    if (cfg->priority < 0 || cfg->priority > 99) return -1;
    t->cfg = *cfg;
    t->period_ns = 1e9 / cfg->rate_hz;
    if (t->cfg.late_ns <= 0) t->cfg.late_ns = (int64_t)(t->period_ns / 2);
    msid_tstats_reset(&t->lateness);
    msid_tstats_reset(&t->wake);
    if (cfg->realtime) go_realtime(t);
    else snprintf(t->sched, sizeof t->sched, "the scheduling as it was (real-time scheduling not asked for)");
    return 0;
}

void msid_tick_start(msid_tick *t, int64_t t0_ns)
{
    t->t0 = t0_ns > 0 ? t0_ns : msid_now_ns() + (int64_t)t->period_ns;
    t->next = 0;
    t->cpu_mark = thread_cpu_ns(&t->user_mark);
}

int64_t msid_tick_deadline(const msid_tick *t, uint64_t n)
{
    return t->t0 + (int64_t)llround((double)n * t->period_ns);
}

uint64_t msid_tick_wait(msid_tick *t, uint64_t *skipped, int64_t *lateness_ns)
{
    const int64_t due = msid_tick_deadline(t, t->next);
    const int slept = msid_now_ns() < due;
    struct timespec ts = {(time_t)(due / 1000000000), (long)(due % 1000000000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
    }
    const int64_t now = msid_now_ns();
    uint64_t n = t->next, skip = 0;
    /* the latest tick due: skip those whose successor is due already */
    if (msid_tick_deadline(t, n + 1) <= now) {
        uint64_t k = (uint64_t)((double)(now - t->t0) / t->period_ns);   /* about the latest due; exact below */
        if (k < n) k = n;
        while (k > n && msid_tick_deadline(t, k) > now) --k;
        while (msid_tick_deadline(t, k + 1) <= now) ++k;
        skip = k - n;
        n = k;
    }
    const int64_t late = now - msid_tick_deadline(t, n);
    t->missed += skip;
    ++t->ticks;
    if (late > t->cfg.late_ns) ++t->late;
    msid_tstats_add(&t->lateness, late);
    if (slept && skip == 0) msid_tstats_add(&t->wake, late);
    int64_t user = 0;
    const int64_t cpu = thread_cpu_ns(&user);
    t->cpu_ns += cpu - t->cpu_mark;
    t->cpu_user_ns += user - t->user_mark;
    t->cpu_mark = cpu;
    t->user_mark = user;
    t->next = n + 1;
    if (skipped) *skipped = skip;
    if (lateness_ns) *lateness_ns = late;
    return n;
}

void msid_tick_retime(msid_tick *t, double period_ns, int64_t shift_ns)
{
    const int64_t due = msid_tick_deadline(t, t->next) + shift_ns;
    t->period_ns = period_ns;
    t->t0 = due - (int64_t)llround((double)t->next * period_ns);
}

void msid_tick_release(msid_tick *t)
{
    if (t->fifo && t->had_saved) {
        struct sched_param sp;
        memset(&sp, 0, sizeof sp);
        sp.sched_priority = t->saved_prio;
        pthread_setschedparam(pthread_self(), t->saved_policy, &sp);
    }
    if (t->locked) munlockall();
    t->fifo = t->locked = 0;
}
