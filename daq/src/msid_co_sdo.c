/* CANopen SDO client (CiA 301 7.2.4): expedited and segmented transfers, one request and one response at
   a time. The steps: build a request, await the node's response (other frames handed on), check its
   command, copy the data; any failure after the first request is ended by an abort frame, unless the node
   aborted itself or the link failed. */
#include "msid_daq/msid_co_sdo.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* command specifiers (byte 0, bits 7..5) */
#define CCS_DOWNLOAD_SEGMENT 0u
#define CCS_INITIATE_DOWNLOAD 1u
#define CCS_INITIATE_UPLOAD 2u
#define CCS_UPLOAD_SEGMENT 3u
#define SCS_UPLOAD_SEGMENT 0u
#define SCS_DOWNLOAD_SEGMENT 1u
#define SCS_INITIATE_UPLOAD 2u
#define SCS_INITIATE_DOWNLOAD 3u
#define CS_ABORT 4u

#define SEGMENT_BYTES 7u
#define EXPEDITED_BYTES 4u

/* one transfer's state */
typedef struct xfer {
    msid_co_sdo *s;
    uint16_t index;
    uint8_t sub;
    const char *what;  /* "upload" or "download" */
} xfer;

static void put_le32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t get_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void request_frame(const xfer *x, msid_can_frame *f, uint8_t cmd)
{
    memset(f, 0, sizeof *f);
    f->id = MSID_CO_COB_SDO_RX + x->s->node;
    f->len = 8;
    f->data[0] = cmd;
}

/* the multiplexer (index, subindex) of an initiate request or an abort */
static void put_mux(const xfer *x, msid_can_frame *f)
{
    f->data[1] = (uint8_t)(x->index & 0xFFu);
    f->data[2] = (uint8_t)(x->index >> 8);
    f->data[3] = x->sub;
}

static int send_frame(const xfer *x, const msid_can_frame *f)
{
    const int rc = x->s->io.send(x->s->io.ctx, f);
    if (rc < 0)
        snprintf(x->s->err, sizeof x->s->err, "SDO %s of 0x%04X:%02X on node %u: cannot send: %s", x->what,
                 (unsigned)x->index, (unsigned)x->sub, (unsigned)x->s->node, msid_daq_message(rc));
    return rc < 0 ? rc : 0;
}

/* msid ends the transfer with an abort naming why; rc is what the caller returns */
static int client_abort(const xfer *x, uint32_t code, int rc)
{
    msid_can_frame f;
    request_frame(x, &f, (uint8_t)(CS_ABORT << 5));
    put_mux(x, &f);
    put_le32(&f.data[4], code);
    x->s->abort_code = code;
    x->s->abort_by_node = 0;
    (void)x->s->io.send(x->s->io.ctx, &f);  /* the error already named is the one reported */
    return rc;
}

static int fail(const xfer *x, uint32_t code, int rc, const char *why)
{
    snprintf(x->s->err, sizeof x->s->err, "SDO %s of 0x%04X:%02X on node %u: %s (aborted: %s)", x->what,
             (unsigned)x->index, (unsigned)x->sub, (unsigned)x->s->node, why, msid_co_abort_name(code));
    return client_abort(x, code, rc);
}

static int is_response(const msid_co_sdo *s, const msid_can_frame *f)
{
    return (f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) == 0 && !(f->flags & MSID_CANF_FD) &&
           f->id == MSID_CO_COB_SDO_TX + s->node;
}

