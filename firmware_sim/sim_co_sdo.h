/**
 * @file sim_co_sdo.h
 * @brief The simulated node's SDO server (CiA 301): expedited and segmented upload and download on the
 *        default SDO (0x600 + node in, 0x580 + node out), access and length checked against the object
 *        dictionary, the node's own rules asked before a value is stored, and CiA 301's aborts: toggle bit
 *        not alternated, command unknown (block transfer is not served), protocol timed out (a segmented
 *        transfer left idle), plus those of the dictionary and of the node.
 */
#ifndef MSID_SIM_CO_SDO_H
#define MSID_SIM_CO_SDO_H

#include <stdint.h>

#include "msid_daq/msid_can_transport.h"
#include "sim_co_od.h"

/** A segmented transfer left idle this long (ms, of the node's clock) is aborted with "timed out". */
#define SIM_CO_SDO_TIMEOUT_MS 1000u

/**
 * The node's rule on a write, asked once the dictionary's checks passed: 0 to store the value (the node
 * may act on it: it is stored first), or an abort code.
 */
typedef uint32_t (*sim_co_sdo_write_fn)(void *ctx, sim_co_var *v, const uint8_t *data, size_t len);
/** A read about to be answered: 0, or an abort code (a fault on an entry). */
typedef uint32_t (*sim_co_sdo_read_fn)(void *ctx, const sim_co_var *v);

/** The server (caller-owned). */
typedef struct sim_co_sdo_srv {
    sim_co_od *od;
    uint8_t node;                 /**< 1..127 */
    sim_co_sdo_write_fn on_write; /**< required */
    sim_co_sdo_read_fn on_read;   /**< NULL: every readable entry is answered */
    void *ctx;
    int state;                    /**< 0 idle, 1 segmented download, 2 segmented upload */
    uint16_t index;
    uint8_t sub;
    uint8_t toggle;               /**< the toggle bit the next segment must carry */
    uint8_t buf[SIM_CO_OD_DOMAIN_MAX];
    uint32_t len;                 /**< bytes held (download) or to send (upload) */
    uint32_t pos;                 /**< bytes sent (upload) */
    uint32_t size;                /**< download: the size the client indicated (UINT32_MAX: none) */
    uint64_t last_ms;             /**< node time of the last frame of the transfer */
    uint64_t aborts_sent;
} sim_co_sdo_srv;

/** @brief Set up a server of node (1..127) over od. */
void sim_co_sdo_init(sim_co_sdo_srv *s, sim_co_od *od, unsigned node, sim_co_sdo_write_fn on_write,
                     sim_co_sdo_read_fn on_read, void *ctx);

/**
 * @brief Take a request (the frame's identifier is the caller's to check) at node time now_ms.
 * @return 1 with *resp the answer to send, 0 for nothing to send (an abort from the client)
 */
int sim_co_sdo_rx(sim_co_sdo_srv *s, const msid_can_frame *req, msid_can_frame *resp, uint64_t now_ms);

/** @brief A transfer idle for SIM_CO_SDO_TIMEOUT_MS: 1 with *resp the abort to send (the transfer ends). */
int sim_co_sdo_poll(sim_co_sdo_srv *s, msid_can_frame *resp, uint64_t now_ms);

#endif
