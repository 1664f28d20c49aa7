/**
 * @file msid_devdesc.h
 * @brief msid-device/1: the description of a device that does not run msid's
 *        firmware (a PLC, a drive, an I/O module, an ECU), as typed values.
 *
 * A description names the transport and, for every channel, where it lives
 * on that transport and what it means:
 *  - `drive` channels are written by the host every tick (the excitation):
 *    their limits (`min`, `max`, `max_step` per tick), the `safe` value
 *    written on every way out, the operating point the excitation is added
 *    to and its peak amplitude, all in physical units;
 *  - `measure` channels are read every tick, each with a role: `input` (the
 *    input the device applied, read back), `output`, `reference` (recorded,
 *    not estimated from) or `counter` (the device's cycle counter, which
 *    lets the host see the device's clock).
 * Physical value = raw * scale + offset. The file format (TOML) is read by
 * ::msid_devdesc_load (msid_devdesc_file.h); docs/devices.md describes it.
 * This header holds the typed form shared by the host's tick loop (daq/)
 * and the device simulator (firmware_sim/), the checks every consumer runs,
 * and the register value codec. No allocation, no printing.
 */
#ifndef MSID_DEVDESC_H
#define MSID_DEVDESC_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MSID_DEV_MAX_DRIVE 16u     /**< drive channels (the design's inputs) */
#define MSID_DEV_MAX_MEASURE 40u   /**< measure channels */
#define MSID_DEV_NAME_CAP 64u      /**< bytes of a name, message or signal name, with the NUL */
#define MSID_DEV_UNIT_CAP 32u      /**< bytes of a unit, with the NUL */
#define MSID_DEV_PATH_CAP 512u     /**< bytes of a path, with the NUL */

/** Transports. */
typedef enum msid_dev_transport { MSID_DEV_MODBUS = 1, MSID_DEV_CAN = 2, MSID_DEV_CANOPEN = 3 } msid_dev_transport;

/** What a CANopen channel's raw value counts (its scale is resolved by the link where it depends on the node). */
/** Who sends a CANopen run's SYNC (key sync). */
typedef enum msid_dev_co_sync {
    MSID_DEV_SYNC_TICK = 0,     /**< "tick": msid's tick loop, each SYNC right after that tick's RPDO */
    MSID_DEV_SYNC_KERNEL = 1    /**< "kernel": the kernel's broadcast manager on its own timer; the samples placed
                                     by SYNC count (msid_co_map.h) */
} msid_dev_co_sync;

typedef enum msid_dev_co_quantity {
    MSID_DEV_CO_RAW = 0,       /**< the description's scale and offset, as written */
    MSID_DEV_CO_TORQUE = 1,    /**< per mille of the rated torque: scale = rated torque (N m) / 1000, from the
                                    description's rated_torque or the node's 0x6076 (mN m) */
    MSID_DEV_CO_VELOCITY = 2,  /**< the description's velocity_scale */
    MSID_DEV_CO_POSITION = 3   /**< the description's position_scale */
} msid_dev_co_quantity;

/** Bytes one RPDO or TPDO carries (classic CAN), and TPDOs msid maps the measure channels into. */
#define MSID_DEV_CO_PDO_BYTES 8u
#define MSID_DEV_CO_TPDOS 2u

/** Roles of measure channels. */
typedef enum msid_dev_role {
    MSID_DEV_ROLE_INPUT = 1,      /**< the input the device applied, read back (errors-in-variables FRF) */
    MSID_DEV_ROLE_OUTPUT = 2,     /**< an output of the FRF */
    MSID_DEV_ROLE_REFERENCE = 3,  /**< recorded beside the FRF, not estimated from */
    MSID_DEV_ROLE_COUNTER = 4     /**< the device's cycle counter (wraps at its type's range) */
} msid_dev_role;

/** Modbus register tables. */
typedef enum msid_dev_table { MSID_DEV_HOLDING = 1, MSID_DEV_INPUT = 2 } msid_dev_table;

/** Register value types. */
typedef enum msid_dev_type {
    MSID_DEV_INT16 = 1, MSID_DEV_UINT16, MSID_DEV_INT32, MSID_DEV_UINT32, MSID_DEV_FLOAT32, MSID_DEV_FLOAT64
} msid_dev_type;