/* Await the node's response within the timeout, handing other frames on; an abort from the node ends it. */
static int await_response(const xfer *x, msid_can_frame *f)
{
    msid_co_sdo *s = x->s;
    const uint64_t deadline = msid_co_now_ms(&s->io) + (uint64_t)s->timeout_ms;
    for (;;) {
        const uint64_t now = msid_co_now_ms(&s->io);
        int rc = now >= deadline ? -MSID_DAQ_E_TIMEOUT : s->io.recv(s->io.ctx, f, (int)(deadline - now));
        if (rc == -MSID_DAQ_E_TIMEOUT) {
            char why[64];
            snprintf(why, sizeof why, "no response within %d ms", s->timeout_ms);
            return fail(x, MSID_CO_ABORT_TIMEOUT, -MSID_DAQ_E_TIMEOUT, why);
        }
        if (rc < 0) {
            snprintf(s->err, sizeof s->err, "SDO %s of 0x%04X:%02X on node %u: %s", x->what, (unsigned)x->index,
                     (unsigned)x->sub, (unsigned)s->node, msid_daq_message(rc));
            return rc;
        }
        if (!is_response(s, f)) {
            if (s->io.other) s->io.other(s->io.ctx, f);
            continue;
        }
        if (f->len != 8) {
            char why[64];
            snprintf(why, sizeof why, "a response of %u bytes (CiA 301: 8)", (unsigned)f->len);
            return fail(x, MSID_CO_ABORT_GENERAL, -MSID_DAQ_E_PROTOCOL, why);
        }
        if ((f->data[0] >> 5) == CS_ABORT) {
            s->abort_code = get_le32(&f->data[4]);
            s->abort_by_node = 1;
            snprintf(s->err, sizeof s->err, "SDO %s of 0x%04X:%02X on node %u: the node aborted with 0x%08X: %s",
                     x->what, (unsigned)x->index, (unsigned)x->sub, (unsigned)s->node, (unsigned)s->abort_code,
                     msid_co_abort_name(s->abort_code));
            return -MSID_DAQ_E_DEVICE;
        }
        return 0;
    }
}

/* An initiate response must name the entry requested. */
static int check_mux(const xfer *x, const msid_can_frame *f)
{
    const unsigned index = (unsigned)f->data[1] | (unsigned)f->data[2] << 8;
    if (index == x->index && f->data[3] == x->sub) return 0;
    char why[80];
    snprintf(why, sizeof why, "the response names 0x%04X:%02X", index, (unsigned)f->data[3]);
    return fail(x, MSID_CO_ABORT_GENERAL, -MSID_DAQ_E_PROTOCOL, why);
}

static int wrong_command(const xfer *x, const msid_can_frame *f, const char *expected)
{
    char why[96];
    snprintf(why, sizeof why, "command byte 0x%02X where %s was due", (unsigned)f->data[0], expected);
    return fail(x, MSID_CO_ABORT_COMMAND, -MSID_DAQ_E_PROTOCOL, why);
}

/* Send an initiate request (f holds its command and data) and take the node's response into f: it must
   answer with command specifier scs for this entry. */
static int initiate(const xfer *x, msid_can_frame *f, unsigned scs, const char *expected)
{
    put_mux(x, f);
    int rc = send_frame(x, f);
    if (rc < 0) return rc;
    if ((rc = await_response(x, f)) < 0) return rc;
    if ((f->data[0] >> 5) != scs) return wrong_command(x, f, expected);
    return check_mux(x, f);
}

/* Send a segment request (f) and take the node's segment response into f: command specifier scs, the
   same toggle bit. */
static int exchange_segment(const xfer *x, msid_can_frame *f, unsigned scs, unsigned toggle, const char *expected)
{
    int rc = send_frame(x, f);
    if (rc < 0) return rc;
    if ((rc = await_response(x, f)) < 0) return rc;
    if ((f->data[0] >> 5) != scs) return wrong_command(x, f, expected);
    if (((f->data[0] >> 4) & 1u) != toggle) return fail(x, MSID_CO_ABORT_TOGGLE, -MSID_DAQ_E_PROTOCOL, "toggle bit not alternated");
    return 0;
}

static int begin(xfer *x, msid_co_sdo *s, uint16_t index, uint8_t sub, const char *what)
{
    x->s = s;
    x->index = index;
    x->sub = sub;
    x->what = what;
    if (!s) return -MSID_DAQ_E_ARG;
    s->err[0] = '\0';
    s->abort_code = 0;
    s->abort_by_node = 0;
    return 0;
}

/* ---- upload ---- */

