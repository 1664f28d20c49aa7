/**
 * @file msid_mbap.h
 * @brief Modbus TCP client framing of our own: one request, the matching MBAP reply.
 *
 * libmodbus 3.1.6 reads exactly one frame after a request and rejects it when
 * its transaction id differs, so a stale reply (a device that answers twice,
 * a reply that arrived after its request timed out) makes the *next* request
 * fail too, and recovery depends on timing. This reader sends the request
 * with its own transaction id on the connected socket, then reads whole MBAP
 * frames (Modbus Messaging on TCP/IP Implementation Guide v1.0b, section
 * 3.1.3: transaction id, protocol id 0, length = unit id + PDU bytes, unit id)
 * and skips, counting them, every frame whose transaction id or unit id is
 * not the request's, until the matching frame arrives or the response
 * timeout passes. A length outside 2..254 or a protocol id other than 0 is a
 * malformed frame: one error, -MSID_DAQ_E_PROTOCOL (the byte stream has lost
 * its framing; the caller reconnects). No allocation.
 */
#ifndef MSID_MBAP_H
#define MSID_MBAP_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Largest PDU (function code + data), bytes: a Modbus ADU of 260 less the 7-byte MBAP header + 1. */
#define MSID_MBAP_MAX_PDU 253u

/** State of one client connection's framing (caller-owned). */
typedef struct msid_mbap {
    int fd;                       /**< connected TCP socket (blocking or not) */
    uint8_t unit;                 /**< unit id sent and expected, 0..255 */
    uint16_t tid;                 /**< transaction id of the last request sent */
    uint32_t response_timeout_ms; /**< from the request sent to the first byte of the matching reply, ms (> 0) */
    uint32_t byte_timeout_ms;     /**< between two bytes of one frame, ms (> 0) */
    uint64_t skipped;             /**< frames skipped: transaction id or unit id not the request's (cumulative) */
    uint64_t malformed;           /**< malformed frames: bad length or protocol id (cumulative) */
    char err[160];                /**< what went wrong last */
} msid_mbap;

/**
 * @brief Send one request PDU and return the PDU of the matching reply.
 * @param c     state; c->fd connected
 * @param req   request PDU (function code + data), 1..MSID_MBAP_MAX_PDU bytes
 * @param rsp   out: reply PDU, room for MSID_MBAP_MAX_PDU bytes
 * @param rsp_n out: its length in bytes, 1..MSID_MBAP_MAX_PDU
 * @return 0; -MSID_DAQ_E_TIMEOUT (no matching reply within the response timeout, or a frame stopped for
 *         longer than the byte timeout), -MSID_DAQ_E_PROTOCOL (malformed frame), -MSID_DAQ_E_IO (the
 *         connection failed or closed), -MSID_DAQ_E_ARG. c->err says which.
 */
int msid_mbap_request(msid_mbap *c, const uint8_t *req, size_t req_n, uint8_t *rsp, size_t *rsp_n);

/**
 * @brief Check one 7-byte MBAP header.
 * @return the PDU length that follows (1..MSID_MBAP_MAX_PDU), or 0 if the header is malformed
 *         (protocol id not 0, or length field outside 2..254).
 */
size_t msid_mbap_header_pdu_len(const uint8_t h[7]);

#ifdef __cplusplus
}
#endif
#endif
