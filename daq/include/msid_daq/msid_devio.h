/**
 * @file msid_devio.h
 * @brief A described device (msid-device/1) as the host's tick loop sees it:
 *        a backend table, like the transports (msid_mb_transport.h), with one
 *        backend per transport: the Modbus register map (msid_mb_map.h) and
 *        DBC signals on CAN.
 *
 * Values cross this table in physical units, in the order of the
 * description's drive and measure channels; encoding, requests and frames are
 * the backend's. Every call is bounded in time (the backend's timeouts) and
 * says when its transactions ran (CLOCK_MONOTONIC ns), so that the tick loop
 * can record round trips and the instants at which the device was written and
 * read. Callers use the wrappers, never the table itself.
 */
#ifndef MSID_DEVIO_H
#define MSID_DEVIO_H

#include <stdint.h>
#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/** When one exchange's transactions ran (ns, CLOCK_MONOTONIC; 0: that part did not run). */
typedef struct msid_devio_times {
    int64_t w0, w1;    /**< the write: request sent .. answer received (CAN: the frame queued .. sent) */
    int64_t r0, r1;    /**< the read: request sent .. answer received (CAN: the status frame's arrival in both) */
    uint32_t transactions;   /**< requests (Modbus) or frames sent (CAN) */
    /** The device's counter channel as read just before the write, when the write and the counter's read are
        not one transaction (a device cycle may then fall between them, and which cycle took the write is
        known only if the counter did not move): its raw value; `has_counter_before` 0 when not read. */
    double counter_before;
    int has_counter_before;
    /** A device whose cycle the backend sees begin (a CANopen SYNC on the kernel's timer): the time from the
        start of the device's current cycle to the write (ns, 0..period), so that the tick loop can keep its
        ticks in the middle of the cycle; `has_phase` 0 when not known. */
    int64_t phase_ns;
    int has_phase;
} msid_devio_times;

/** The backend table. Calls return 0 or -msid_daq_status (error() has the detail). */
typedef struct msid_devio_backend {
    const char *name;
    /** One tick: write the drive values [n_drive], then read the measure values [n_measure]. A failure means
        nothing usable was read (the device may or may not have applied the write). */
    int (*exchange)(void *ctx, const double *drive, double *measure, msid_devio_times *t);
    /** Write the drive values only (ramps and the safe values). */
    int (*write)(void *ctx, const double *drive, msid_devio_times *t);
    /** Read the measure values only (msid device check). */
    int (*read)(void *ctx, double *measure, msid_devio_times *t);
    /** After a failure: drop what the link holds, reconnect when it was lost. */
    int (*recover)(void *ctx);
    /** Detail of the last error ("" if none). */
    const char *(*error)(void *ctx);
    /** How one exchange is carried, for the file ("FC23", "FC16 + FC04", "frame 0x101 + status 0x181"). */
    const char *(*describe)(void *ctx);
} msid_devio_backend;

/** A device: a backend and its state. */
typedef struct msid_devio {
    const msid_devio_backend *be;
    void *ctx;
} msid_devio;

/** @brief One tick's exchange (see msid_devio_backend::exchange). */
int msid_devio_exchange(const msid_devio *d, const double *drive, double *measure, msid_devio_times *t);
/** @brief Write the drive values only. */
int msid_devio_write(const msid_devio *d, const double *drive, msid_devio_times *t);
/** @brief Read the measure values only. */
int msid_devio_read(const msid_devio *d, double *measure, msid_devio_times *t);
/** @brief Recover after a failure (flush, reconnect). */
int msid_devio_recover(const msid_devio *d);
/** @brief Detail of the last error. */
const char *msid_devio_error(const msid_devio *d);
/** @brief How one exchange is carried. */
const char *msid_devio_describe(const msid_devio *d);

#ifdef __cplusplus
}
#endif
#endif
