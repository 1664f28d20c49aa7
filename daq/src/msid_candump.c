/* candump .log writer and replay transport. */
#include "msid_daq/msid_candump.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

static const char HEX[] = "0123456789ABCDEF";

int msid_candump_format(char *buf, size_t cap, const msid_can_frame *f, const char *iface)
{
    if (cap < 200 || f->len > 64) return -1;
    const unsigned long long sec = f->t_ns / 1000000000ull, usec = f->t_ns % 1000000000ull / 1000ull;
    int n = snprintf(buf, cap, "(%010llu.%06llu) %s ", sec, usec, iface);
    if (n < 0 || (size_t)n > cap - 150) return -1;
    if (f->id & MSID_CAN_ERR_FLAG)
        n += snprintf(buf + n, cap - (size_t)n, "%08X#", (unsigned)(f->id & (MSID_CAN_ERR_FLAG | 0x1FFFFFFFu)));
    else if (f->id & MSID_CAN_EFF_FLAG)
        n += snprintf(buf + n, cap - (size_t)n, "%08X#", (unsigned)(f->id & 0x1FFFFFFFu));
    else
        n += snprintf(buf + n, cap - (size_t)n, "%03X#", (unsigned)(f->id & 0x7FFu));
    if (f->flags & MSID_CANF_FD) {
        buf[n++] = '#';
        buf[n++] = HEX[((f->flags & MSID_CANF_BRS) ? 1 : 0) | ((f->flags & MSID_CANF_ESI) ? 2 : 0)];
    } else if (f->id & MSID_CAN_RTR_FLAG) {
        buf[n++] = 'R';
        if (f->len > 0 && f->len <= 8) buf[n++] = (char)('0' + f->len);   /* 123#R8: the requested length */
    }
    if (!(f->id & MSID_CAN_RTR_FLAG) || (f->flags & MSID_CANF_FD))
        for (unsigned i = 0; i < f->len; ++i) {
            buf[n++] = HEX[f->data[i] >> 4];
            buf[n++] = HEX[f->data[i] & 15];
        }
    /* direction, as python-can's CanutilsLogWriter and `candump -x` write it: T sent by this host,
       R received; none on error frames (they come from the controller, not from a node) */
    if (!(f->id & MSID_CAN_ERR_FLAG)) {
        buf[n++] = ' ';
        buf[n++] = (f->flags & MSID_CANF_TX) ? 'T' : 'R';
    }
    buf[n++] = '\n';
    buf[n] = 0;
    return n;
}

