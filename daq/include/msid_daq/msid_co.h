/**
 * @file msid_co.h
 * @brief CANopen (CiA 301) basics shared by msid's CANopen master: node ids, the
 *        predefined connection set's COB-IDs and the frame I/O table.
 *
 * msid is the master of the nodes it measures: it drives them by NMT, reads and
 * writes their object dictionaries by SDO (::msid_co_sdo), configures their PDOs
 * (msid_co_pdo.h), watches heartbeats and decodes EMCY (msid_co_nmt.h,
 * msid_co_emcy.h). Every one of these objects reaches the bus through a
 * ::msid_co_io table, so unit tests drive them with frames in memory and a run
 * drives them over SocketCAN. None allocates; the caller owns every struct.
 */
#ifndef MSID_CO_H
#define MSID_CO_H

#include <stdint.h>
#include "msid_can_transport.h"
#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Node ids of the predefined connection set: 1..127 (0 addresses every node in NMT only). */
#define MSID_CO_NODE_MIN 1u
#define MSID_CO_NODE_MAX 127u

/** Function codes of the predefined connection set (COB-ID = code + node id). */
#define MSID_CO_COB_NMT 0x000u        /**< NMT command (master to nodes, no node id) */
#define MSID_CO_COB_SYNC 0x080u       /**< SYNC (no node id) */
#define MSID_CO_COB_EMCY 0x080u       /**< EMCY: 0x080 + node id */
#define MSID_CO_COB_TPDO1 0x180u      /**< TPDO1..4: 0x180, 0x280, 0x380, 0x480 + node id */
#define MSID_CO_COB_RPDO1 0x200u      /**< RPDO1..4: 0x200, 0x300, 0x400, 0x500 + node id */
#define MSID_CO_COB_SDO_TX 0x580u     /**< SDO server to client: 0x580 + node id */
#define MSID_CO_COB_SDO_RX 0x600u     /**< SDO client to server: 0x600 + node id */
#define MSID_CO_COB_HEARTBEAT 0x700u  /**< heartbeat / boot-up: 0x700 + node id */

/**
 * How the CANopen objects reach the bus. send and recv are required; now_ms and
 * other may be NULL.
 */
typedef struct msid_co_io {
    void *ctx;
    /** Send one classic frame. Returns 0 or -msid_daq_status. */
    int (*send)(void *ctx, const msid_can_frame *f);
    /** Wait at most timeout_ms (>= 0) for one frame. Returns 1, -MSID_DAQ_E_TIMEOUT or another -msid_daq_status. */
    int (*recv)(void *ctx, msid_can_frame *f, int timeout_ms);
    /** Monotonic time in ms (NULL: CLOCK_MONOTONIC). A test gives its own clock. */
    uint64_t (*now_ms)(void *ctx);
    /** A frame received while waiting that is not the one awaited (PDO, heartbeat, EMCY); NULL: dropped. */
    void (*other)(void *ctx, const msid_can_frame *f);
} msid_co_io;

/** @brief 1 when node is a node id of the predefined connection set (1..127), else 0. */
int msid_co_node_valid(unsigned node);

/** @brief The io's clock in ms (its now_ms, or CLOCK_MONOTONIC when it has none). */
uint64_t msid_co_now_ms(const msid_co_io *io);

#ifdef __cplusplus
}
#endif
#endif