/** Which clock the tick loop runs on. */
typedef enum msid_dev_clock {
    MSID_DEV_CLOCK_HOST = 1,      /**< absolute deadlines on the host's monotonic clock */
    MSID_DEV_CLOCK_DEVICE = 2     /**< the device's: its counter (Modbus) or its status frames (CAN) pace the ticks */
} msid_dev_clock;

/** One channel. Limits and values are physical units; NAN where the description gives none. */
typedef struct msid_dev_chan {
    char name[MSID_DEV_NAME_CAP];
    char unit[MSID_DEV_UNIT_CAP];
    uint32_t role;                /**< measure channels: ::msid_dev_role (0 for drive channels) */
    double scale, offset;         /**< physical = raw * scale + offset (defaults 1 and 0); scale != 0 */
    /* drive channels */
    double min, max;              /**< allowed range (NAN: none) */
    double max_step;              /**< largest change from one tick to the next (NAN: none) */
    double safe;                  /**< written on every way out; required for drive channels */
    double op;                    /**< operating point the excitation is added to (NAN: the safe value) */
    double amplitude;             /**< peak of the excitation around op (NAN: half the room to the nearest limit) */
    /* Modbus */
    uint32_t table;               /**< ::msid_dev_table */
    uint32_t addr;                /**< first register, 0..65535 */
    uint32_t type;                /**< ::msid_dev_type */
    uint32_t word_order;          /**< MSID_MB_ABCD.. (msid_mb_proto.h) */
    /* CAN (resolved against the DBC by the CAN session) */
    char message[MSID_DEV_NAME_CAP];
    char signal[MSID_DEV_NAME_CAP];
    int32_t reads_back;           /**< role input: index of the drive channel it reads back (-1: the k-th input
                                       channel reads back the k-th drive channel) */
    /* CANopen: the object dictionary entry the channel is mapped from (type: int16, uint16, int32, uint32, float32) */
    uint16_t co_index;            /**< 0x0001..0xFFFF; 0: not given */
    uint8_t co_sub;
    uint8_t co_quantity;          /**< ::msid_dev_co_quantity */
    uint32_t line;                /**< line of the channel's table in the description (messages) */
} msid_dev_chan;

/** A device description. */
typedef struct msid_devdesc {
    char source[MSID_DEV_PATH_CAP];   /**< the file it was read from (messages) */
    char name[MSID_DEV_NAME_CAP];     /**< optional device name */
    uint32_t transport;               /**< ::msid_dev_transport */
    uint32_t unit;                    /**< Modbus unit id 0..247 (0: the device URI's) */
    int32_t fc23;                     /**< Modbus function 23 (read/write in one transaction): -1 when the device
                                           answers it (tried once with the safe values), 0 never, 1 always */
    uint32_t fade_periods;            /**< whole periods of fade-in and of fade-out, 0..8 (default 1) */
    uint32_t clock;                   /**< ::msid_dev_clock */
    double cycle_hz;                  /**< the device's own cycle rate, when stated (NAN: unknown) */
    char dbc[MSID_DEV_PATH_CAP];      /**< CAN: the DBC, relative to the description's folder when not absolute */
    /* CANopen (CiA 402 drives) */
    uint32_t co_preset;               /**< the preset that filled the channels: its mode (8 CSP, 9 CSV, 10 CST; 0: none) */
    uint32_t co_mode;                 /**< modes of operation 0x6060 written before the run (8, 9, 10) */
    uint32_t co_closed_loop;          /**< a closed-loop preset: the FRF's input is the reference read back, and the
                                           plant is estimated through it (G = G_yr G_ur^-1, the torque demand its
                                           input); 1: "csv-loop" (the reference the velocity target the drive
                                           applied), 2: "csv-torque-loop" (the reference the torque offset 0x60B2
                                           the drive applied, in CSV at hold_velocity); 0: none */
    double co_hold_velocity;          /**< "csv-torque-loop": the velocity target 0x60FF held through the run, in
                                           velocity_unit (default 0; its counts must fit INTEGER32); 0x60FF is
                                           written 0 on every way out */
    double rated_torque;              /**< N m (NAN: the node's 0x6076, read by SDO) */
    double velocity_scale, position_scale;   /**< physical units per count of 0x606C/0x60FF, 0x6064/0x607A */
    char velocity_unit[MSID_DEV_UNIT_CAP], position_unit[MSID_DEV_UNIT_CAP];
    int32_t restore_pdo;              /**< 1: the PDO mapping read before the run is written back after it */
    uint32_t heartbeat_ms;            /**< consumer time msid watches the node's heartbeat with (0: none) */
    uint32_t co_sync;                 /**< who sends the SYNC of a run: ::MSID_DEV_SYNC_TICK (msid's tick, after the
                                           RPDO) or ::MSID_DEV_SYNC_KERNEL (the kernel's timer, CAN_BCM) */
    char co_eds[MSID_DEV_PATH_CAP];   /**< the node's EDS/DCF every entry is checked against before the run, relative
                                           to the description's folder when not absolute ("": none) */
    uint32_t n_drive, n_measure;
    msid_dev_chan drive[MSID_DEV_MAX_DRIVE];
    msid_dev_chan measure[MSID_DEV_MAX_MEASURE];
} msid_devdesc;