static int hexval(char c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* The end of a line after the frame: nothing, or a space and the direction T (sent by the logging
   host: MSID_CANF_TX) or R (received), as python-can and `candump -x` write it; then only spaces and
   the line end. An error frame's direction is accepted and dropped (the writer gives it none). */
static int parse_tail(const char *s, msid_can_frame *f)
{
    if (*s == ' ') {
        while (*s == ' ') ++s;
        if ((*s == 'T' || *s == 'R') && (s[1] == ' ' || s[1] == 0 || s[1] == '\n' || s[1] == '\r')) {
            if (*s == 'T' && !(f->id & MSID_CAN_ERR_FLAG)) f->flags |= MSID_CANF_TX;
            ++s;
        }
    }
    while (*s == '\r' || *s == '\n' || *s == ' ') ++s;
    return *s ? -MSID_DAQ_E_FORMAT : 0;
}

int msid_candump_parse(const char *s, msid_can_frame *f, char *iface, size_t iface_cap)
{
    memset(f, 0, sizeof *f);
    while (*s == ' ' || *s == '\t') ++s;
    if (*s == 0 || *s == '\n' || (*s == '\r' && s[1] == '\n')) return 1;
    if (*s++ != '(') return -MSID_DAQ_E_FORMAT;
    unsigned long long sec = 0, usec = 0;
    int nd = 0;
    while (*s >= '0' && *s <= '9' && nd < 19) { sec = sec * 10 + (unsigned)(*s++ - '0'); ++nd; }
    if (nd == 0 || *s++ != '.') return -MSID_DAQ_E_FORMAT;
    nd = 0;
    while (*s >= '0' && *s <= '9') { if (nd < 6) usec = usec * 10 + (unsigned)(*s - '0'); ++s; ++nd; }
    if (nd == 0) return -MSID_DAQ_E_FORMAT;
    for (; nd < 6; ++nd) usec *= 10;
    if (*s++ != ')' || *s++ != ' ') return -MSID_DAQ_E_FORMAT;
    f->t_ns = sec * 1000000000ull + usec * 1000ull;
    size_t k = 0;
    while (*s && *s != ' ') {
        if (k + 1 >= iface_cap) return -MSID_DAQ_E_FORMAT;
        iface[k++] = *s++;
    }
    iface[k] = 0;
    if (k == 0 || *s++ != ' ') return -MSID_DAQ_E_FORMAT;
    uint32_t id = 0;
    int nid = 0, h;
    while ((h = hexval(*s)) >= 0) { id = id << 4 | (uint32_t)h; ++s; if (++nid > 8) return -MSID_DAQ_E_FORMAT; }
    if (*s++ != '#') return -MSID_DAQ_E_FORMAT;
    if (nid == 3) {
        if (id > 0x7FF) return -MSID_DAQ_E_FORMAT;
    } else if (nid == 8) {
        /* an error frame is the flag and its class bits only (no EFF/RTR bits, as SocketCAN delivers it) */
        id = (id & 0x1FFFFFFFu) | ((id & MSID_CAN_ERR_FLAG) ? MSID_CAN_ERR_FLAG : MSID_CAN_EFF_FLAG);
    } else {
        return -MSID_DAQ_E_FORMAT;
    }
    f->id = id;
    unsigned maxlen = 8;
    if (*s == '#') {
        ++s;
        const int fl = hexval(*s++);
        if (fl < 0) return -MSID_DAQ_E_FORMAT;
        f->flags = (uint8_t)(MSID_CANF_FD | ((fl & 1) ? MSID_CANF_BRS : 0) | ((fl & 2) ? MSID_CANF_ESI : 0));
        maxlen = 64;
    } else if (*s == 'R') {
        f->id |= MSID_CAN_RTR_FLAG;
        ++s;
        if (*s >= '0' && *s <= '8') f->len = (uint8_t)(*s++ - '0');
        return parse_tail(s, f);
    }
    unsigned len = 0;
    for (;;) {
        if (*s == '.') { ++s; continue; }   /* candump accepts '.' separators */
        const int a = hexval(s[0]);
        if (a < 0) break;
        const int b = hexval(s[1]);
        if (b < 0 || len >= maxlen) return -MSID_DAQ_E_FORMAT;
        f->data[len++] = (uint8_t)(a << 4 | b);
        s += 2;
    }
    f->len = (uint8_t)len;
    if (*s == '_') {   /* classic len8_dlc suffix: ignored */
        if (hexval(s[1]) < 0) return -MSID_DAQ_E_FORMAT;
        s += 2;
    }
    return parse_tail(s, f);
}

static int replay_recv(void *ctx, msid_can_frame *out, int n, int timeout_ms)
{
    (void)timeout_ms;
    msid_candump_reader *r = ctx;
    char line[1024];
    int got = 0;
    if (r->pending) {   /* the error met after the frames returned last time */
        const int e = r->pending;
        r->pending = 0;
        return e;
    }
    while (got < n) {
        if (!fgets(line, sizeof line, r->fp)) {
            if (ferror(r->fp)) {
                snprintf(r->err, sizeof r->err, "read error after line %llu: %s", (unsigned long long)r->line, strerror(errno));
                return got ? got : -MSID_DAQ_E_IO;
            }
            return got ? got : -MSID_DAQ_E_EOF;
        }
        r->line++;
        if (!strchr(line, '\n') && !feof(r->fp)) {
            snprintf(r->err, sizeof r->err, "line %llu is too long", (unsigned long long)r->line);
            r->pending = got ? -MSID_DAQ_E_FORMAT : 0;
            return got ? got : -MSID_DAQ_E_FORMAT;
        }
        const int st = msid_candump_parse(line, &out[got], r->iface, sizeof r->iface);
        if (st == 1) continue;
        if (st < 0) {
            size_t l = strcspn(line, "\r\n");
            snprintf(r->err, sizeof r->err, "line %llu is not a candump log line: '%.*s'", (unsigned long long)r->line,
                     (int)(l > 120 ? 120 : l), line);
            r->pending = got ? -MSID_DAQ_E_FORMAT : 0;
            return got ? got : -MSID_DAQ_E_FORMAT;
        }
        r->st.frames++;
        r->st.timestamps++;
        ++got;
    }
    return got;
}

static int replay_send(void *ctx, const msid_can_frame *f, int timeout_ms)
{
    (void)f; (void)timeout_ms;
    msid_candump_reader *r = ctx;
    snprintf(r->err, sizeof r->err, "a replayed log cannot send frames");
    return -MSID_DAQ_E_ARG;
}

static void replay_stats(void *ctx, msid_can_link_stats *s) { *s = ((msid_candump_reader *)ctx)->st; }
static const char *replay_error(void *ctx) { return ((msid_candump_reader *)ctx)->err; }
static void replay_close(void *ctx)
{
    msid_candump_reader *r = ctx;
    if (r->fp) fclose(r->fp);
    r->fp = NULL;
}

static const msid_can_backend CANDUMP = {"candump-replay", replay_recv, replay_send, replay_stats, replay_error,
                                         replay_close};

int msid_candump_open(msid_candump_reader *r, const char *path)
{
    memset(r, 0, sizeof *r);
    r->fp = fopen(path, "r");
    if (!r->fp) {
        snprintf(r->err, sizeof r->err, "cannot open '%s': %s", path, strerror(errno));
        return -MSID_DAQ_E_IO;
    }
    r->tr.be = &CANDUMP;
    r->tr.ctx = r;
    return 0;
}

void msid_candump_rewind(msid_candump_reader *r)
{
    if (r->fp) rewind(r->fp);
    r->line = 0;
    r->pending = 0;
    memset(&r->st, 0, sizeof r->st);
}
