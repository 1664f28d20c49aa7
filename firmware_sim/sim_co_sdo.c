/* SDO server of the simulated CANopen node (CiA 301 7.2.4). */
#include "sim_co_sdo.h"

#include <string.h>

void sim_co_sdo_init(sim_co_sdo_srv *s, sim_co_od *od, unsigned node, sim_co_sdo_write_fn on_write,
                     sim_co_sdo_read_fn on_read, void *ctx)
{
    memset(s, 0, sizeof *s);
    s->od = od;
    s->node = (uint8_t)node;
    s->on_write = on_write;
    s->on_read = on_read;
    s->ctx = ctx;
}

static void answer(const sim_co_sdo_srv *s, msid_can_frame *r, uint8_t cmd, uint16_t index, uint8_t sub)
{
    memset(r, 0, sizeof *r);
    r->id = 0x580u + s->node;
    r->len = 8;
    r->data[0] = cmd;
    r->data[1] = (uint8_t)index, r->data[2] = (uint8_t)(index >> 8), r->data[3] = sub;
}

static int abort_with(sim_co_sdo_srv *s, msid_can_frame *r, uint16_t index, uint8_t sub, uint32_t code)
{
    answer(s, r, 0x80, index, sub);
    for (int i = 0; i < 4; ++i) r->data[4 + i] = (uint8_t)(code >> (8 * i));
    s->state = 0;
    s->aborts_sent++;
    return 1;
}

/* Store a complete download after every check; 0 or the abort code. */
static uint32_t write_value(sim_co_sdo_srv *s, uint16_t index, uint8_t sub, const uint8_t *data, size_t len)
{
    const uint32_t a = sim_co_od_check_write(s->od, index, sub, len);
    if (a) return a;
    sim_co_var *v = sim_co_od_find(s->od, index, sub);
    return s->on_write(s->ctx, v, data, len);
}

static int initiate_download(sim_co_sdo_srv *s, const uint8_t *d, msid_can_frame *r, uint16_t index, uint8_t sub,
                             uint64_t now_ms)
{
    const int expedited = d[0] & 0x02, sized = d[0] & 0x01;
    if (expedited) {
        size_t len = sized ? 4u - ((d[0] >> 2) & 3u) : 4u;
        if (!sized) {
            /* size not indicated: the entry's own, if 1..4 bytes */
            const sim_co_var *v = sim_co_od_find(s->od, index, sub);
            if (v && v->size && v->size <= 4) len = v->size;
        }
        const uint32_t a = write_value(s, index, sub, &d[4], len);
        if (a) return abort_with(s, r, index, sub, a);
        answer(s, r, 0x60, index, sub);
        return 1;
    }
    const uint32_t size = sized ? (uint32_t)d[4] | (uint32_t)d[5] << 8 | (uint32_t)d[6] << 16 | (uint32_t)d[7] << 24
                                : UINT32_MAX;
    /* what can be refused before the data: a missing or read-only entry, a size that cannot fit */
    uint32_t a = sim_co_od_check_write(s->od, index, sub, sized ? size : 0);
    if (a == SIM_CO_ABORT_TOO_LOW && !sized) a = 0;
    if (a == SIM_CO_ABORT_TOO_HIGH && !sized) a = 0;
    if (a) return abort_with(s, r, index, sub, a);
    s->state = 1, s->index = index, s->sub = sub, s->toggle = 0, s->len = 0, s->size = size, s->last_ms = now_ms;
    answer(s, r, 0x60, index, sub);
    return 1;
}

static int download_segment(sim_co_sdo_srv *s, const uint8_t *d, msid_can_frame *r, uint64_t now_ms)
{
    if (((d[0] >> 4) & 1u) != s->toggle) return abort_with(s, r, s->index, s->sub, SIM_CO_ABORT_TOGGLE);
    const uint32_t n = 7u - ((d[0] >> 1) & 7u);
    if (s->len + n > sizeof s->buf) return abort_with(s, r, s->index, s->sub, SIM_CO_ABORT_TOO_HIGH);
    memcpy(&s->buf[s->len], &d[1], n);
    s->len += n;
    s->last_ms = now_ms;
    const uint8_t t = s->toggle;
    s->toggle ^= 1u;
    if (d[0] & 0x01u) {
        if (s->size != UINT32_MAX && s->len != s->size)
            return abort_with(s, r, s->index, s->sub, s->len > s->size ? SIM_CO_ABORT_TOO_HIGH : SIM_CO_ABORT_TOO_LOW);
        const uint32_t a = write_value(s, s->index, s->sub, s->buf, s->len);
        if (a) return abort_with(s, r, s->index, s->sub, a);
        s->state = 0;
    }
    memset(r, 0, sizeof *r);
    r->id = 0x580u + s->node;
    r->len = 8;
    r->data[0] = (uint8_t)(0x20u | t << 4);
    return 1;
}

