/**
 * @file msid_modbus.h
 * @brief Modbus TCP and RTU transports on libmodbus (client side).
 *
 * libmodbus connects both and frames RTU. Over TCP the requests and replies
 * are framed by ::msid_mbap_request: a reply whose transaction id or unit id
 * is not the request's (a stale duplicate, a foreign reply) is skipped and
 * counted (msid_mb_backend.skipped), a malformed frame (length, protocol id)
 * is -MSID_DAQ_E_PROTOCOL. An RTU frame has no transaction id: before each
 * request whatever waits on the line (an answer that came after its request
 * timed out) is dropped and counted as a skipped reply; an answer later than
 * the next request's own can still be taken for it, once.
 *
 * Explicit response and byte timeouts (libmodbus's own error recovery is
 * off: the adapter retries and reconnects), errno mapped to msid_daq_status:
 * ETIMEDOUT -> timeout, EMBBADCRC -> bad CRC, an exception response ->
 * exception (its code kept), EMBBADDATA/EMBMDATA/EMBBADEXC/EMBBADSLAVE ->
 * bad reply, anything else (reset, broken pipe) -> I/O.
 */
#ifndef MSID_MODBUS_H
#define MSID_MODBUS_H

#include "msid_mb_transport.h"
#include "msid_mbap.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Options. */
typedef struct msid_modbus_cfg {
    int rtu;                      /**< 0: TCP, 1: RTU */
    const char *host;             /**< TCP: address, e.g. "127.0.0.1" */
    int port;                     /**< TCP: port (502) */
    const char *device;           /**< RTU: serial device, e.g. "/dev/ttyUSB0" or a pty */
    int baud;                     /**< RTU: 115200 */
    char parity;                  /**< RTU: 'N', 'E' or 'O' */
    int data_bits, stop_bits;     /**< RTU: 8, 1 */
    int unit;                     /**< unit (slave) id, 1..247 (TCP: 255 accepted) */
    uint32_t response_timeout_ms; /**< wait for the first byte of a reply */
    uint32_t byte_timeout_ms;     /**< wait between bytes of a reply */
} msid_modbus_cfg;

/** State (caller-owned). */
typedef struct msid_modbus {
    msid_mb_transport tr;         /**< the transport to use after open */
    void *mb;                     /**< modbus_t */
    msid_modbus_cfg cfg;
    char host[128], device[256];
    msid_mbap mbap;               /**< TCP: our own request framing and reply matching (msid_mbap.h) */
    uint64_t rtu_stale;           /**< RTU: stale answers dropped from the line before a request */
    int rtu_owed;                 /**< RTU: the last request failed; its answer may still come */
    uint32_t exc;                 /**< last exception code */
    char err[400];
} msid_modbus;

/** A first TCP connection the device refuses is tried again for this long (ms), every 50 ms: a
 *  device (or msid-devsim started in the same shell line) that is still starting up. */
#define MSID_MODBUS_CONNECT_WAIT_MS 2000

/**
 * @brief Create the libmodbus context and connect (TCP: a refused connection is retried for
 *        ::MSID_MODBUS_CONNECT_WAIT_MS).
 * @return 0, -MSID_DAQ_E_ARG or -MSID_DAQ_E_CONNECT; m->err holds the detail.
 */
int msid_modbus_open(msid_modbus *m, const msid_modbus_cfg *cfg);

#ifdef __cplusplus
}
#endif
#endif
