/* msid-modbus/1 register map: value codecs, header, parameter records, RTU line rate. */
#include "msid_daq/msid_mb_proto.h"

#include <math.h>
#include <string.h>

uint32_t msid_mb_value_regs(uint32_t e)
{
    return e == MSID_MB_ENC_S16 ? 1u : (e == MSID_MB_ENC_S32 || e == MSID_MB_ENC_F32) ? 2u : 0u;
}

uint32_t msid_mb_sample_regs(uint32_t e, uint32_t n) { return 1u + n * msid_mb_value_regs(e); }

uint32_t msid_mb_ring_samples(uint32_t sample_regs)
{
    return sample_regs ? (65536u - MSID_MB_RING_ADDR) / sample_regs : 0u;
}

/* bytes A B C D (A most significant) <-> two registers in word order w */
static void put4(uint16_t *r, uint32_t v, uint32_t w)
{
    const uint16_t hi = (uint16_t)(v >> 16), lo = (uint16_t)v;
    const uint16_t shi = (uint16_t)(hi << 8 | hi >> 8), slo = (uint16_t)(lo << 8 | lo >> 8);
    switch (w) {
    case MSID_MB_CDAB: r[0] = lo; r[1] = hi; break;
    case MSID_MB_BADC: r[0] = shi; r[1] = slo; break;
    case MSID_MB_DCBA: r[0] = slo; r[1] = shi; break;
    default: r[0] = hi; r[1] = lo; break;
    }
}

static uint32_t get4(const uint16_t *r, uint32_t w)
{
    uint16_t hi, lo;
    switch (w) {
    case MSID_MB_CDAB: hi = r[1]; lo = r[0]; break;
    case MSID_MB_BADC: hi = (uint16_t)(r[0] << 8 | r[0] >> 8); lo = (uint16_t)(r[1] << 8 | r[1] >> 8); break;
    case MSID_MB_DCBA: hi = (uint16_t)(r[1] << 8 | r[1] >> 8); lo = (uint16_t)(r[0] << 8 | r[0] >> 8); break;
    default: hi = r[0]; lo = r[1]; break;
    }
    return (uint32_t)hi << 16 | lo;
}

/* int16 is "AB" in ABCD/CDAB and "BA" in BADC/DCBA (byte-swapped orders). */
static int swapped16(uint32_t w) { return w == MSID_MB_BADC || w == MSID_MB_DCBA; }

void msid_mb_encode_value(uint16_t *r, double v, uint32_t e, uint32_t w, double scale)
{
    if (e == MSID_MB_ENC_F32) {
        const float f = (float)v;
        uint32_t u;
        memcpy(&u, &f, 4);
        put4(r, u, w);
    } else if (e == MSID_MB_ENC_S32) {
        const double q = nearbyint(v / scale);
        const int32_t x = (isfinite(q) && q > -2147483648.0 && q <= 2147483647.0) ? (int32_t)q : INT32_MIN;
        put4(r, (uint32_t)x, w);
    } else {
        const double q = nearbyint(v / scale);
        const int16_t x = (isfinite(q) && q > -32768.0 && q <= 32767.0) ? (int16_t)q : INT16_MIN;
        const uint16_t u = (uint16_t)x;
        r[0] = swapped16(w) ? (uint16_t)(u << 8 | u >> 8) : u;
    }
}

double msid_mb_decode_value(const uint16_t *r, uint32_t e, uint32_t w, double scale)
{
    if (e == MSID_MB_ENC_F32) {
        const uint32_t u = get4(r, w);
        float f;
        memcpy(&f, &u, 4);
        return (double)f;
    }
    if (e == MSID_MB_ENC_S32) {
        const int32_t x = (int32_t)get4(r, w);
        return x == INT32_MIN ? NAN : (double)x * scale;
    }
    const uint16_t u = swapped16(w) ? (uint16_t)(r[0] << 8 | r[0] >> 8) : r[0];
    const int16_t x = (int16_t)u;
    return x == INT16_MIN ? NAN : (double)x * scale;
}

void msid_mb_put_u32(uint16_t *r, uint32_t v)
{
    r[0] = (uint16_t)(v >> 16);
    r[1] = (uint16_t)v;
}