static int initiate_upload(sim_co_sdo_srv *s, msid_can_frame *r, uint16_t index, uint8_t sub, uint64_t now_ms)
{
    uint32_t a = sim_co_od_check_read(s->od, index, sub);
    const sim_co_var *v = a ? NULL : sim_co_od_find(s->od, index, sub);
    if (!a && s->on_read) a = s->on_read(s->ctx, v);
    if (a) return abort_with(s, r, index, sub, a);
    size_t len;
    const uint8_t *b = sim_co_od_bytes(s->od, v, &len);
    if (len >= 1 && len <= 4) {
        answer(s, r, (uint8_t)(0x43u | (4u - len) << 2), index, sub);
        memcpy(&r->data[4], b, len);
        return 1;
    }
    memcpy(s->buf, b, len);
    s->state = 2, s->index = index, s->sub = sub, s->toggle = 0, s->len = (uint32_t)len, s->pos = 0;
    s->last_ms = now_ms;
    answer(s, r, 0x41, index, sub);
    for (int i = 0; i < 4; ++i) r->data[4 + i] = (uint8_t)(len >> (8 * i));
    return 1;
}

static int upload_segment(sim_co_sdo_srv *s, const uint8_t *d, msid_can_frame *r, uint64_t now_ms)
{
    if (((d[0] >> 4) & 1u) != s->toggle) return abort_with(s, r, s->index, s->sub, SIM_CO_ABORT_TOGGLE);
    uint32_t n = s->len - s->pos;
    if (n > 7) n = 7;
    const int last = s->pos + n == s->len;
    memset(r, 0, sizeof *r);
    r->id = 0x580u + s->node;
    r->len = 8;
    r->data[0] = (uint8_t)(s->toggle << 4 | (7u - n) << 1 | (last ? 1u : 0u));
    memcpy(&r->data[1], &s->buf[s->pos], n);
    s->pos += n;
    s->toggle ^= 1u;
    s->last_ms = now_ms;
    if (last) s->state = 0;
    return 1;
}

int sim_co_sdo_rx(sim_co_sdo_srv *s, const msid_can_frame *req, msid_can_frame *resp, uint64_t now_ms)
{
    uint8_t d[8] = {0};
    memcpy(d, req->data, req->len < 8 ? req->len : 8);
    const uint16_t index = (uint16_t)(d[1] | d[2] << 8);
    const uint8_t sub = d[3];
    const unsigned ccs = d[0] >> 5;
    if (req->len != 8) {
        /* CiA 301 SDO frames are 8 bytes; a shorter one is no command the server knows */
        return abort_with(s, resp, s->state ? s->index : index, s->state ? s->sub : sub, SIM_CO_ABORT_COMMAND);
    }
    if (ccs == 4) { s->state = 0; return 0; }   /* the client aborted */
    switch (ccs) {
    case 1: s->state = 0; return initiate_download(s, d, resp, index, sub, now_ms);
    case 2: s->state = 0; return initiate_upload(s, resp, index, sub, now_ms);
    case 0:
        if (s->state != 1) return abort_with(s, resp, s->index, s->sub, SIM_CO_ABORT_COMMAND);
        return download_segment(s, d, resp, now_ms);
    case 3:
        if (s->state != 2) return abort_with(s, resp, s->index, s->sub, SIM_CO_ABORT_COMMAND);
        return upload_segment(s, d, resp, now_ms);
    default:
        return abort_with(s, resp, s->state ? s->index : index, s->state ? s->sub : sub, SIM_CO_ABORT_COMMAND);
    }
}

int sim_co_sdo_poll(sim_co_sdo_srv *s, msid_can_frame *resp, uint64_t now_ms)
{
    if (!s->state || now_ms - s->last_ms < SIM_CO_SDO_TIMEOUT_MS) return 0;
    return abort_with(s, resp, s->index, s->sub, SIM_CO_ABORT_TIMEOUT);
}
