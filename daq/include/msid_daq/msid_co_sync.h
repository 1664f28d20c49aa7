/**
 * @file msid_co_sync.h
 * @brief The SYNC producer: SYNC frames sent by the kernel's broadcast manager (CAN_BCM), on the kernel's
 *        timer, at a fixed period.
 *
 * The kernel sends each SYNC from its own hrtimer, so the host's scheduling does not move it; with a
 * counter (the node's 0x1019 overflow value N, 2..240) the frames carry 1..N in turn, as CiA 301 counts.
 * The kernel deletes a socket's cyclic messages when the socket is closed, so SYNC stops on every way
 * out, a crash of msid included. Linux only (MSID_WITH_CAN); elsewhere start fails with one message.
 */
#ifndef MSID_CO_SYNC_H
#define MSID_CO_SYNC_H

#include <stdint.h>
#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Highest counter overflow value of CiA 301 (0x1019). */
#define MSID_CO_SYNC_COUNTER_MAX 240u

/** A running SYNC producer (caller-owned). */
typedef struct msid_co_sync {
    int fd;               /**< the BCM socket (-1: stopped) */
    uint32_t period_us;
    unsigned counter;     /**< overflow value (0: SYNC without data) */
    char err[200];
} msid_co_sync;

/**
 * @brief Start SYNC on iface every period_us (100..1000000) us, with counter 0 (none) or 2..240.
 * @return 0; -MSID_DAQ_E_ARG; -MSID_DAQ_E_NOSUPPORT (no CAN_BCM in this kernel: modprobe can-bcm), -MSID_DAQ_E_NODEV,
 *         -MSID_DAQ_E_PERM or -MSID_DAQ_E_IO (s->err says which)
 */
int msid_co_sync_start(msid_co_sync *s, const char *iface, uint32_t period_us, unsigned counter);

/** @brief Stop SYNC (the cyclic message deleted, the socket closed); a stopped producer is left alone. */
void msid_co_sync_stop(msid_co_sync *s);

#ifdef __cplusplus
}
#endif
#endif
