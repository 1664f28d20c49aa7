/* msid-can/1 extension estimate/1: EST frame codec (docs/can-protocol.md). */
#include "msid_daq/msid_can_est.h"

#include <string.h>

#include "msid_daq/msid_can_proto.h"

void msid_can_est_encode_state(uint8_t d[8], uint32_t state, uint32_t mode, uint32_t status, uint32_t bad1)
{
    memset(d, 0, 8);
    d[0] = MSID_CAN_EST_MUX_STATE;
    d[1] = (uint8_t)state;
    d[2] = (uint8_t)mode;
    d[3] = MSID_CAN_EST_VERSION;
    d[4] = (uint8_t)status;
    d[5] = (uint8_t)(status >> 8);
    d[6] = (uint8_t)bad1;
    d[7] = (uint8_t)(bad1 >> 8);
}

void msid_can_est_encode_u32(uint8_t d[8], uint32_t mux, uint32_t v)
{
    memset(d, 0, 8);
    d[0] = (uint8_t)mux;
    msid_can_put_u32(d + 4, v);
}

void msid_can_est_encode_value(uint8_t lo[8], uint8_t hi[8], uint32_t index, double v)
{
    uint64_t b;
    memcpy(&b, &v, sizeof b);
    uint8_t *f[2] = {lo, hi};
    for (int w = 0; w < 2; ++w) {
        f[w][0] = (uint8_t)(w ? MSID_CAN_EST_MUX_HI : MSID_CAN_EST_MUX_LO);
        f[w][1] = (uint8_t)index;
        f[w][2] = (uint8_t)(index >> 8);
        f[w][3] = (uint8_t)(index >> 16);
        msid_can_put_u32(f[w] + 4, (uint32_t)(b >> (32 * w)));
    }
}

int msid_can_est_collect(const uint8_t d[8], double *vals, uint8_t *have, uint32_t n)
{
    if (d[0] != MSID_CAN_EST_MUX_LO && d[0] != MSID_CAN_EST_MUX_HI) return 0;
    const uint32_t k = (uint32_t)d[1] | (uint32_t)d[2] << 8 | (uint32_t)d[3] << 16;
    if (k >= n) return 0;
    const int w = d[0] == MSID_CAN_EST_MUX_HI;
    uint64_t b;
    memcpy(&b, &vals[k], sizeof b);
    const uint64_t word = msid_can_get_u32(d + 4);
    b = w ? (b & 0xFFFFFFFFull) | word << 32 : (b & ~0xFFFFFFFFull) | word;
    memcpy(&vals[k], &b, sizeof b);
    have[k] |= (uint8_t)(1u << w);
    return 1;
}

int msid_can_est_update(msid_can_est_view *v, const uint8_t d[8])
{
    const uint32_t w = msid_can_get_u32(d + 4);
    switch (d[0]) {
    case MSID_CAN_EST_MUX_STATE:
        v->states++;
        v->state = d[1];
        v->mode = d[2];
        v->version = d[3];
        v->status = (uint32_t)d[4] | (uint32_t)d[5] << 8;
        v->bad1 = (uint32_t)d[6] | (uint32_t)d[7] << 8;
        break;
    case MSID_CAN_EST_MUX_NEED: v->need = w; break;
    case MSID_CAN_EST_MUX_HAVE: v->have = w; break;
    case MSID_CAN_EST_MUX_SIZE: v->size = w; break;
    case MSID_CAN_EST_MUX_PERIODS:
        v->periods = w;
        v->answers++;
        break;
    default:
        return -1;
    }
    return d[0];
}