static int upload_segments(const xfer *x, uint8_t *buf, size_t cap, size_t *len, int size_known, uint32_t size)
{
    size_t got = 0;
    for (unsigned toggle = 0;; toggle ^= 1u) {
        msid_can_frame f;
        request_frame(x, &f, (uint8_t)(CCS_UPLOAD_SEGMENT << 5 | toggle << 4));
        const int rc = exchange_segment(x, &f, SCS_UPLOAD_SEGMENT, toggle, "an upload segment");
        if (rc < 0) return rc;
        const size_t n = SEGMENT_BYTES - ((f.data[0] >> 1) & 7u);
        const int last = f.data[0] & 1u;
        if (got + n > cap) {
            char why[96];
            snprintf(why, sizeof why, "the entry holds more than the %zu bytes the caller has room for", cap);
            return fail(x, MSID_CO_ABORT_MEMORY, -MSID_DAQ_E_RANGE, why);
        }
        memcpy(buf + got, &f.data[1], n);
        got += n;
        if (size_known && got > size) break;
        if (last) break;
    }
    if (size_known && got != size) {
        char why[96];
        snprintf(why, sizeof why, "%zu bytes sent where the node announced %u", got, (unsigned)size);
        return fail(x, MSID_CO_ABORT_GENERAL, -MSID_DAQ_E_PROTOCOL, why);
    }
    *len = got;
    return 0;
}

int msid_co_sdo_upload(msid_co_sdo *s, uint16_t index, uint8_t sub, void *buf, size_t cap, size_t *len)
{
    xfer x;
    if (begin(&x, s, index, sub, "upload") < 0) return -MSID_DAQ_E_ARG;
    if (!len || (!buf && cap)) {
        snprintf(s->err, sizeof s->err, "SDO upload of 0x%04X:%02X: no buffer", (unsigned)index, (unsigned)sub);
        return -MSID_DAQ_E_ARG;
    }
    msid_can_frame f;
    request_frame(&x, &f, (uint8_t)(CCS_INITIATE_UPLOAD << 5));
    const int rc = initiate(&x, &f, SCS_INITIATE_UPLOAD, "an initiate upload response");
    if (rc < 0) return rc;
    const int expedited = (f.data[0] >> 1) & 1u, size_known = f.data[0] & 1u;
    if (expedited) {
        const size_t n = size_known ? EXPEDITED_BYTES - ((f.data[0] >> 2) & 3u) : EXPEDITED_BYTES;
        if (n > cap) {
            char why[96];
            snprintf(why, sizeof why, "the entry's %zu bytes exceed the %zu the caller has room for", n, cap);
            return fail(&x, MSID_CO_ABORT_MEMORY, -MSID_DAQ_E_RANGE, why);
        }
        memcpy(buf, &f.data[4], n);
        *len = n;
        return 0;
    }
    const uint32_t size = get_le32(&f.data[4]);
    if (size_known && size > cap) {
        char why[96];
        snprintf(why, sizeof why, "the entry's %u bytes exceed the %zu the caller has room for", (unsigned)size, cap);
        return fail(&x, MSID_CO_ABORT_MEMORY, -MSID_DAQ_E_RANGE, why);
    }
    return upload_segments(&x, (uint8_t *)buf, cap, len, size_known, size);
}

/* ---- download ---- */

static int download_segments(const xfer *x, const uint8_t *data, size_t len)
{
    size_t sent = 0;
    unsigned toggle = 0;
    do {
        const size_t n = len - sent < SEGMENT_BYTES ? len - sent : SEGMENT_BYTES;
        const unsigned last = sent + n == len;
        msid_can_frame f;
        request_frame(x, &f, (uint8_t)(CCS_DOWNLOAD_SEGMENT << 5 | toggle << 4 | (SEGMENT_BYTES - n) << 1 | last));
        if (n) memcpy(&f.data[1], data + sent, n);
        const int rc = exchange_segment(x, &f, SCS_DOWNLOAD_SEGMENT, toggle, "a download segment response");
        if (rc < 0) return rc;
        sent += n;
        toggle ^= 1u;
    } while (sent < len);
    return 0;
}

/* An SDO's size field holds 32 bits; a size_t of 32 bits always fits it (the test would be always false there). */
static int beyond_size_field(size_t len)
{
#if SIZE_MAX > 0xFFFFFFFFu
    return len > 0xFFFFFFFFu;
#else
    (void)len;
    return 0;
#endif
}

