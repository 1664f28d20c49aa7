/**
 * @file msid_co_sdo.h
 * @brief CANopen SDO client (CiA 301): expedited and segmented upload and download.
 *
 * One client talks to one node's default SDO server (requests on 0x600 + node,
 * responses on 0x580 + node). Transfers of 1..4 bytes are expedited; longer ones,
 * and a download of 0 bytes (which the expedited form cannot express), are
 * segmented, 7 bytes a segment, the toggle bit alternating from 0. Each response is
 * awaited for at most the client's timeout; frames of other COB-IDs that arrive
 * meanwhile go to the io's `other` hook. On a timeout, a toggle error, a command
 * that does not belong to the transfer or an upload larger than the caller's
 * buffer, the client sends the CiA 301 abort that names it and returns; an abort
 * from the node ends the transfer with its code kept in ::msid_co_sdo::abort_code
 * and named by ::msid_co_abort_name. Block transfer is not used.
 */
#ifndef MSID_CO_SDO_H
#define MSID_CO_SDO_H

#include <stddef.h>
#include <stdint.h>
#include "msid_co.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Default time a response is awaited, in ms (CiA 301 leaves it to the application). */
#define MSID_CO_SDO_TIMEOUT_MS 500

/** Abort codes msid itself sends (CiA 301 table 22; the node's own are named by ::msid_co_abort_name). */
#define MSID_CO_ABORT_TOGGLE 0x05030000u     /**< toggle bit not alternated */
#define MSID_CO_ABORT_TIMEOUT 0x05040000u    /**< SDO protocol timed out */
#define MSID_CO_ABORT_COMMAND 0x05040001u    /**< command specifier not valid or unknown */
#define MSID_CO_ABORT_MEMORY 0x05040005u     /**< out of memory */
#define MSID_CO_ABORT_GENERAL 0x08000000u    /**< general error */

/** A client of one node's SDO server (caller-owned). */
typedef struct msid_co_sdo {
    msid_co_io io;
    uint8_t node;           /**< 1..127 */
    int timeout_ms;         /**< per response, > 0 */
    uint32_t abort_code;    /**< abort of the last transfer, the node's or msid's (0: none) */
    uint8_t abort_by_node;  /**< 1: abort_code came from the node; 0: msid sent it (or none) */
    char err[240];          /**< what went wrong last ("" after a transfer that succeeded) */
} msid_co_sdo;

/**
 * @brief Set up a client of node's SDO server.
 * @param io the bus (copied); send and recv must be set
 * @param node 1..127
 * @param timeout_ms per response, 1..60000 (0: ::MSID_CO_SDO_TIMEOUT_MS)
 * @return 0, or -MSID_DAQ_E_ARG (s->err names the argument, when s is not NULL)
 */
int msid_co_sdo_init(msid_co_sdo *s, const msid_co_io *io, unsigned node, int timeout_ms);

/**
 * @brief Read entry index:sub into buf.
 * @param cap bytes buf holds; an entry longer than that is aborted (out of memory) and refused
 * @param len receives the entry's size in bytes
 * @return 0; -MSID_DAQ_E_DEVICE (the node aborted: s->abort_code); -MSID_DAQ_E_TIMEOUT; -MSID_DAQ_E_PROTOCOL
 *         (a response outside the protocol: toggle, command, index, size); -MSID_DAQ_E_RANGE (longer than cap);
 *         -MSID_DAQ_E_ARG; or the io's own error. s->err says which, with the entry and the node.
 */
int msid_co_sdo_upload(msid_co_sdo *s, uint16_t index, uint8_t sub, void *buf, size_t cap, size_t *len);

/**
 * @brief Write len bytes (0..2^32-1) of data to entry index:sub.
 * @return 0 or a negative code as ::msid_co_sdo_upload (no -MSID_DAQ_E_RANGE)
 */
int msid_co_sdo_download(msid_co_sdo *s, uint16_t index, uint8_t sub, const void *data, size_t len);

/**
 * @brief Read an unsigned entry of exactly size bytes (1, 2 or 4), little endian as CANopen sends it.
 * @return 0, -MSID_DAQ_E_PROTOCOL when the node sent another size (s->err names both), or as ::msid_co_sdo_upload
 */
int msid_co_sdo_read_uint(msid_co_sdo *s, uint16_t index, uint8_t sub, unsigned size, uint32_t *value);

/** @brief Write the low size bytes (1, 2 or 4) of value, little endian. Returns as ::msid_co_sdo_download. */
int msid_co_sdo_write_uint(msid_co_sdo *s, uint16_t index, uint8_t sub, unsigned size, uint32_t value);

/**
 * @brief The CiA 301 name of an SDO abort code ("unknown abort code" for one the standard does not define).
 * @return a static string, never NULL
 */
const char *msid_co_abort_name(uint32_t code);

#ifdef __cplusplus
}
#endif
#endif
