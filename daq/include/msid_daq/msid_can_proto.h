/**
 * @file msid_can_proto.h
 * @brief msid-can/1: the CAN frame layout shared by the device (firmware_sim/)
 *        and the host (daq/). Pure C11: no OS calls, no heap, no stdio.
 *
 * Every identifier is an 11-bit offset from a base (a multiple of 0x80,
 * default 0x200). Host -> device: CTRL (base+0x00), CFG (base+0x01).
 * Device -> host: STATUS (base+0x02) and sample frames. A sample frame
 * starts with a 4-byte header (24-bit sample counter, experiment, period-start
 * and segment-start markers) followed by channel values of one chunk of the
 * row [u_1..u_nu, y_1..y_ny]: scaled int16 or float32, little-endian, in a
 * classic 8-byte frame or a 64-byte CAN FD frame. The design is uploaded as
 * parameters (CFG frames, checked by a CRC-32), never as samples. The full
 * layout is docs/can-protocol.md; the DBC file is daq/can/msid.dbc.
 */
#ifndef MSID_CAN_PROTO_H
#define MSID_CAN_PROTO_H

#include <stddef.h>
#include <stdint.h>
#include "msid/msid_design.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Protocol version carried in CTRL, CFG BEGIN and STATUS INFO frames. */
#define MSID_CAN_PROTO_VERSION 1u
/** Default base identifier. */
#define MSID_CAN_DEFAULT_BASE 0x200u

/** Identifier offsets from the base. */
#define MSID_CAN_ID_CTRL 0x00u     /**< host -> device: start, stop, reset, query */
#define MSID_CAN_ID_CFG 0x01u      /**< host -> device: one design parameter */
#define MSID_CAN_ID_STATUS 0x02u   /**< device -> host: state, info, counters */
#define MSID_CAN_ID_S16 0x10u      /**< + chunk 0..15: classic, 2 int16 channels */
#define MSID_CAN_ID_F32 0x20u      /**< + chunk 0..31: classic, 1 float32 channel */
#define MSID_CAN_ID_FD_S16 0x40u   /**< + chunk 0..1: FD 64 bytes, 30 int16 channels */
#define MSID_CAN_ID_FD_F32 0x48u   /**< + chunk 0..2: FD 64 bytes, 15 float32 channels */

/** Sample header: byte 3 bits. */
#define MSID_CAN_EXP_MASK 0x3Fu
#define MSID_CAN_PSTART 0x40u      /**< first sample of a period (n mod P == 0) */
#define MSID_CAN_SEGSTART 0x80u    /**< first sample after START or a device restart (n == 0) */
/** The sample counter wraps at 2^24. */
#define MSID_CAN_SEQ_MOD (1u << 24)
/** int16 code for a value out of range (decoded as NaN: the period is rejected). */
#define MSID_CAN_S16_INVALID (-32768)

/** Commands (CTRL byte 0). */
enum { MSID_CAN_CMD_START = 1, MSID_CAN_CMD_STOP = 2, MSID_CAN_CMD_RESET = 3, MSID_CAN_CMD_QUERY = 4 };

/** STATUS multiplexer (byte 0). */
enum { MSID_CAN_ST_STATE = 0, MSID_CAN_ST_INFO = 1, MSID_CAN_ST_COUNTERS = 2 };

/** Device states. */
enum {
    MSID_CAN_STATE_BOOT = 0, MSID_CAN_STATE_IDLE = 1, MSID_CAN_STATE_CONFIGURED = 2,
    MSID_CAN_STATE_RUNNING = 3, MSID_CAN_STATE_DONE = 4, MSID_CAN_STATE_ERROR = 5
};

/** Device error codes (STATE byte 3). */
enum {
    MSID_CAN_ERR_NONE = 0,
    MSID_CAN_ERR_VERSION = 1,      /**< protocol version mismatch */
    MSID_CAN_ERR_CRC = 2,          /**< configuration CRC mismatch (a CFG frame was lost) */
    MSID_CAN_ERR_DESIGN = 3,       /**< the design was refused (bytes 4-7: msid_status) */
    MSID_CAN_ERR_NOT_CONFIGURED = 4, /**< START without a committed configuration */
    MSID_CAN_ERR_EXPERIMENT = 5,   /**< experiment index out of range */
    MSID_CAN_ERR_DIMS = 6,         /**< inputs or channels do not match the device */
    MSID_CAN_ERR_CFG = 7           /**< malformed or incomplete configuration */
};

