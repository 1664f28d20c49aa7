/**
 * @file msid_mb_transport.h
 * @brief Modbus transport backend table of the host acquisition (daq/).
 *
 * Like the CAN transports (msid_can_transport.h), a Modbus transport is a
 * table of function pointers and a caller-owned state: ::msid_modbus opens
 * the libmodbus TCP and RTU backends. A transport performs one request and
 * reports what went wrong (timeout, bad CRC, exception response, a reply
 * that does not match, a lost connection); retries, backoff and reconnects
 * are the adapter's (::msid_mb_call), so they behave the same on every link.
 * Callers use the wrapper functions below (::msid_mb_read_input, ...), never
 * the table itself.
 */
#ifndef MSID_MB_TRANSPORT_H
#define MSID_MB_TRANSPORT_H

#include <stdint.h>
#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/** The backend table. Requests return 0 or -msid_daq_status. */
typedef struct msid_mb_backend {
    const char *name;   /**< "tcp", "rtu" */
    /** Read n <= 125 input registers (FC 04). */
    int (*read_input)(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst);
    /** Read n <= 125 holding registers (FC 03). */
    int (*read_holding)(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst);
    /** Write n <= 123 holding registers (FC 16). */
    int (*write_holding)(void *ctx, uint32_t addr, uint32_t n, const uint16_t *src);
    /** Drop what the link holds (stale or partial replies). */
    void (*flush)(void *ctx);
    /** Close, flush and connect again (TCP: a new connection; RTU: the port reopened). */
    int (*reconnect)(void *ctx);
    /** Code of the last exception response (1..255). */
    uint32_t (*exception)(void *ctx);
    /** Detail of the last error ("" if none). */
    const char *(*error)(void *ctx);
    /** Release the transport. */
    void (*close)(void *ctx);
    /** Replies skipped so far as stale or foreign (cumulative): TCP, their transaction id or unit id was not the
        request's; RTU, an answer waiting on the line before a request. NULL: the backend cannot tell. */
    uint64_t (*skipped)(void *ctx);
    /** Write nw <= 121 holding registers at waddr, then read nr <= 125 holding registers at raddr, in one
        transaction (FC 23; the write is performed before the read). NULL: not supported by the backend. */
    int (*write_read)(void *ctx, uint32_t waddr, uint32_t nw, const uint16_t *src, uint32_t raddr, uint32_t nr,
                      uint16_t *dst);
    /** Change the response and byte timeouts (ms, >= 1). NULL: fixed at open. */
    void (*set_timeouts)(void *ctx, uint32_t response_ms, uint32_t byte_ms);
} msid_mb_backend;

/** A transport: a backend and its state. */
typedef struct msid_mb_transport {
    const msid_mb_backend *be;
    void *ctx;
} msid_mb_transport;

/** @brief Read n <= 125 input registers (FC 04) at addr into dst. @return 0 or -msid_daq_status. */
int msid_mb_read_input(const msid_mb_transport *t, uint32_t addr, uint32_t n, uint16_t *dst);

/** @brief Read n <= 125 holding registers (FC 03) at addr into dst. @return 0 or -msid_daq_status. */
int msid_mb_read_holding(const msid_mb_transport *t, uint32_t addr, uint32_t n, uint16_t *dst);

/** @brief Write n <= 123 holding registers (FC 16) at addr from src. @return 0 or -msid_daq_status. */
int msid_mb_write_holding(const msid_mb_transport *t, uint32_t addr, uint32_t n, const uint16_t *src);

/**
 * @brief Write nw <= 121 holding registers at waddr and read nr <= 125 holding registers at raddr in one
 *        transaction (FC 23: the write is performed first).
 * @return 0 or -msid_daq_status; -MSID_DAQ_E_NOSUPPORT when the backend has no FC 23
 */
int msid_mb_write_read(const msid_mb_transport *t, uint32_t waddr, uint32_t nw, const uint16_t *src, uint32_t raddr,
                       uint32_t nr, uint16_t *dst);

/** @brief Change the response and byte timeouts (ms, >= 1; a backend without the setter keeps its own). */
void msid_mb_set_timeouts(const msid_mb_transport *t, uint32_t response_ms, uint32_t byte_ms);

/** @brief Drop what the link holds (stale or partial replies). */
void msid_mb_flush(const msid_mb_transport *t);

/** @brief Close, flush and connect again. @return 0 or -msid_daq_status. */
int msid_mb_reconnect(const msid_mb_transport *t);

/** @brief Code of the last exception response (1..255). */
uint32_t msid_mb_exception(const msid_mb_transport *t);

/** @brief Detail of the transport's last error ("" if none). */
const char *msid_mb_error(const msid_mb_transport *t);

/** @brief Replies the transport skipped as stale or foreign, cumulative (0 if it cannot tell). */
uint64_t msid_mb_skipped(const msid_mb_transport *t);

/** @brief Name of the backend ("tcp", "rtu"). */
const char *msid_mb_backend_name(const msid_mb_transport *t);

/** @brief Release the transport (a transport that was never opened, be == NULL, is left alone). */
void msid_mb_close(msid_mb_transport *t);

/** @brief Name of a Modbus exception code ("illegal data address", ...). */
const char *msid_mb_exception_name(uint32_t code);

#ifdef __cplusplus
}
#endif
#endif
