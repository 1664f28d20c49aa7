/**
 * @file msid_co_emcy.h
 * @brief CANopen emergency messages (CiA 301 7.2.7): decoded and named.
 *
 * A node sends an EMCY (0x80 + node id, 8 bytes) when an error occurs and again,
 * with error code 0x0000, when its errors are reset: the emergency error code
 * (little endian), its error register (0x1001) and five manufacturer-specific
 * bytes. msid treats an EMCY other than an error reset during a run as a way
 * out. Error codes are named by CiA 301's table (classes by their high byte or
 * nibble), the communication codes 0x81xx/0x82xx and a few of CiA 402's drive
 * codes by their exact value.
 */
#ifndef MSID_CO_EMCY_H
#define MSID_CO_EMCY_H

#include <stddef.h>
#include <stdint.h>
#include "msid_co.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Bits of the error register 0x1001. */
#define MSID_CO_ERREG_GENERIC 0x01u
#define MSID_CO_ERREG_CURRENT 0x02u
#define MSID_CO_ERREG_VOLTAGE 0x04u
#define MSID_CO_ERREG_TEMPERATURE 0x08u
#define MSID_CO_ERREG_COMMUNICATION 0x10u
#define MSID_CO_ERREG_PROFILE 0x20u
#define MSID_CO_ERREG_MANUFACTURER 0x80u

/** One decoded emergency message. */
typedef struct msid_co_emcy {
    uint8_t node;          /**< sender, 1..127 */
    uint16_t code;         /**< emergency error code (0x0000: error reset or no error) */
    uint8_t reg;           /**< error register 0x1001 */
    uint8_t mfr[5];        /**< manufacturer-specific bytes */
} msid_co_emcy;

/**
 * @brief Decode f when it is an EMCY from node (1..127).
 * @return 1 decoded into e; 0 another frame; -MSID_DAQ_E_PROTOCOL for this node's EMCY COB-ID with a payload
 *         other than 8 bytes
 */
int msid_co_emcy_decode(const msid_can_frame *f, unsigned node, msid_co_emcy *e);

/** @brief The name of an emergency error code: exact where known, else its class's. Never NULL. */
const char *msid_co_emcy_name(uint16_t code);

/** @brief The set bits of an error register by name ("generic, communication"; "none" for 0), into buf of n bytes. */
void msid_co_erreg_describe(uint8_t reg, char *buf, size_t n);

/**
 * @brief One line for a user: "node 5 EMCY 0x8130 (life guard error or heartbeat error), error register
 *        0x11 (generic, communication), manufacturer bytes 01 02 03 04 05".
 * @return the length written (truncated to n - 1 as snprintf)
 */
int msid_co_emcy_describe(const msid_co_emcy *e, char *buf, size_t n);

#ifdef __cplusplus
}
#endif
#endif