uint32_t msid_mb_get_u32(const uint16_t *r) { return (uint32_t)r[0] << 16 | r[1]; }

/* Header fields in register order: (offset, 32-bit?) */
#define HDR_FIELDS(X)                                                                                               \
    X(magic, MSID_MB_IR_MAGIC, 0) X(version, MSID_MB_IR_VERSION, 0) X(state, MSID_MB_IR_STATE, 0)                   \
    X(experiment, MSID_MB_IR_EXPERIMENT, 0) X(error, MSID_MB_IR_ERROR, 0) X(detail, MSID_MB_IR_DETAIL, 0)           \
    X(nu, MSID_MB_IR_NU, 0) X(ny, MSID_MB_IR_NY, 0) X(encoding, MSID_MB_IR_ENCODING, 0)                             \
    X(word_order, MSID_MB_IR_WORD_ORDER, 0) X(sample_regs, MSID_MB_IR_SAMPLE_REGS, 0)                               \
    X(ring_addr, MSID_MB_IR_RING_ADDR, 0) X(ring_samples, MSID_MB_IR_RING_SAMPLES, 1)                               \
    X(write_index, MSID_MB_IR_WRITE_INDEX, 1) X(seg_start, MSID_MB_IR_SEG_START, 1)                                 \
    X(segment, MSID_MB_IR_SEGMENT, 0) X(restarts, MSID_MB_IR_RESTARTS, 0) X(overruns, MSID_MB_IR_OVERRUNS, 1)       \
    X(period_count, MSID_MB_IR_PERIOD_COUNT, 1) X(total, MSID_MB_IR_TOTAL, 1) X(crc, MSID_MB_IR_CRC, 1)             \
    X(period, MSID_MB_IR_PERIOD, 1) X(cmd_done, MSID_MB_IR_CMD_DONE, 0) X(cfg_done, MSID_MB_IR_CFG_DONE, 0)         \
    X(cfg_records, MSID_MB_IR_CFG_RECORDS, 1) X(rate, MSID_MB_IR_RATE, 1) X(lines, MSID_MB_IR_LINES, 0)             \
    X(experiments, MSID_MB_IR_EXPERIMENTS, 0) X(periods, MSID_MB_IR_PERIODS, 1)

void msid_mb_header_decode(msid_mb_header *h, const uint16_t *r)
{
#define X(f, a, wide) h->f = (wide) ? msid_mb_get_u32(r + (a)) : r[a];
    HDR_FIELDS(X)
#undef X
}

void msid_mb_header_encode(uint16_t *r, const msid_mb_header *h)
{
    memset(r, 0, sizeof(uint16_t) * MSID_MB_IR_HEADER);
#define X(f, a, wide) if (wide) msid_mb_put_u32(r + (a), h->f); else r[a] = (uint16_t)h->f;
    HDR_FIELDS(X)
#undef X
}

void msid_mb_pack_records(uint16_t *r, const uint8_t (*rec)[8], size_t n)
{
    for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < 4; ++k) r[4 * i + k] = (uint16_t)(rec[i][2 * k] << 8 | rec[i][2 * k + 1]);
}

void msid_mb_unpack_records(uint8_t (*rec)[8], const uint16_t *r, size_t n)
{
    for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < 4; ++k) {
            rec[i][2 * k] = (uint8_t)(r[4 * i + k] >> 8);
            rec[i][2 * k + 1] = (uint8_t)r[4 * i + k];
        }
}

double msid_mb_rtu_reg_rate(double baud, uint32_t bits_per_char, uint32_t regs)
{
    if (!(baud > 0) || regs == 0) return 0;
    const double tc = bits_per_char / baud;                  /* one character */
    const double gap = baud > 19200 ? 1.75e-3 : 3.5 * tc;    /* t3.5 before each frame */
    const double t = (8.0 + 5.0 + 2.0 * regs) * tc + 2 * gap;
    return regs / t;
}

const char *msid_mb_word_order_name(uint32_t w)
{
    static const char *const n[4] = {"ABCD", "CDAB", "BADC", "DCBA"};
    return w < 4 ? n[w] : NULL;
}

const char *msid_mb_encoding_name(uint32_t e)
{
    static const char *const n[3] = {"int16", "int32", "float32"};
    return e < 3 ? n[e] : NULL;
}