/** @brief Reset a description to its defaults (no channels, fade 1 period, host clock, fc23 -1). */
void msid_devdesc_defaults(msid_devdesc *d);

/** @brief Reset a channel to its defaults (scale 1, offset 0, limits NAN, ABCD, reads_back -1). */
void msid_dev_chan_defaults(msid_dev_chan *c);

/**
 * @brief Check a description as a whole: unique names, every drive channel
 *        with a finite safe value inside [min, max], min < max, max_step > 0,
 *        op inside the range, the amplitude positive, Modbus drive channels in
 *        holding registers, registers inside 0..65535 and not overlapping
 *        another channel's, values representable in their type, CAN channels
 *        with message and signal, at least one drive and one output channel,
 *        every input channel reading back a drive channel exactly once;
 *        CANopen: every channel with its object and an int16, uint16, int32,
 *        uint32 or float32 type, the drive channels in one RPDO (8 bytes) and
 *        the measure channels in two TPDOs (8 bytes, 8 objects each), a mode.
 * @param err  message (names the channel and its line), cap bytes
 * @return 0, or -1 with err set
 */
int msid_devdesc_check(const msid_devdesc *d, char *err, size_t cap);

/** @brief Channels of a role among the measure channels. */
uint32_t msid_devdesc_count(const msid_devdesc *d, msid_dev_role role);

/** @brief Index of the measure channel reading back drive channel i (-1: none). */
int msid_devdesc_readback(const msid_devdesc *d, uint32_t i);

/**
 * @brief Where the measure channels go in the TPDOs: channels are packed in order, TPDO1 first, a channel that
 *        does not fit the remaining room of TPDO1 opening TPDO2.
 * @param tpdo_of  [n_measure] receives 0 or 1 (may be NULL)
 * @return TPDOs used (1 or 2), or 0 when the channels do not fit in two
 */
uint32_t msid_devdesc_co_pack(const msid_devdesc *d, uint8_t *tpdo_of);

/** @brief Bytes a CANopen channel's object takes in a PDO (2 or 4; 0 for a type a PDO does not carry here). */
uint32_t msid_dev_co_bytes(const msid_dev_chan *c);

/** @brief Registers one value of a type takes (1, 2 or 4; 0 if unknown). */
uint32_t msid_dev_type_regs(uint32_t type);

/** @brief Name of a type ("int16", ...; NULL if unknown). */
const char *msid_dev_type_name(uint32_t type);

/**
 * @brief Encode a physical value into a channel's registers: raw = (v - offset)
 *        / scale, rounded to nearest for integer types.
 * @param regs  msid_dev_type_regs(c->type) registers, in the channel's word order
 * @return 0, or -1 when the raw value does not fit the type (nothing written)
 */
int msid_dev_encode(const msid_dev_chan *c, double v, uint16_t *regs);

/** @brief Decode a channel's registers into a physical value (a non-finite float decodes as it is). */
double msid_dev_decode(const msid_dev_chan *c, const uint16_t *regs);

/** @brief The raw value of a channel's registers before scale and offset (counters). */
double msid_dev_decode_raw(const msid_dev_chan *c, const uint16_t *regs);

#ifdef __cplusplus
}
#endif
#endif