/** CFG parameter identifiers (byte 0). Bytes 1-3: index (u24), bytes 4-7: value (u32). */
enum {
    MSID_CAN_P_BEGIN = 0x01,       /**< index: protocol version */
    MSID_CAN_P_PERIOD = 0x02, MSID_CAN_P_LINES = 0x03, MSID_CAN_P_INPUTS = 0x04,
    MSID_CAN_P_EXPERIMENTS = 0x05, MSID_CAN_P_PATTERN = 0x06, MSID_CAN_P_PHASE_MODE = 0x07,
    MSID_CAN_P_SEED = 0x08,        /**< index 0: low word, 1: high word */
    MSID_CAN_P_BIN = 0x09,         /**< index l */
    MSID_CAN_P_AMP = 0x0A,         /**< index 2 (i L + l) + w: double, w = 0 low word, 1 high word */
    MSID_CAN_P_PHASE = 0x0B,       /**< same indexing, turns */
    MSID_CAN_P_OMEGA = 0x0C,       /**< index 2 l + w: rad/s (continuous-time design) */
    MSID_CAN_P_SAMPLE_TIME = 0x0D, /**< index w: seconds (continuous-time design) */
    MSID_CAN_P_ENCODING = 0x10,    /**< 0: int16 scaled, 1: float32 */
    MSID_CAN_P_SCALE = 0x11,       /**< float32 bits: value of one int16 step */
    MSID_CAN_P_FD = 0x12,          /**< 0: classic 8-byte frames, 1: CAN FD 64-byte frames */
    MSID_CAN_P_RATE = 0x13,        /**< sample rate in Hz (0: as fast as possible) */
    MSID_CAN_P_PERIODS = 0x14,     /**< periods per experiment */
    MSID_CAN_P_COMMIT = 0x7F       /**< value: CRC-32 of every CFG frame since BEGIN */
};

/** Channel encodings. */
enum { MSID_CAN_ENC_S16 = 0, MSID_CAN_ENC_F32 = 1 };

/** Channels carried by one sample frame of this format. */
uint32_t msid_can_chunk_channels(uint32_t encoding, uint32_t fd);
/** Payload bytes of a sample frame (8 classic, 64 FD). */
uint32_t msid_can_sample_len(uint32_t fd);
/** Frames per sample row of n_channels channels. */
uint32_t msid_can_chunks(uint32_t n_channels, uint32_t encoding, uint32_t fd);
/** Identifier offset of chunk k of this format. */
uint32_t msid_can_chunk_id(uint32_t encoding, uint32_t fd, uint32_t k);
/**
 * @brief Classify an identifier offset: returns 1 for a sample frame and sets
 *        *encoding, *fd, *chunk; 0 otherwise.
 */
int msid_can_classify_sample(uint32_t offset, uint32_t *encoding, uint32_t *fd, uint32_t *chunk);

/** CRC-32 (IEEE 802.3, reflected, as zlib) continued from `crc` (start with 0). */
uint32_t msid_can_crc32(uint32_t crc, const uint8_t *p, size_t n);

/** @brief Store v little-endian in p[0..3]. */
void msid_can_put_u32(uint8_t *p, uint32_t v);
/** @brief Read a little-endian 32-bit value from p[0..3]. */
uint32_t msid_can_get_u32(const uint8_t *p);

/**
 * @brief Encode chunk k of one sample row into `data` (msid_can_sample_len bytes).
 * @param seq sample index n (only the low 24 bits are sent)
 * @param flags MSID_CAN_PSTART / MSID_CAN_SEGSTART
 * @param row the n_channels values of the row
 * @param scale int16 step (int16 encoding)
 */
void msid_can_encode_sample(uint8_t *data, uint32_t encoding, uint32_t fd, uint32_t k, uint32_t seq,
                            uint32_t experiment, uint32_t flags, const double *row, uint32_t n_channels,
                            double scale);

/**
 * @brief Decode the values of chunk k into row[] (channels of that chunk only).
 *        An int16 value of MSID_CAN_S16_INVALID decodes as NaN.
 */
void msid_can_decode_values(const uint8_t *data, uint32_t encoding, uint32_t fd, uint32_t k, double *row,
                            uint32_t n_channels, double scale);

/** @brief Name of a device error code (MSID_CAN_ERR_*; an msid-modbus/1 device reports the same codes). */
const char *msid_can_device_error_name(uint32_t code);

/** @brief Build the CTRL payload (8 bytes). */
void msid_can_encode_ctrl(uint8_t *data, uint32_t cmd, uint32_t experiment, uint32_t periods);
/** @brief Build a STATUS STATE payload. */
void msid_can_encode_state(uint8_t *data, uint32_t state, uint32_t experiment, uint32_t error, uint32_t value);
/** @brief Build a STATUS INFO payload. */
void msid_can_encode_info(uint8_t *data, uint32_t version, uint32_t nu, uint32_t ny, uint32_t cfg_crc);
/** @brief Build a STATUS COUNTERS payload. */
void msid_can_encode_counters(uint8_t *data, uint32_t tec, uint32_t rec, uint32_t restarts, uint32_t tx_dropped);
#ifdef __cplusplus
}
#endif
#endif
