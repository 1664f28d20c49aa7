/**
 * @file msid_co_can.h
 * @brief A ::msid_co_io over a CAN transport (SocketCAN in a run): frames are read in batches and handed
 *        to the CANopen objects one at a time.
 */
#ifndef MSID_CO_CAN_H
#define MSID_CO_CAN_H

#include "msid_co.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Frames read from the transport in one call. */
#define MSID_CO_CAN_BATCH 16

/** The adapter's state (caller-owned; lives as long as the io made from it). */
typedef struct msid_co_can {
    const msid_can_transport *t;
    int send_timeout_ms;   /**< how long a full send queue is retried */
    int n, at;             /**< frames in buf, the next one to hand on */
    msid_can_frame buf[MSID_CO_CAN_BATCH];
    char err[200];         /**< the transport's detail of the last failure */
} msid_co_can;

/**
 * @brief Make io send and receive on t. other (frames not awaited) is left NULL: the caller may set it.
 * @param send_timeout_ms 1..60000: how long a full queue is retried before a send fails
 * @return 0 or -MSID_DAQ_E_ARG
 */
int msid_co_can_io(msid_co_can *c, const msid_can_transport *t, int send_timeout_ms, msid_co_io *io);

#ifdef __cplusplus
}
#endif
#endif
