/* The kernel's reply to RTM_GETLINK read for a CAN interface's bit timing (msid_can_bitrate.h): the link
 * kind and the nominal and data bit rates. Pure: no socket, every header copied out with memcpy (the bytes
 * need no alignment) after its length was checked against what encloses it. */
#include "msid_daq/msid_can_bitrate.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>

/* the attribute type without the flags the kernel sets on nested ones (nla_nest_start: NLA_F_NESTED) */
#define ATTR_TYPE(t) ((unsigned)(t) & (unsigned)NLA_TYPE_MASK)

const char *msid_can_bitrate_status_name(msid_can_bitrate_status s)
{
    switch (s) {
    case MSID_CAN_BITRATE_KNOWN: return "known";
    case MSID_CAN_BITRATE_VIRTUAL: return "virtual";
    case MSID_CAN_BITRATE_UNSET: return "unset";
    case MSID_CAN_BITRATE_NOT_CAN: return "not CAN";
    case MSID_CAN_BITRATE_MISSING: return "missing";
    case MSID_CAN_BITRATE_FAILED: return "failed";
    }
    return "failed";
}

static int fail(msid_can_bitrate *out, int rc, const char *what)
{
    out->status = MSID_CAN_BITRATE_FAILED;
    out->bitrate = out->data_bitrate = 0;
    snprintf(out->err, sizeof out->err, "rtnetlink reply: %s", what);
    return rc;
}

/* One attribute area [p, p + len): calls back for each attribute with its payload. 0, or -1 for an
 * attribute whose length does not fit the area (the area's rest ignored then). */
typedef int (*attr_fn)(void *ctx, unsigned type, const unsigned char *payload, size_t n);

static int walk(const unsigned char *p, size_t len, attr_fn fn, void *ctx)
{
    while (len >= sizeof(struct rtattr)) {
        struct rtattr a;
        memcpy(&a, p, sizeof a);
        if (a.rta_len < sizeof a || a.rta_len > len) return -1;
        const int r = fn(ctx, ATTR_TYPE(a.rta_type), p + RTA_LENGTH(0), a.rta_len - RTA_LENGTH(0));
        if (r) return r;
        const size_t step = RTA_ALIGN(a.rta_len);
        if (step >= len) return 0;   /* the last attribute may go without its padding */
        p += step;
        len -= step;
    }
    return len ? -1 : 0;   /* a tail too short for a header */
}

typedef struct {
    char kind[MSID_CAN_BITRATE_KIND_CAP];
    int have_info, have_kind, bad;
    const unsigned char *data;   /* IFLA_INFO_DATA's payload */
    size_t data_n;
    uint32_t bitrate, data_bitrate;
} link_view;

static int get_bitrate(const unsigned char *payload, size_t n, uint32_t *rate)
{
    struct can_bittiming bt;
    if (n < sizeof bt) return -1;
    memcpy(&bt, payload, sizeof bt);
    *rate = bt.bitrate;
    return 0;
}

static int on_can(void *ctx, unsigned type, const unsigned char *payload, size_t n)
{
    link_view *v = ctx;
    if (type == IFLA_CAN_BITTIMING) return get_bitrate(payload, n, &v->bitrate);
    if (type == IFLA_CAN_DATA_BITTIMING) return get_bitrate(payload, n, &v->data_bitrate);
    return 0;
}

static int on_info(void *ctx, unsigned type, const unsigned char *payload, size_t n)
{
    link_view *v = ctx;
    if (type == IFLA_INFO_KIND) {
        /* a NUL-terminated string (nla_put_string), read up to its payload's end; a kind longer than the
         * room is none of the CAN kinds, kept cut */
        size_t k = 0;
        while (k < n && payload[k]) ++k;
        if (k == 0) return -1;
        if (k >= sizeof v->kind) k = sizeof v->kind - 1;
        memcpy(v->kind, payload, k);
        v->kind[k] = '\0';
        v->have_kind = 1;
    } else if (type == IFLA_INFO_DATA) {
        v->data = payload;
        v->data_n = n;
    }
    return 0;
}

static int on_link(void *ctx, unsigned type, const unsigned char *payload, size_t n)
{
    link_view *v = ctx;
    if (type != IFLA_LINKINFO) return 0;
    v->have_info = 1;
    return walk(payload, n, on_info, v);
}

