/**
 * @file msid_co_pdo.h
 * @brief CANopen PDO configuration by SDO (CiA 301 7.2.2 and 7.5.2.35-38) and the communication cycle
 *        period 0x1006.
 *
 * A PDO is configured in the order CiA 301 prescribes: its COB-ID made not valid
 * (bit 31 set), its transmission type and (TPDO) inhibit time written, its mapping
 * count set to 0, the mapping entries written, the count set, and the COB-ID made
 * valid again. A mapping longer than 8 bytes, more than 8 entries, a COB-ID
 * outside the 11-bit range or among CiA 301's restricted ones, or a transmission
 * type the PDO cannot take is refused before anything is written. What the node
 * held before is read first (::msid_co_pdo_save), so that it can be put back
 * (::msid_co_pdo_restore), and is put back when a configuration fails part way.
 */
#ifndef MSID_CO_PDO_H
#define MSID_CO_PDO_H

#include <stdint.h>
#include "msid_co_sdo.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Entries a mapping holds at most here (every entry at least one byte: an 8-byte PDO). */
#define MSID_CO_PDO_MAX_ENTRIES 8u
/** Bit 31 of a PDO COB-ID: the PDO is not valid (disabled). */
#define MSID_CO_PDO_COB_INVALID 0x80000000u
/** Bit 30 of a PDO COB-ID: no RTR allowed on this PDO. */
#define MSID_CO_PDO_COB_NO_RTR 0x40000000u
/** Transmission type 1: sent (TPDO) or applied (RPDO) on every SYNC. */
#define MSID_CO_PDO_SYNC_EVERY 1u

/** One mapped object. */
typedef struct msid_co_pdo_entry {
    uint16_t index;
    uint8_t sub;
    uint8_t bits;  /**< 1..64 */
} msid_co_pdo_entry;

/** A PDO's communication and mapping parameters. */
typedef struct msid_co_pdo_cfg {
    uint8_t tx;             /**< 1: a TPDO (node to msid, 0x1800/0x1A00); 0: an RPDO (msid to node, 0x1400/0x1600) */
    uint16_t num;           /**< PDO number, 1..512 */
    uint32_t cob_id;        /**< 11-bit identifier with its bit 30/31 flags as the node keeps them; 0 in a
                                 configuration: the predefined connection set's for PDOs 1..4 */
    uint8_t trans_type;     /**< 0..240 synchronous (1: every SYNC), 252/253 RTR (TPDO), 254/255 event driven */
    uint16_t inhibit_100us; /**< TPDO inhibit time in units of 100 us (0: none; not written for an RPDO) */
    uint8_t n;              /**< mapped entries, 0..::MSID_CO_PDO_MAX_ENTRIES */
    msid_co_pdo_entry e[MSID_CO_PDO_MAX_ENTRIES];
} msid_co_pdo_cfg;

/** @brief The communication parameter index of a PDO (0x1400 + num - 1 or 0x1800 + num - 1); the mapping is + 0x200. */
uint16_t msid_co_pdo_comm_index(unsigned tx, unsigned num);

/** @brief A mapping entry's 32-bit value: index << 16 | sub << 8 | bits. */
uint32_t msid_co_pdo_map_value(const msid_co_pdo_entry *e);

/** @brief Bits a configuration maps. */
unsigned msid_co_pdo_bits(const msid_co_pdo_cfg *c);

/**
 * @brief Check a configuration for node without writing anything.
 * @return 0, or -MSID_DAQ_E_ARG with err (of err_len bytes) naming the PDO and the problem
 */
int msid_co_pdo_check(const msid_co_pdo_cfg *c, unsigned node, char *err, size_t err_len);

/**
 * @brief Read what the node holds for PDO (tx, num) into saved (writes nothing).
 * @return 0 or as ::msid_co_sdo_upload (s->err)
 */
int msid_co_pdo_save(msid_co_sdo *s, unsigned tx, unsigned num, msid_co_pdo_cfg *saved);

/**
 * @brief Write c to the node in CiA 301's order (checked first: nothing is written for a configuration
 *        ::msid_co_pdo_check refuses). When a write fails part way, saved (when not NULL) is written back
 *        and the first failure is the one reported.
 * @return 0; -MSID_DAQ_E_ARG (refused, s->err); or the SDO's error (s->err names the entry, and the node's abort)
 */
int msid_co_pdo_configure(msid_co_sdo *s, const msid_co_pdo_cfg *c, const msid_co_pdo_cfg *saved);

/** @brief Write back a configuration ::msid_co_pdo_save read (its COB-ID as it was, valid or not). */
int msid_co_pdo_restore(msid_co_sdo *s, const msid_co_pdo_cfg *saved);

/** @brief Write the communication cycle period 0x1006 (the SYNC interval a node expects), in us (0: none). */
int msid_co_cycle_write(msid_co_sdo *s, uint32_t period_us);

/** @brief Read the communication cycle period 0x1006, in us. */
int msid_co_cycle_read(msid_co_sdo *s, uint32_t *period_us);

#ifdef __cplusplus
}
#endif
#endif
