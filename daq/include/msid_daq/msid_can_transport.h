/**
 * @file msid_can_transport.h
 * @brief Transport backend table of the host acquisition (daq/).
 *
 * A transport moves CAN frames; it knows nothing of msid-can/1. Backends plug
 * in as a table of function pointers, the way libmodbus plugs its RTU and TCP
 * backends in: ::msid_socketcan (live SocketCAN) and ::msid_candump_reader
 * (replay of a candump .log file). Callers use the wrapper functions below
 * (::msid_can_recv, ::msid_can_send, ...), never the table itself. The caller
 * owns every backend struct; no backend allocates after open.
 */
#ifndef MSID_CAN_TRANSPORT_H
#define MSID_CAN_TRANSPORT_H

#include <stddef.h>
#include <stdint.h>
#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Identifier flags, as in Linux's can_id. */
#define MSID_CAN_EFF_FLAG 0x80000000u  /**< 29-bit identifier */
#define MSID_CAN_RTR_FLAG 0x40000000u  /**< remote request */
#define MSID_CAN_ERR_FLAG 0x20000000u  /**< error frame (data: CAN_ERR_* classes) */

/** Frame flags. */
#define MSID_CANF_FD 0x01u   /**< CAN FD frame */
#define MSID_CANF_BRS 0x02u  /**< FD bit-rate switch */
#define MSID_CANF_ESI 0x04u  /**< FD error state indicator */
#define MSID_CANF_TX 0x80u   /**< sent by this host (logs) */

/** One CAN or CAN FD frame. */
typedef struct msid_can_frame {
    uint32_t id;        /**< identifier with MSID_CAN_*_FLAG bits */
    uint8_t len;        /**< payload bytes: 0..8 classic, 0..64 FD */
    uint8_t flags;      /**< MSID_CANF_* */
    uint8_t data[64];
    uint64_t t_ns;      /**< receive time, ns since the epoch (0: unknown) */
} msid_can_frame;


/** Link-level counters a transport keeps (all cumulative). */
typedef struct msid_can_link_stats {
    uint64_t frames;        /**< frames delivered to the caller */
    uint64_t kernel_drops;  /**< frames the kernel dropped for a full socket queue (SO_RXQ_OVFL) */
    uint64_t bad_length;    /**< reads whose length was neither CAN_MTU nor CANFD_MTU, rejected */
    uint64_t send_retries;  /**< send attempts refused with ENOBUFS/EAGAIN and retried after poll() */
    uint64_t timestamps;    /**< frames that carried a kernel timestamp */
} msid_can_link_stats;

/** The backend table. */
typedef struct msid_can_backend {
    const char *name;
    /** Receive up to n frames; wait at most timeout_ms (-1: forever). Returns the count (>= 1) or -msid_daq_status. */
    int (*recv)(void *ctx, msid_can_frame *f, int n, int timeout_ms);
    /** Send one frame; retries on a full queue for at most timeout_ms. Returns 0 or -msid_daq_status. */
    int (*send)(void *ctx, const msid_can_frame *f, int timeout_ms);
    /** Copy the link counters. */
    void (*stats)(void *ctx, msid_can_link_stats *s);
    /** Detail of the last error ("" if none). */
    const char *(*error)(void *ctx);
    /** Release the transport. */
    void (*close)(void *ctx);
} msid_can_backend;

/** A transport: a backend and its state. */
typedef struct msid_can_transport {
    const msid_can_backend *be;
    void *ctx;
} msid_can_transport;

/**
 * @brief Receive up to n frames into f[0..n-1], waiting at most timeout_ms (-1: forever, 0: poll).
 * @return the count (>= 1), -MSID_DAQ_E_TIMEOUT, -MSID_DAQ_E_EOF (end of a log) or another -msid_daq_status
 *         (::msid_can_error has the detail).
 */
int msid_can_recv(const msid_can_transport *t, msid_can_frame *f, int n, int timeout_ms);

/**
 * @brief Send one frame; a full queue is retried for at most timeout_ms.
 * @return 0 or -msid_daq_status (::msid_can_error has the detail).
 */
int msid_can_send(const msid_can_transport *t, const msid_can_frame *f, int timeout_ms);

/** @brief Copy the transport's cumulative link counters into *s. */
void msid_can_get_stats(const msid_can_transport *t, msid_can_link_stats *s);

/** @brief Detail of the transport's last error ("" if none); valid until the next call on t. */
const char *msid_can_error(const msid_can_transport *t);

/** @brief Release the transport (a transport that was never opened, be == NULL, is left alone). */
void msid_can_close(msid_can_transport *t);

#ifdef __cplusplus
}
#endif
#endif