int msid_co_sdo_download(msid_co_sdo *s, uint16_t index, uint8_t sub, const void *data, size_t len)
{
    xfer x;
    if (begin(&x, s, index, sub, "download") < 0) return -MSID_DAQ_E_ARG;
    if ((!data && len) || beyond_size_field(len)) {
        snprintf(s->err, sizeof s->err, "SDO download of 0x%04X:%02X: no data or more than 2^32-1 bytes", (unsigned)index,
                 (unsigned)sub);
        return -MSID_DAQ_E_ARG;
    }
    const int expedited = len >= 1 && len <= EXPEDITED_BYTES;
    msid_can_frame f;
    if (expedited) {
        request_frame(&x, &f, (uint8_t)(CCS_INITIATE_DOWNLOAD << 5 | (EXPEDITED_BYTES - len) << 2 | 2u | 1u));
        memcpy(&f.data[4], data, len);
    } else {
        request_frame(&x, &f, (uint8_t)(CCS_INITIATE_DOWNLOAD << 5 | 1u));
        put_le32(&f.data[4], (uint32_t)len);
    }
    const int rc = initiate(&x, &f, SCS_INITIATE_DOWNLOAD, "an initiate download response");
    if (rc < 0) return rc;
    return expedited ? 0 : download_segments(&x, (const uint8_t *)data, len);
}

/* ---- init and the unsigned helpers ---- */

int msid_co_sdo_init(msid_co_sdo *s, const msid_co_io *io, unsigned node, int timeout_ms)
{
    if (!s) return -MSID_DAQ_E_ARG;
    memset(s, 0, sizeof *s);
    if (!io || !io->send || !io->recv) {
        snprintf(s->err, sizeof s->err, "SDO client: no bus to send and receive on");
        return -MSID_DAQ_E_ARG;
    }
    if (!msid_co_node_valid(node)) {
        snprintf(s->err, sizeof s->err, "node id %u is out of range (1..127)", node);
        return -MSID_DAQ_E_ARG;
    }
    if (timeout_ms < 0 || timeout_ms > 60000) {
        snprintf(s->err, sizeof s->err, "SDO timeout %d ms is out of range (1..60000)", timeout_ms);
        return -MSID_DAQ_E_ARG;
    }
    s->io = *io;
    s->node = (uint8_t)node;
    s->timeout_ms = timeout_ms ? timeout_ms : MSID_CO_SDO_TIMEOUT_MS;
    return 0;
}

int msid_co_sdo_read_uint(msid_co_sdo *s, uint16_t index, uint8_t sub, unsigned size, uint32_t *value)
{
    if (!s || !value || (size != 1 && size != 2 && size != 4)) return -MSID_DAQ_E_ARG;
    uint8_t b[4];
    size_t n = 0;
    int rc = msid_co_sdo_upload(s, index, sub, b, sizeof b, &n);
    if (rc == -MSID_DAQ_E_RANGE) n = sizeof b + 1;
    else if (rc < 0) return rc;
    if (n != size) {
        if (n > sizeof b) snprintf(s->err, sizeof s->err, "0x%04X:%02X on node %u holds more than 4 bytes where %u were expected",
                                   (unsigned)index, (unsigned)sub, (unsigned)s->node, size);
        else snprintf(s->err, sizeof s->err, "0x%04X:%02X on node %u holds %zu bytes where %u were expected", (unsigned)index,
                      (unsigned)sub, (unsigned)s->node, n, size);
        return -MSID_DAQ_E_PROTOCOL;
    }
    uint32_t v = 0;
    for (unsigned i = 0; i < size; i++) v |= (uint32_t)b[i] << (8 * i);
    *value = v;
    return 0;
}

int msid_co_sdo_write_uint(msid_co_sdo *s, uint16_t index, uint8_t sub, unsigned size, uint32_t value)
{
    if (!s || (size != 1 && size != 2 && size != 4)) return -MSID_DAQ_E_ARG;
    uint8_t b[4];
    put_le32(b, value);
    return msid_co_sdo_download(s, index, sub, b, size);
}