/* one RTM_NEWLINK message's payload (after its nlmsghdr) */
static int read_link(const unsigned char *p, size_t n, msid_can_bitrate *out)
{
    if (n < NLMSG_ALIGN(sizeof(struct ifinfomsg))) return fail(out, -MSID_DAQ_E_PROTOCOL, "a link message without its ifinfomsg");
    link_view v;
    memset(&v, 0, sizeof v);
    const size_t hdr = NLMSG_ALIGN(sizeof(struct ifinfomsg));
    if (walk(p + hdr, n - hdr, on_link, &v)) return fail(out, -MSID_DAQ_E_PROTOCOL, "an attribute longer than its message");
    memcpy(out->kind, v.kind, sizeof out->kind);
    if (!v.have_kind) {
        out->status = MSID_CAN_BITRATE_NOT_CAN;
        snprintf(out->err, sizeof out->err, "not a CAN interface (no link kind)");
        return 0;
    }
    if (!strcmp(v.kind, "vcan") || !strcmp(v.kind, "vxcan")) {
        out->status = MSID_CAN_BITRATE_VIRTUAL;
        snprintf(out->err, sizeof out->err, "a virtual CAN interface (%s): no bit rate", v.kind);
        return 0;
    }
    if (strcmp(v.kind, "can") != 0) {
        out->status = MSID_CAN_BITRATE_NOT_CAN;
        snprintf(out->err, sizeof out->err, "not a CAN interface (link kind %s)", v.kind);
        return 0;
    }
    if (v.data && walk(v.data, v.data_n, on_can, &v))
        return fail(out, -MSID_DAQ_E_PROTOCOL, "a CAN attribute shorter than its structure or longer than its message");
    if (!v.bitrate) {
        /* the kernel leaves IFLA_CAN_BITTIMING out while no bit rate is set (can_fill_info) */
        out->status = MSID_CAN_BITRATE_UNSET;
        snprintf(out->err, sizeof out->err, "a CAN interface without a bit rate set");
        return 0;
    }
    out->status = MSID_CAN_BITRATE_KNOWN;
    out->bitrate = v.bitrate;
    out->data_bitrate = v.data_bitrate;
    snprintf(out->err, sizeof out->err, "a CAN interface at %u bit/s", (unsigned)v.bitrate);
    return 0;
}

int msid_can_bitrate_parse(const void *reply, size_t len, msid_can_bitrate *out)
{
    if (!out) return -MSID_DAQ_E_ARG;
    memset(out, 0, sizeof *out);
    if (!reply && len) return fail(out, -MSID_DAQ_E_ARG, "no buffer");
    const unsigned char *p = reply;
    while (len >= sizeof(struct nlmsghdr)) {
        struct nlmsghdr h;
        memcpy(&h, p, sizeof h);
        if (h.nlmsg_len < sizeof h || h.nlmsg_len > len) return fail(out, -MSID_DAQ_E_PROTOCOL, "a message cut short");
        const unsigned char *body = p + NLMSG_HDRLEN;
        const size_t n = h.nlmsg_len - NLMSG_HDRLEN;
        if (h.nlmsg_type == NLMSG_ERROR) {
            struct nlmsgerr e;
            if (n < sizeof e) return fail(out, -MSID_DAQ_E_PROTOCOL, "an error message cut short");
            memcpy(&e, body, sizeof e);
            if (e.error == -ENODEV) {
                out->status = MSID_CAN_BITRATE_MISSING;
                snprintf(out->err, sizeof out->err, "no such interface");
                return 0;
            }
            if (e.error != 0) {
                out->status = MSID_CAN_BITRATE_FAILED;
                snprintf(out->err, sizeof out->err, "RTM_GETLINK: %s", strerror(-e.error));
                return -MSID_DAQ_E_IO;
            }
        } else if (h.nlmsg_type == RTM_NEWLINK) {
            return read_link(body, n, out);
        } else if (h.nlmsg_type == NLMSG_DONE) {
            break;
        }
        const size_t step = NLMSG_ALIGN(h.nlmsg_len);
        if (step >= len) break;
        p += step;
        len -= step;
    }
    return fail(out, -MSID_DAQ_E_PROTOCOL, len && len < sizeof(struct nlmsghdr) ? "a message cut short"
                                                                                  : "no link message");
}
