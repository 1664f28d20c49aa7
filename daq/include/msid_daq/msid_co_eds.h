/**
 * @file msid_co_eds.h
 * @brief A CANopen node's object dictionary from its EDS or DCF file (CiA 306, INI), and the checks made
 *        with it before anything is written: an entry the node does not have, a read-only entry as a
 *        target, a value of another size than the entry's type, an object that is not PDO-mappable.
 *
 * Read: the sections [XXXX] of variables (ObjectType 0x7, or none) and domains (0x2), and the
 * [XXXXsubY] sections of records and arrays (ObjectType 0x8, 0x9), with an array's CompactSubObj=N
 * (subindexes 1..N of the array's own DataType and AccessType, 0 the count); in each, DataType,
 * AccessType (ro, wo, rw, rwr, rww, const), PDOMapping and DefaultValue (or a DCF's ParameterValue,
 * which wins). Other sections and keys are skipped. Refused, with the line: a section of no ObjectType
 * CiA 306 defines, a variable without DataType or AccessType, an unknown access type, two sections of
 * one entry.
 */
#ifndef MSID_CO_EDS_H
#define MSID_CO_EDS_H

#include <stddef.h>
#include <stdint.h>
#include "msid_co_pdo.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Access types of CiA 306. */
typedef enum msid_co_access {
    MSID_CO_RO = 0,  /**< read only (may change: a measured value) */
    MSID_CO_WO,      /**< write only */
    MSID_CO_RW,      /**< read and write */
    MSID_CO_RWR,     /**< read and write, mapped in a TPDO */
    MSID_CO_RWW,     /**< read and write, mapped in an RPDO */
    MSID_CO_CONST    /**< read only, constant */
} msid_co_access;

/** One entry of the dictionary. */
typedef struct msid_co_od_entry {
    uint16_t index;
    uint8_t sub;
    uint8_t access;        /**< ::msid_co_access */
    uint16_t type;         /**< CiA 301 data type index (0x0007 UNSIGNED32, 0x000F DOMAIN, ...) */
    uint8_t pdo_mappable;  /**< 1: PDOMapping=1 */
    char name[48];         /**< ParameterName, cut to fit */
    char value[40];        /**< DefaultValue or ParameterValue as written ("" when none) */
    uint32_t line;         /**< line of its section in the file */
} msid_co_od_entry;

/** A dictionary read into caller memory (entries sorted by index, then subindex). */
typedef struct msid_co_eds {
    msid_co_od_entry *e;
    uint32_t n;
    char source[128];      /**< the file, for messages */
    char err[240];         /**< what is wrong ("" after success) */
} msid_co_eds;

/**
 * @brief Read an EDS or DCF file into entries[0..cap).
 * @return 0; -MSID_DAQ_E_IO (the file cannot be read), -MSID_DAQ_E_FORMAT (a section or key msid refuses:
 *         eds->err names the line), -MSID_DAQ_E_RANGE (more than cap entries: eds->err says how many)
 */
int msid_co_eds_load(const char *path, msid_co_eds *eds, msid_co_od_entry *entries, uint32_t cap);

/** @brief The entry index:sub, or NULL. O(log n). */
const msid_co_od_entry *msid_co_eds_find(const msid_co_eds *eds, uint16_t index, uint8_t sub);

/** @brief Bits of a value of a CiA 301 basic data type (BOOLEAN 1 .. UNSIGNED64 64); 0 for strings, domains and unknown types. */
unsigned msid_co_type_bits(uint16_t type);

/** @brief "UNSIGNED32", "INTEGER16", "DOMAIN", ... ("data type 0xNNNN" is not given: "unknown type"). */
const char *msid_co_type_name(uint16_t type);

/**
 * @brief Check a write of `bytes` bytes to index:sub against the dictionary (before anything is written).
 * @return 0, or -MSID_DAQ_E_ARG with err naming the entry and the problem (not in the file; read only or
 *         constant; another size than its type's)
 */
int msid_co_eds_check_write(const msid_co_eds *eds, uint16_t index, uint8_t sub, size_t bytes, char *err, size_t len);

/**
 * @brief Check a PDO's mapping against the dictionary: each object there, PDO-mappable, of the bits its
 *        type has, and for an RPDO (msid's targets) writable.
 * @return 0, or -MSID_DAQ_E_ARG with err naming the PDO, the object and the problem
 */
int msid_co_eds_check_pdo(const msid_co_eds *eds, const msid_co_pdo_cfg *c, char *err, size_t len);

#ifdef __cplusplus
}
#endif
#endif
