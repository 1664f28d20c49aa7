/**
 * @file msid_can_bitrate.h
 * @brief The bit rate a SocketCAN interface is set to, as the kernel reports it (rtnetlink).
 *
 * One RTM_GETLINK request for the interface's index; the reply's IFLA_LINKINFO carries the link kind
 * (IFLA_INFO_KIND: "can" for a CAN controller, "vcan" and "vxcan" for virtual buses) and, for a CAN
 * controller, IFLA_INFO_DATA with IFLA_CAN_BITTIMING (struct can_bittiming, the nominal bit rate) and,
 * with CAN FD, IFLA_CAN_DATA_BITTIMING (the data phase's rate). The same as `ip -details link show IFACE`
 * prints. The request (::msid_can_bitrate_query) and the reading of its reply (::msid_can_bitrate_parse,
 * pure: bytes in, result out, never a byte read past the given length) are apart, so that the reading is
 * tested on replies built in memory. Run once before a measurement: a stack buffer, no allocation.
 * Linux only (MSID_WITH_CAN); elsewhere the query fails with one message.
 */
#ifndef MSID_CAN_BITRATE_H
#define MSID_CAN_BITRATE_H

#include <stddef.h>
#include <stdint.h>

#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/** What the kernel said of the interface. */
typedef enum msid_can_bitrate_status {
    MSID_CAN_BITRATE_KNOWN = 0,   /**< a CAN controller with its bit timing set: bitrate (and data_bitrate) hold it */
    MSID_CAN_BITRATE_VIRTUAL,     /**< vcan or vxcan: a virtual bus has no bit rate */
    MSID_CAN_BITRATE_UNSET,       /**< a CAN controller whose bit timing is not set (ip link set IFACE type can bitrate BPS) */
    MSID_CAN_BITRATE_NOT_CAN,     /**< an interface of another kind (kind names it; "" for none, as lo) */
    MSID_CAN_BITRATE_MISSING,     /**< no interface of that name or index */
    MSID_CAN_BITRATE_FAILED       /**< no answer could be read: the request failed or the reply is malformed (err) */
} msid_can_bitrate_status;

/** Room for the link kind (IFLA_INFO_KIND), its terminating zero included. */
#define MSID_CAN_BITRATE_KIND_CAP 16

/** The result (caller-owned). */
typedef struct msid_can_bitrate {
    msid_can_bitrate_status status;
    uint32_t bitrate;        /**< bit/s of the nominal (arbitration) phase, > 0 when KNOWN, else 0 */
    uint32_t data_bitrate;   /**< bit/s of the CAN FD data phase; 0: no data bit timing set (classic CAN) */
    char kind[MSID_CAN_BITRATE_KIND_CAP];   /**< IFLA_INFO_KIND ("can", "vcan", "vxcan", "veth", ...); "" if none */
    char err[160];           /**< why, when FAILED (and a short description otherwise) */
} msid_can_bitrate;

/**
 * @brief Read one rtnetlink reply to RTM_GETLINK (one or more netlink messages, as received).
 *
 * An RTM_NEWLINK message is read for its IFLA_LINKINFO; an NLMSG_ERROR of -ENODEV is MISSING, any other
 * error FAILED. Every length (nlmsghdr, rtattr, nested rtattr, the can_bittiming payload) is checked
 * against what encloses it and against len: a reply that is cut short or whose lengths do not add up is
 * FAILED, never read past its end. The bytes need no alignment.
 * @param reply  the received bytes (NULL only with len 0)
 * @param len    their count
 * @param out    the result (always written)
 * @return 0 when out->status is KNOWN, VIRTUAL, UNSET, NOT_CAN or MISSING; -MSID_DAQ_E_PROTOCOL (FAILED:
 *         malformed, or no link message in it), -MSID_DAQ_E_IO (FAILED: the kernel's error), -MSID_DAQ_E_ARG
 */
int msid_can_bitrate_parse(const void *reply, size_t len, msid_can_bitrate *out);

/**
 * @brief Ask the kernel for the bit rate of interface iface (a name of 1..15 characters, e.g. "can0").
 *
 * An interface the name does not resolve to is MISSING without a request. Needs no privilege.
 * @return as ::msid_can_bitrate_parse; also -MSID_DAQ_E_IO when no NETLINK_ROUTE socket can be opened or
 *         nothing arrives within a second, -MSID_DAQ_E_NOSUPPORT when built without SocketCAN (out->err says which)
 */
int msid_can_bitrate_query(const char *iface, msid_can_bitrate *out);

/** @brief A short name of a status ("known", "virtual", "unset", "not CAN", "missing", "failed"). */
const char *msid_can_bitrate_status_name(msid_can_bitrate_status s);

#ifdef __cplusplus
}
#endif
#endif
