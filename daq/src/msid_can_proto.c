/* msid-can/1 frame layout: encode and decode (no OS, no heap). */
#include "msid_daq/msid_can_proto.h"

#include <math.h>
#include <string.h>

void msid_can_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

uint32_t msid_can_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint32_t msid_can_chunk_channels(uint32_t encoding, uint32_t fd)
{
    if (fd) return encoding == MSID_CAN_ENC_F32 ? 15u : 30u;
    return encoding == MSID_CAN_ENC_F32 ? 1u : 2u;
}

uint32_t msid_can_sample_len(uint32_t fd) { return fd ? 64u : 8u; }

uint32_t msid_can_chunks(uint32_t n_channels, uint32_t encoding, uint32_t fd)
{
    const uint32_t k = msid_can_chunk_channels(encoding, fd);
    return (n_channels + k - 1) / k;
}

uint32_t msid_can_chunk_id(uint32_t encoding, uint32_t fd, uint32_t k)
{
    if (fd) return (encoding == MSID_CAN_ENC_F32 ? MSID_CAN_ID_FD_F32 : MSID_CAN_ID_FD_S16) + k;
    return (encoding == MSID_CAN_ENC_F32 ? MSID_CAN_ID_F32 : MSID_CAN_ID_S16) + k;
}

int msid_can_classify_sample(uint32_t off, uint32_t *encoding, uint32_t *fd, uint32_t *chunk)
{
    uint32_t e, f, k;
    if (off >= MSID_CAN_ID_S16 && off < MSID_CAN_ID_S16 + 16) { e = MSID_CAN_ENC_S16; f = 0; k = off - MSID_CAN_ID_S16; }
    else if (off >= MSID_CAN_ID_F32 && off < MSID_CAN_ID_F32 + 32) { e = MSID_CAN_ENC_F32; f = 0; k = off - MSID_CAN_ID_F32; }
    else if (off >= MSID_CAN_ID_FD_S16 && off < MSID_CAN_ID_FD_S16 + 2) { e = MSID_CAN_ENC_S16; f = 1; k = off - MSID_CAN_ID_FD_S16; }
    else if (off >= MSID_CAN_ID_FD_F32 && off < MSID_CAN_ID_FD_F32 + 3) { e = MSID_CAN_ENC_F32; f = 1; k = off - MSID_CAN_ID_FD_F32; }
    else return 0;
    *encoding = e; *fd = f; *chunk = k;
    return 1;
}

uint32_t msid_can_crc32(uint32_t crc, const uint8_t *p, size_t n)
{
    crc = ~crc;
    for (size_t i = 0; i < n; ++i) {
        crc ^= p[i];
        for (int b = 0; b < 8; ++b) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

static int16_t quantize(double x, double scale)
{
    if (!(x == x) || !(scale > 0)) return MSID_CAN_S16_INVALID;
    const double q = x / scale;
    if (!(q > -32767.5 && q < 32767.5)) return MSID_CAN_S16_INVALID;   /* out of range or NaN */
    return (int16_t)lrint(q);
}

void msid_can_encode_sample(uint8_t *data, uint32_t encoding, uint32_t fd, uint32_t k, uint32_t seq,
                            uint32_t experiment, uint32_t flags, const double *row, uint32_t n_channels,
                            double scale)
{
    const uint32_t len = msid_can_sample_len(fd), per = msid_can_chunk_channels(encoding, fd);
    memset(data, 0, len);
    data[0] = (uint8_t)seq; data[1] = (uint8_t)(seq >> 8); data[2] = (uint8_t)(seq >> 16);
    data[3] = (uint8_t)((experiment & MSID_CAN_EXP_MASK) | (flags & (MSID_CAN_PSTART | MSID_CAN_SEGSTART)));
    for (uint32_t j = 0; j < per; ++j) {
        const uint32_t c = k * per + j;
        if (c >= n_channels) break;
        if (encoding == MSID_CAN_ENC_F32) {
            const float v = (float)row[c];
            uint32_t w;
            memcpy(&w, &v, 4);
            msid_can_put_u32(data + 4 + 4 * j, w);
        } else {
            const uint16_t w = (uint16_t)quantize(row[c], scale);
            data[4 + 2 * j] = (uint8_t)w;
            data[5 + 2 * j] = (uint8_t)(w >> 8);
        }
    }
}

void msid_can_decode_values(const uint8_t *data, uint32_t encoding, uint32_t fd, uint32_t k, double *row,
                            uint32_t n_channels, double scale)
{
    const uint32_t per = msid_can_chunk_channels(encoding, fd);
    for (uint32_t j = 0; j < per; ++j) {
        const uint32_t c = k * per + j;
        if (c >= n_channels) break;
        if (encoding == MSID_CAN_ENC_F32) {
            const uint32_t w = msid_can_get_u32(data + 4 + 4 * j);
            float v;
            memcpy(&v, &w, 4);
            row[c] = (double)v;
        } else {
            const int16_t v = (int16_t)(uint16_t)(data[4 + 2 * j] | data[5 + 2 * j] << 8);
            row[c] = v == MSID_CAN_S16_INVALID ? NAN : (double)v * scale;
        }
    }
}

void msid_can_encode_ctrl(uint8_t *d, uint32_t cmd, uint32_t experiment, uint32_t periods)
{
    d[0] = (uint8_t)cmd; d[1] = (uint8_t)experiment; d[2] = (uint8_t)MSID_CAN_PROTO_VERSION; d[3] = 0;
    msid_can_put_u32(d + 4, periods);
}

void msid_can_encode_state(uint8_t *d, uint32_t state, uint32_t experiment, uint32_t error, uint32_t value)
{
    d[0] = MSID_CAN_ST_STATE; d[1] = (uint8_t)state; d[2] = (uint8_t)experiment; d[3] = (uint8_t)error;
    msid_can_put_u32(d + 4, value);
}

void msid_can_encode_info(uint8_t *d, uint32_t version, uint32_t nu, uint32_t ny, uint32_t cfg_crc)
{
    d[0] = MSID_CAN_ST_INFO; d[1] = (uint8_t)version; d[2] = (uint8_t)nu; d[3] = (uint8_t)ny;
    msid_can_put_u32(d + 4, cfg_crc);
}

void msid_can_encode_counters(uint8_t *d, uint32_t tec, uint32_t rec, uint32_t restarts, uint32_t tx_dropped)
{
    d[0] = MSID_CAN_ST_COUNTERS;
    d[1] = (uint8_t)(tec > 255 ? 255 : tec);
    d[2] = (uint8_t)(rec > 255 ? 255 : rec);
    d[3] = (uint8_t)(restarts > 255 ? 255 : restarts);
    msid_can_put_u32(d + 4, tx_dropped);
}

const char *msid_can_device_error_name(uint32_t code)
{
    switch (code) {
    case MSID_CAN_ERR_VERSION: return "protocol version mismatch";
    case MSID_CAN_ERR_CRC: return "configuration CRC mismatch (a CFG frame was lost)";
    case MSID_CAN_ERR_DESIGN: return "the device refused the design";
    case MSID_CAN_ERR_NOT_CONFIGURED: return "the device is not configured";
    case MSID_CAN_ERR_EXPERIMENT: return "experiment index out of range";
    case MSID_CAN_ERR_DIMS: return "the design's inputs do not match the device";
    case MSID_CAN_ERR_CFG: return "malformed or unsupported configuration";
    default: return "unknown device error";
    }
}
