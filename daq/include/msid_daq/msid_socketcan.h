/**
 * @file msid_socketcan.h
 * @brief SocketCAN transport (Linux raw CAN socket).
 *
 * CAN_RAW with CAN_RAW_FD_FRAMES; every read whose length is not CAN_MTU or
 * CANFD_MTU is rejected and counted. Identifier filters (CAN_RAW_FILTER),
 * error frames (CAN_RAW_ERR_FILTER: all classes), kernel receive timestamps
 * (SO_TIMESTAMPNS), kernel drop counts (SO_RXQ_OVFL, kept apart from the
 * protocol's sequence gaps), a configurable receive buffer (SO_RCVBUF, or
 * SO_RCVBUFFORCE above net.core.rmem_max, which needs CAP_NET_ADMIN), and
 * ENOBUFS on send handled with poll() and retry. Receives up to 64 frames
 * per recvmmsg() call.
 */
#ifndef MSID_SOCKETCAN_H
#define MSID_SOCKETCAN_H

#include "msid_can_transport.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Up to this many identifier filters. */
#define MSID_SOCKETCAN_MAX_FILTERS 8

/** Options. */
typedef struct msid_socketcan_cfg {
    const char *iface;          /**< interface name, e.g. "vcan0" */
    int fd_frames;              /**< 1: enable CAN FD (needs MTU 72) */
    uint32_t filter_id[MSID_SOCKETCAN_MAX_FILTERS];   /**< accept id & mask == filter_id & mask */
    uint32_t filter_mask[MSID_SOCKETCAN_MAX_FILTERS];
    int n_filters;              /**< 0: accept every identifier */
    int err_frames;             /**< 1: receive error frames (all CAN_ERR_* classes) */
    int rcvbuf;                 /**< receive buffer in bytes (0: kernel default) */
    int recv_own;               /**< 1: also receive this socket's own frames */
} msid_socketcan_cfg;

/** State (caller-owned). */
typedef struct msid_socketcan {
    msid_can_transport tr;      /**< the transport to use after open */
    int fd;
    int ifindex;
    int fd_frames;
    uint32_t last_ovfl;         /**< last SO_RXQ_OVFL value seen */
    int have_ovfl;
    msid_can_link_stats st;
    char err[200];
} msid_socketcan;

/**
 * @brief Open and bind a raw CAN socket.
 * @return 0, or -MSID_DAQ_E_NOSUPPORT (no AF_CAN), -MSID_DAQ_E_NODEV, -MSID_DAQ_E_PERM,
 *         -MSID_DAQ_E_NOFD, -MSID_DAQ_E_IO; s->err holds the detail.
 */
int msid_socketcan_open(msid_socketcan *s, const msid_socketcan_cfg *cfg);

#ifdef __cplusplus
}
#endif
#endif
