/**
 * @file msid_dbc.h
 * @brief DBC files: the messages and signals of a CAN database read into
 *        caller memory, and the signal codec (payload bytes <-> physical values).
 *
 * A device that does not run msid's firmware (an ECU, a drive) describes its
 * CAN frames in a DBC file: messages (`BO_`: identifier, payload length,
 * sender) and their signals (`SG_`: start bit, length, byte order, sign,
 * factor and offset, range, unit). Reading is kissfft style, ask the size,
 * then place: ::msid_dbc_mem_size gives the bytes for a text,
 * ::msid_dbc_init parses it into that memory (names and units NUL-terminated
 * in the arena). No allocation, no printing; every result is the same bits on
 * every host (no type punning that depends on the host's byte order).
 *
 * Read: `BO_` with standard and extended identifiers (bit 31 of the DBC
 * identifier marks an extended one: stored with ::MSID_CAN_EFF_FLAG), payloads
 * of 0..64 bytes (CAN FD); `SG_` of 1..64 bits, `@1` Intel (little endian) and
 * `@0` Motorola (big endian, DBC's sawtooth numbering: the start bit is the
 * most significant bit), `+`/`-`, (factor,offset), [min|max], unit, receivers;
 * `SIG_VALTYPE_` 1 (IEEE float32) and 2 (float64); simple multiplexing (one
 * `M` switch per message, `mN` signals present when the switch's raw value is
 * N); `BA_ "GenMsgCycleTime" BO_ id ms;` and its `BA_DEF_DEF_` default as the
 * message's cycle time (as cantools: only where a `BA_DEF_` defines the
 * attribute). Skipped: `VERSION`, `NS_`, `BS_`, `BU_`, `CM_` (multi-line
 * strings), `BA_DEF_`, other `BA_`, `VAL_`, `VAL_TABLE_`, `EV_` and every other
 * `;`-terminated section of the format; the message
 * `VECTOR__INDEPENDENT_SIG_MSG` (signals of no message) with its signals.
 * Refused, with the line and the reason: extended multiplexing (`SG_MUL_VAL_`,
 * an `mNM` signal, a second switch in a message): msid cannot tell which
 * signals such a frame carries; a signal whose bits leave the message's
 * payload; a factor of 0; a float signal whose length is not 32 or 64; a
 * standard identifier beyond 0x7FF or an extended one beyond 0x1FFFFFFF; two
 * messages with one identifier or one name, two signals of one name in a
 * message; anything that is not DBC syntax.
 */
#ifndef MSID_DBC_H
#define MSID_DBC_H

#include <stddef.h>
#include <stdint.h>
#include "msid_can_transport.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest payload of a message, in bytes (CAN FD). */
#define MSID_DBC_MAX_DLC 64u

/** Byte order of a signal, as DBC writes it after '@'. */
typedef enum msid_dbc_order { MSID_DBC_MOTOROLA = 0, MSID_DBC_INTEL = 1 } msid_dbc_order;

/** Value type of a signal (`SIG_VALTYPE_`). */
typedef enum msid_dbc_type { MSID_DBC_INT = 0, MSID_DBC_FLOAT32 = 1, MSID_DBC_FLOAT64 = 2 } msid_dbc_type;

/** Role of a signal in simple multiplexing. */
typedef enum msid_dbc_mux { MSID_DBC_PLAIN = 0, MSID_DBC_SWITCH = 1, MSID_DBC_MUXED = 2 } msid_dbc_mux;

/** One signal (in the arena). */
typedef struct msid_dbc_signal {
    const char *name;         /**< as the DBC names it */
    const char *unit;         /**< "" when the DBC gives none */
    uint32_t start;           /**< DBC start bit, 0..511 (Motorola: of the most significant bit) */
    uint32_t length;          /**< bits, 1..64 */
    uint8_t order;            /**< ::msid_dbc_order */
    uint8_t is_signed;        /**< '-': two's complement (integers) */
    uint8_t type;             /**< ::msid_dbc_type */
    uint8_t mux;              /**< ::msid_dbc_mux */
    uint32_t mux_value;       /**< MSID_DBC_MUXED: present when the switch's raw value equals this */
    double factor, offset;    /**< physical = raw * factor + offset (factor != 0) */
    double min, max;          /**< the DBC's range; checked by ::msid_dbc_encode only when min < max */
    uint32_t message;         /**< index of its message in msid_dbc::messages */
    uint32_t line;            /**< line of its SG_ in the file (1 = the first) */
} msid_dbc_signal;

/** One message (in the arena). */
typedef struct msid_dbc_message {
    const char *name;
    const char *sender;       /**< "" when the DBC gives none */
    uint32_t id;              /**< 11- or 29-bit identifier, | ::MSID_CAN_EFF_FLAG for an extended one */
    uint32_t dlc;             /**< payload bytes, 0..::MSID_DBC_MAX_DLC */
    uint32_t cycle_ms;        /**< GenMsgCycleTime in ms (0: the DBC gives none) */
    uint32_t line;            /**< line of its BO_ */
    uint32_t first_signal;    /**< its signals are msid_dbc::signals[first_signal .. first_signal + n_signals) */
    uint32_t n_signals;
    int32_t mux_signal;       /**< index in msid_dbc::signals of its multiplexer switch, -1: none */
} msid_dbc_message;

