/**
 * @file msid_mb_proto.h
 * @brief msid-modbus/1: the register map shared by the device (firmware_sim/)
 *        and the host (daq/). Pure C11: no OS calls, no heap, no stdio.
 *
 * Holding registers carry the control block (command with a sequence number,
 * experiment, periods), the stream format (encoding, word order) and a
 * parameter mailbox through which the design is uploaded as the msid-can/1
 * CFG parameter records (same parameters, same CRC-32), never as samples.
 * Input registers carry a header (state, write index, segment, period
 * counter, overrun count, ...) and a ring buffer of samples: each sample is
 * a tag (sample index mod 65536) and the channels [u; y] as scaled int16,
 * scaled int32 or float32 in one of the word orders ABCD, CDAB, BADC, DCBA.
 * The full map is docs/modbus-registers.md.
 */
#ifndef MSID_MB_PROTO_H
#define MSID_MB_PROTO_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/** Version of the register map (input register MSID_MB_IR_VERSION). */
#define MSID_MB_PROTO_VERSION 1u
/** Input register 0: 'M' 'S'. */
#define MSID_MB_MAGIC 0x4D53u
/** Registers per read or write request the host uses at most (Modbus allows 125 reads, 123 writes). */
#define MSID_MB_MAX_READ 125u
#define MSID_MB_MAX_WRITE 123u

/** Holding registers (FC 03 read, FC 16 write). */
enum {
    MSID_MB_HR_CMD_SEQ = 0,      /**< a write that changes it executes the command below */
    MSID_MB_HR_CMD = 1,          /**< 1 START, 2 STOP, 3 RESET */
    MSID_MB_HR_CMD_EXP = 2,      /**< experiment of START (0-based) */
    MSID_MB_HR_CMD_PERIODS = 3,  /**< 3-4: periods of START (u32; 0: the configured number) */
    MSID_MB_HR_ENCODING = 8,     /**< stream encoding, latched at COMMIT */
    MSID_MB_HR_WORD_ORDER = 9,   /**< word order, latched at COMMIT */
    MSID_MB_HR_CFG_SEQ = 16,     /**< a write that changes it applies the records below */
    MSID_MB_HR_CFG_COUNT = 17,   /**< records in this block, 1..MSID_MB_CFG_RECORDS */
    MSID_MB_HR_CFG_REC = 18,     /**< records: 4 registers each (the 8 bytes of an msid-can/1 CFG frame) */
    MSID_MB_HR_COUNT = 18 + 4 * 30
};
/** Parameter records per mailbox write (2 + 4 * 30 = 122 registers <= 123). */
#define MSID_MB_CFG_RECORDS 30u

/** Commands. */
enum { MSID_MB_CMD_START = 1, MSID_MB_CMD_STOP = 2, MSID_MB_CMD_RESET = 3 };

/** Encodings. */
enum { MSID_MB_ENC_S16 = 0, MSID_MB_ENC_S32 = 1, MSID_MB_ENC_F32 = 2 };
/** Word orders, as libmodbus names them (A: most significant byte). */
enum { MSID_MB_ABCD = 0, MSID_MB_CDAB = 1, MSID_MB_BADC = 2, MSID_MB_DCBA = 3 };

/** Input registers: the header (FC 04). 32-bit values: high word first. */
enum {
    MSID_MB_IR_MAGIC = 0, MSID_MB_IR_VERSION = 1, MSID_MB_IR_STATE = 2, MSID_MB_IR_EXPERIMENT = 3,
    MSID_MB_IR_ERROR = 4,        /**< error code (msid-can/1 codes) */
    MSID_MB_IR_DETAIL = 5,       /**< error detail (msid_status of a refused design) */
    MSID_MB_IR_NU = 6, MSID_MB_IR_NY = 7,
    MSID_MB_IR_ENCODING = 8, MSID_MB_IR_WORD_ORDER = 9,
    MSID_MB_IR_SAMPLE_REGS = 10, /**< registers per sample: 1 tag + channels */
    MSID_MB_IR_RING_ADDR = 11,   /**< input register of ring slot 0 */
    MSID_MB_IR_RING_SAMPLES = 12,/**< 12-13: ring capacity R in samples */
    MSID_MB_IR_WRITE_INDEX = 14, /**< 14-15: samples written in this run (the next sample's index) */
    MSID_MB_IR_SEG_START = 16,   /**< 16-17: index of the first sample of the current segment */
    MSID_MB_IR_SEGMENT = 18,     /**< segments started in this run, minus 1 (device restarts) */
    MSID_MB_IR_RESTARTS = 19,    /**< device restarts since power-up */
    MSID_MB_IR_OVERRUNS = 20,    /**< 20-21: samples overwritten before the host read them (this run) */
    MSID_MB_IR_PERIOD_COUNT = 22,/**< 22-23: whole periods written in the current segment */
    MSID_MB_IR_TOTAL = 24,       /**< 24-25: samples per segment of this run (K P) */
    MSID_MB_IR_CRC = 26,         /**< 26-27: CRC-32 of the committed configuration (0: none) */
    MSID_MB_IR_PERIOD = 28,      /**< 28-29: P */
    MSID_MB_IR_CMD_DONE = 30,    /**< sequence number of the last executed command */
    MSID_MB_IR_CFG_DONE = 31,    /**< sequence number of the last applied parameter block */
    MSID_MB_IR_CFG_RECORDS = 32, /**< 32-33: parameter records applied since BEGIN */
    MSID_MB_IR_RATE = 34,        /**< 34-35: sample rate in Hz (0: paced by the host's reads) */
    MSID_MB_IR_LINES = 36, MSID_MB_IR_EXPERIMENTS = 37,
    MSID_MB_IR_PERIODS = 38,     /**< 38-39: periods per experiment */
    MSID_MB_IR_HEADER = 40       /**< header registers the host reads */
};
/** First input register of the ring. */
#define MSID_MB_RING_ADDR 64u

