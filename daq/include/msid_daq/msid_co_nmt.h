/**
 * @file msid_co_nmt.h
 * @brief CANopen network management (CiA 301): NMT commands, SYNC frames and the heartbeat consumer.
 *
 * msid is the NMT master of the nodes it measures: it sends them to
 * pre-operational to configure them, to operational to run, and stops or resets
 * their communication at the end. Each node is watched through its heartbeat
 * (0x700 + node id, one byte: its NMT state): a ::msid_co_hb follows one node as
 * an entry of the consumer heartbeat time 0x1016 would, monitoring from the first
 * heartbeat it receives and reporting the node lost when the next one is later
 * than the consumer time. The producer time the node is asked for (0x1017) must
 * be shorter than the consumer time, with the bus's latency to spare.
 */
#ifndef MSID_CO_NMT_H
#define MSID_CO_NMT_H

#include <stdint.h>
#include "msid_co.h"

#ifdef __cplusplus
extern "C" {
#endif

/** NMT command specifiers (CiA 301 7.2.8.3.1). */
typedef enum msid_co_nmt_cmd {
    MSID_CO_NMT_START = 0x01,             /**< to operational */
    MSID_CO_NMT_STOP = 0x02,              /**< to stopped */
    MSID_CO_NMT_PREOPERATIONAL = 0x80,    /**< to pre-operational */
    MSID_CO_NMT_RESET_NODE = 0x81,        /**< reset the application (and communication) */
    MSID_CO_NMT_RESET_COMMUNICATION = 0x82 /**< reset the communication parameters */
} msid_co_nmt_cmd;

/** NMT states as a heartbeat reports them (bit 7 of the byte is reserved and ignored). */
#define MSID_CO_STATE_BOOTUP 0x00u
#define MSID_CO_STATE_STOPPED 0x04u
#define MSID_CO_STATE_OPERATIONAL 0x05u
#define MSID_CO_STATE_PREOPERATIONAL 0x7Fu
#define MSID_CO_STATE_UNKNOWN 0xFFu  /**< no heartbeat received yet */

/**
 * @brief Send an NMT command to one node (1..127) or to every node (0).
 * @return 0, -MSID_DAQ_E_ARG for a node id beyond 127 or a command CiA 301 does not define, or the io's error
 */
int msid_co_nmt_send(const msid_co_io *io, msid_co_nmt_cmd cmd, unsigned node);

/** @brief The name of an NMT command ("start", "stop", "enter pre-operational", ...; "unknown command"). */
const char *msid_co_nmt_cmd_name(unsigned cmd);

/** @brief The name of an NMT state byte ("boot-up", "stopped", "operational", "pre-operational", "no heartbeat yet", "unknown state"). */
const char *msid_co_state_name(unsigned state);

/**
 * @brief A SYNC frame (COB-ID 0x80): no data, or one byte of counter when counter is 1..240
 *        (the node's 0x1019 synchronous counter overflow value is then > 1). counter 0: no counter.
 * @return 0, -MSID_DAQ_E_ARG for a counter beyond 240
 */
int msid_co_sync_frame(msid_can_frame *f, unsigned counter);

/** @brief A 0x1016 consumer entry: node id in bits 16..23, consumer time in ms in bits 0..15. */
uint32_t msid_co_hb_entry(unsigned node, unsigned time_ms);

/** What ::msid_co_hb_check found. */
typedef enum msid_co_hb_status {
    MSID_CO_HB_WAITING = 0,  /**< no heartbeat yet: monitoring has not started */
    MSID_CO_HB_ALIVE = 1,    /**< the last heartbeat is within the consumer time */
    MSID_CO_HB_LOST = 2      /**< the consumer time passed without a heartbeat (until the next one arrives) */
} msid_co_hb_status;

/** The heartbeat consumer of one node (caller-owned). */
typedef struct msid_co_hb {
    uint8_t node;          /**< 1..127 */
    uint16_t time_ms;      /**< consumer time, 1..65535 ms */
    uint8_t state;         /**< NMT state of the last heartbeat (::MSID_CO_STATE_UNKNOWN before the first) */
    uint8_t lost;          /**< 1 from the check that found the consumer time passed until the next heartbeat */
    uint64_t last_ms;      /**< time of the last heartbeat (the caller's clock) */
    uint64_t heartbeats;   /**< heartbeats received */
    uint64_t bootups;      /**< boot-up messages received (the node reset) */
    uint64_t losses;       /**< times the consumer time passed */
    uint64_t malformed;    /**< frames of its COB-ID that were not one byte */
} msid_co_hb;

/**
 * @brief Watch node with consumer time time_ms.
 * @return 0, -MSID_DAQ_E_ARG for a node id outside 1..127 or a time of 0 or beyond 65535
 */
int msid_co_hb_init(msid_co_hb *hb, unsigned node, unsigned time_ms);

/**
 * @brief Offer a received frame at now_ms.
 * @return 1 when it was this node's heartbeat (state updated, a loss ended), 0 when it was another frame,
 *         -MSID_DAQ_E_PROTOCOL when it had this node's COB-ID but not one byte (counted, state kept)
 */
int msid_co_hb_frame(msid_co_hb *hb, const msid_can_frame *f, uint64_t now_ms);

/** @brief The consumer's verdict at now_ms (a loss is counted once, when first found). */
msid_co_hb_status msid_co_hb_check(msid_co_hb *hb, uint64_t now_ms);

#ifdef __cplusplus
}
#endif
#endif