/** A parsed DBC (caller-owned; the tables live in the caller's memory). */
typedef struct msid_dbc {
    uint32_t n_messages, n_signals;
    msid_dbc_message *messages;   /**< [n_messages], in file order */
    msid_dbc_signal *signals;     /**< [n_signals], by message, in file order */
    uint32_t *by_id;              /**< [n_messages] message indices sorted by id (binary search) */
    uint32_t *by_name;            /**< [n_messages] message indices sorted by name (strcmp) */
    uint32_t err_line;            /**< line of the problem ::msid_dbc_init refused (0: none or no line) */
    char err[224];                /**< what is wrong, with its line ("" after success) */
} msid_dbc;

/**
 * @brief Bytes of memory ::msid_dbc_init needs for this DBC text.
 * @param text the file's bytes (need not be NUL-terminated); len their count
 * @return the size, or 0 for a text that is not DBC syntax (::msid_dbc_init with
 *         no memory then names the line and the problem)
 */
size_t msid_dbc_mem_size(const char *text, size_t len);

/**
 * @brief Parse a DBC text into mem (at least ::msid_dbc_mem_size bytes, aligned
 *        to 8 bytes). The text may be freed afterwards: d refers only to mem.
 * @return 0; -MSID_DAQ_E_FORMAT for a text msid does not read (d->err names the
 *         line and what is wrong; a syntax error is reported even with mem NULL);
 *         -MSID_DAQ_E_ARG for d or text NULL, mem too small or misaligned (d->err)
 */
int msid_dbc_init(msid_dbc *d, const char *text, size_t len, void *mem, size_t mem_len);

/** @brief The message of identifier id (| ::MSID_CAN_EFF_FLAG when extended; RTR/ERR bits must be clear), or NULL. O(log n). */
const msid_dbc_message *msid_dbc_message_by_id(const msid_dbc *d, uint32_t id);

/** @brief The message of this name, or NULL. O(log n). */
const msid_dbc_message *msid_dbc_message_by_name(const msid_dbc *d, const char *name);

/** @brief The signal of message m of this name, or NULL. */
const msid_dbc_signal *msid_dbc_signal_by_name(const msid_dbc *d, const msid_dbc_message *m, const char *name);

/** @brief Payload bytes a frame needs to carry signal s whole (its last byte + 1), 1..64. */
uint32_t msid_dbc_signal_bytes(const msid_dbc_signal *s);

/**
 * @brief The raw bits of s in a payload, unsigned (bit length-1 is the sign of a signed signal).
 * @param len payload bytes
 * @return 0, or -MSID_DAQ_E_SHORT when the payload ends before the signal's last byte
 */
int msid_dbc_get_raw(const msid_dbc_signal *s, const uint8_t *data, size_t len, uint64_t *raw);

/**
 * @brief Write the low `length` bits of raw as s into a payload (its other bits unchanged).
 * @return 0, -MSID_DAQ_E_SHORT (payload too short) or -MSID_DAQ_E_RANGE (raw has bits above length)
 */
int msid_dbc_set_raw(const msid_dbc_signal *s, uint64_t raw, uint8_t *data, size_t len);

/**
 * @brief Physical value of s in a payload: raw * factor + offset, raw read as an
 *        unsigned or two's complement integer or as an IEEE float32/float64.
 *        Integers above 2^53 in magnitude are rounded to the nearest double.
 * @return 0 or -MSID_DAQ_E_SHORT (the payload ends before the signal's last byte)
 */
int msid_dbc_decode(const msid_dbc_signal *s, const uint8_t *data, size_t len, double *phys);

/**
 * @brief Write physical value phys as s: raw = (phys - offset) / factor, rounded to
 *        the nearest integer (ties to even, as cantools) or to the nearest float32.
 *        Refused, payload unchanged, when the raw does not fit the signal's bits
 *        (never clamped), when phys is NaN or infinite, and when the DBC gives a
 *        range (min < max) and phys lies outside it by more than |factor| 1e-6
 *        (the rounding of the DBC's decimal bounds; cantools' tolerance).
 * @return 0, -MSID_DAQ_E_RANGE (refused) or -MSID_DAQ_E_SHORT (payload too short)
 */
int msid_dbc_encode(const msid_dbc_signal *s, double phys, uint8_t *data, size_t len);

/**
 * @brief Does a payload of s's message carry s? Plain signals and the switch
 *        always; a multiplexed signal when the switch's raw value is its mux_value.
 * @return 1 present, 0 not, -MSID_DAQ_E_SHORT (the payload ends before the switch)
 */
int msid_dbc_present(const msid_dbc *d, const msid_dbc_signal *s, const uint8_t *data, size_t len);

#ifdef __cplusplus
}
#endif
#endif