/** Device states (as msid-can/1). */
enum {
    MSID_MB_STATE_BOOT = 0, MSID_MB_STATE_IDLE = 1, MSID_MB_STATE_CONFIGURED = 2,
    MSID_MB_STATE_RUNNING = 3, MSID_MB_STATE_DONE = 4, MSID_MB_STATE_ERROR = 5
};

/** The decoded header. */
typedef struct msid_mb_header {
    uint32_t magic, version, state, experiment, error, detail, nu, ny, encoding, word_order;
    uint32_t sample_regs, ring_addr, ring_samples, write_index, seg_start, segment, restarts, overruns;
    uint32_t period_count, total, crc, period, cmd_done, cfg_done, cfg_records, rate, lines, experiments, periods;
} msid_mb_header;

/** @brief Registers per value of an encoding (1 or 2; 0 if unknown). */
uint32_t msid_mb_value_regs(uint32_t encoding);

/** @brief Registers per ring sample: 1 tag + n_channels values. */
uint32_t msid_mb_sample_regs(uint32_t encoding, uint32_t n_channels);

/** @brief Ring capacity in samples for this sample size (the ring fills the input register space). */
uint32_t msid_mb_ring_samples(uint32_t sample_regs);

/** @brief Encode one value into regs (1 or 2 registers). int16/int32: round(v / scale), NaN or out of range as the invalid code. */
void msid_mb_encode_value(uint16_t *regs, double v, uint32_t encoding, uint32_t word_order, double scale);

/** @brief Decode one value (invalid int16/int32 codes decode as NaN). */
double msid_mb_decode_value(const uint16_t *regs, uint32_t encoding, uint32_t word_order, double scale);

/** @brief Store a 32-bit value as two registers, high word first. */
void msid_mb_put_u32(uint16_t *regs, uint32_t v);

/** @brief Read a 32-bit value from two registers, high word first. */
uint32_t msid_mb_get_u32(const uint16_t *regs);

/** @brief Decode MSID_MB_IR_HEADER input registers. */
void msid_mb_header_decode(msid_mb_header *h, const uint16_t *regs);

/** @brief Encode a header into MSID_MB_IR_HEADER registers (device side). */
void msid_mb_header_encode(uint16_t *regs, const msid_mb_header *h);

/** @brief Pack n parameter records (8 bytes each) into 4 n registers, bytes in order, high byte first. */
void msid_mb_pack_records(uint16_t *regs, const uint8_t (*rec)[8], size_t n);

/** @brief Unpack 4 n registers into n parameter records. */
void msid_mb_unpack_records(uint8_t (*rec)[8], const uint16_t *regs, size_t n);

/**
 * @brief Modbus RTU register rate from the line: reads of `regs` registers,
 *        request 8 bytes + reply 5 + 2 regs bytes, `bits_per_char` bits each
 *        (start + 8 data + parity + stop), a 3.5-character silence before each
 *        frame (1.75 ms above 19200 baud, as the standard fixes it).
 * @return registers per second
 */
double msid_mb_rtu_reg_rate(double baud, uint32_t bits_per_char, uint32_t regs);

/** @brief Name of a word order ("ABCD", ...; NULL if unknown). */
const char *msid_mb_word_order_name(uint32_t w);

/** @brief Name of an encoding ("int16", "int32", "float32"; NULL if unknown). */
const char *msid_mb_encoding_name(uint32_t e);

#ifdef __cplusplus
}
#endif
#endif
