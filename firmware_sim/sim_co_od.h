/**
 * @file sim_co_od.h
 * @brief The simulated CANopen node's object dictionary: the entries of an EDS (msid_co_eds.h) with their
 *        values held in fixed memory, data types and access rights enforced on every read and write.
 *
 * Values of basic types (BOOLEAN .. UNSIGNED64) are held as up to 8 bytes, little endian, as on the bus;
 * DOMAIN and string entries hold up to ::SIM_CO_OD_DOMAIN_MAX bytes. Entries the EDS lacks and the node
 * needs (0x1014 COB-ID EMCY) are added with CiA 301's defaults.
 */
#ifndef MSID_SIM_CO_OD_H
#define MSID_SIM_CO_OD_H

#include <stddef.h>
#include <stdint.h>

#include "msid_daq/msid_co_eds.h"

/** Entries the dictionary holds at most. */
#define SIM_CO_OD_MAX 320u
/** Bytes a DOMAIN or string entry holds at most. */
#define SIM_CO_OD_DOMAIN_MAX 256u

/** CiA 301 abort codes the node sends (table 22). */
#define SIM_CO_ABORT_TOGGLE 0x05030000u      /**< toggle bit not alternated */
#define SIM_CO_ABORT_TIMEOUT 0x05040000u     /**< SDO protocol timed out */
#define SIM_CO_ABORT_COMMAND 0x05040001u     /**< command specifier not valid or unknown */
#define SIM_CO_ABORT_WRITE_ONLY 0x06010001u  /**< attempt to read a write only object */
#define SIM_CO_ABORT_READ_ONLY 0x06010002u   /**< attempt to write a read only object */
#define SIM_CO_ABORT_NO_OBJECT 0x06020000u   /**< object does not exist in the object dictionary */
#define SIM_CO_ABORT_NO_MAP 0x06040041u      /**< object cannot be mapped to the PDO */
#define SIM_CO_ABORT_MAP_LEN 0x06040042u     /**< the number and length of the objects would exceed the PDO length */
#define SIM_CO_ABORT_LENGTH 0x06070010u      /**< data type does not match, length of service parameter does not match */
#define SIM_CO_ABORT_TOO_HIGH 0x06070012u    /**< data type does not match, length of service parameter too high */
#define SIM_CO_ABORT_TOO_LOW 0x06070013u     /**< data type does not match, length of service parameter too low */
#define SIM_CO_ABORT_NO_SUB 0x06090011u      /**< subindex does not exist */
#define SIM_CO_ABORT_RANGE 0x06090030u       /**< invalid value for parameter */
#define SIM_CO_ABORT_VALUE_HIGH 0x06090031u  /**< value of parameter written too high */
#define SIM_CO_ABORT_GENERAL 0x08000000u     /**< general error */
#define SIM_CO_ABORT_STORE 0x08000020u       /**< data cannot be transferred or stored to the application */
#define SIM_CO_ABORT_STATE 0x08000022u       /**< ... because of the present device state */

/** One entry with its value. */
typedef struct sim_co_var {
    uint16_t index;
    uint8_t sub;
    uint8_t access;       /**< msid_co_access */
    uint16_t type;        /**< CiA 301 data type index */
    uint8_t mappable;     /**< 1: PDO-mappable */
    uint8_t size;         /**< bytes of a basic type's value, 1..8; 0: DOMAIN or string (len says) */
    uint8_t val[8];       /**< a basic type's value, little endian */
    uint8_t def[8];       /**< its default (restored by NMT resets) */
    uint16_t len;         /**< a DOMAIN's or string's bytes now, 0..SIM_CO_OD_DOMAIN_MAX */
    uint16_t dom;         /**< offset of its bytes in the domain store */
} sim_co_var;

/** The dictionary (caller-owned; no allocation). */
typedef struct sim_co_od {
    sim_co_var v[SIM_CO_OD_MAX];
    uint32_t n;
    uint8_t domains[8u * SIM_CO_OD_DOMAIN_MAX];   /**< bytes of DOMAIN and string entries (8 at most) */
    uint32_t n_dom;
    char err[320];
} sim_co_od;

/**
 * @brief Build the dictionary from an EDS read by msid_co_eds_load, for node id node (1..127: the value of
 *        $NODEID in DefaultValue). @return 0, or -1 with od->err naming the entry (a value that does not
 *        parse or fit its type, too many entries or domains).
 */
int sim_co_od_init(sim_co_od *od, const msid_co_eds *eds, unsigned node);

/** @brief The entry index:sub, or NULL. */
sim_co_var *sim_co_od_find(sim_co_od *od, uint16_t index, uint8_t sub);

/** @brief 1 when some entry has this index. */
int sim_co_od_has_index(const sim_co_od *od, uint16_t index);

/**
 * @brief The abort code a read of index:sub by SDO earns (0: it may be read): object or subindex missing,
 *        write only.
 */
uint32_t sim_co_od_check_read(sim_co_od *od, uint16_t index, uint8_t sub);

/**
 * @brief The abort code a write of len bytes to index:sub by SDO earns before the node's own rules (0: it
 *        may be written): object or subindex missing, read only or constant, length other than the type's.
 */
uint32_t sim_co_od_check_write(sim_co_od *od, uint16_t index, uint8_t sub, size_t len);

/** @brief The bytes of an entry's value (basic types: its size; DOMAIN: its length). */
const uint8_t *sim_co_od_bytes(sim_co_od *od, const sim_co_var *v, size_t *len);

/** @brief Store len bytes as the value (len checked by the caller; a DOMAIN takes 0..SIM_CO_OD_DOMAIN_MAX). */
void sim_co_od_store(sim_co_od *od, sim_co_var *v, const uint8_t *data, size_t len);

/** @brief The value of a basic-type entry as an unsigned integer (sign bits as stored), 0 if absent. */
uint64_t sim_co_od_get(sim_co_od *od, uint16_t index, uint8_t sub);

/** @brief The value of a basic-type entry sign-extended from its size (INTEGERn), 0 if absent. */
int64_t sim_co_od_get_signed(sim_co_od *od, uint16_t index, uint8_t sub);

/** @brief Set a basic-type entry's value (cut to its size); nothing if absent. */
void sim_co_od_set(sim_co_od *od, uint16_t index, uint8_t sub, uint64_t value);

/** @brief Restore the defaults of the entries in [lo, hi] (NMT reset communication: 0x1000..0x1FFF). */
void sim_co_od_reset(sim_co_od *od, uint16_t lo, uint16_t hi);

#endif
