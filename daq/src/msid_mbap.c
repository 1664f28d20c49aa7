/* Modbus TCP framing of our own: send a request, skip stale and foreign MBAP frames, return the matching one. */
#define _DEFAULT_SOURCE
#include "msid_daq/msid_mbap.h"
#include "msid_daq/msid_daq.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>

static int64_t now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000 + t.tv_nsec / 1000000;
}

size_t msid_mbap_header_pdu_len(const uint8_t h[7])
{
    const uint32_t proto = (uint32_t)h[2] << 8 | h[3], len = (uint32_t)h[4] << 8 | h[5];
    if (proto != 0 || len < 2 || len > MSID_MBAP_MAX_PDU + 1) return 0;
    return len - 1;   /* the length counts the unit id */
}

/* Wait until fd is ready for `ev` or the deadline (monotonic ms) passes: 1 ready, 0 timed out, -1 error. */
static int wait_fd(int fd, short ev, int64_t deadline)
{
    for (;;) {
        const int64_t left = deadline - now_ms();
        if (left <= 0) return 0;
        struct pollfd p = {fd, ev, 0};
        const int r = poll(&p, 1, left > 60000 ? 60000 : (int)left);
        if (r > 0) return 1;
        if (r < 0 && errno != EINTR) return -1;
    }
}

/* Read exactly n bytes: the first by `first` (monotonic ms; a new frame: the response deadline), each
   further one within the byte timeout. 0, or -msid_daq_status with c->err set. */
static int read_n(msid_mbap *c, uint8_t *dst, size_t n, int64_t first, int new_frame)
{
    size_t got = 0;
    int64_t deadline = first;
    while (got < n) {
        /* what has arrived already is taken without a poll (the body behind its header, mostly) */
        const ssize_t q = recv(c->fd, dst + got, n - got, MSG_DONTWAIT);
        if (q > 0) {
            got += (size_t)q;
            deadline = now_ms() + c->byte_timeout_ms;
            continue;
        }
        if (q == 0) {
            snprintf(c->err, sizeof c->err, "connection closed by the device");
            return -MSID_DAQ_E_IO;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR) {
            snprintf(c->err, sizeof c->err, "receive: %s", strerror(errno));
            return -MSID_DAQ_E_IO;
        }
        const int w = wait_fd(c->fd, POLLIN, deadline);
        if (w == 0) {
            if (new_frame && got == 0)
                snprintf(c->err, sizeof c->err, "no reply (response timeout of %u ms)", (unsigned)c->response_timeout_ms);
            else
                snprintf(c->err, sizeof c->err, "a reply stopped after %zu of %zu bytes (byte timeout of %u ms)", got, n,
                         (unsigned)c->byte_timeout_ms);
            return -MSID_DAQ_E_TIMEOUT;
        }
        const ssize_t r = w < 0 ? -1 : recv(c->fd, dst + got, n - got, MSG_DONTWAIT);
        if (r == 0) {
            snprintf(c->err, sizeof c->err, "connection closed by the device");
            return -MSID_DAQ_E_IO;
        }
        if (r < 0) {
            if (w > 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) continue;
            snprintf(c->err, sizeof c->err, "receive: %s", strerror(errno));
            return -MSID_DAQ_E_IO;
        }
        got += (size_t)r;
        deadline = now_ms() + c->byte_timeout_ms;
    }
    return 0;
}

static int send_all(msid_mbap *c, const uint8_t *src, size_t n, int64_t deadline)
{
    size_t sent = 0;
    while (sent < n) {
        const ssize_t r = send(c->fd, src + sent, n - sent, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (r > 0) {
            sent += (size_t)r;
            continue;
        }
        if (r < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
            const int w = wait_fd(c->fd, POLLOUT, deadline);
            if (w > 0) continue;
            if (w == 0) {
                snprintf(c->err, sizeof c->err, "request not sent (response timeout)");
                return -MSID_DAQ_E_TIMEOUT;
            }
            snprintf(c->err, sizeof c->err, "send: %s", strerror(errno));
            return -MSID_DAQ_E_IO;
        }
        snprintf(c->err, sizeof c->err, "send: %s", r < 0 ? strerror(errno) : "nothing sent");
        return -MSID_DAQ_E_IO;
    }
    return 0;
}

int msid_mbap_request(msid_mbap *c, const uint8_t *req, size_t req_n, uint8_t *rsp, size_t *rsp_n)
{
    if (!c || !req || !rsp || !rsp_n || req_n == 0 || req_n > MSID_MBAP_MAX_PDU || c->fd < 0 ||
        c->response_timeout_ms == 0 || c->byte_timeout_ms == 0)
        return -MSID_DAQ_E_ARG;
    c->err[0] = 0;
    uint8_t f[7 + MSID_MBAP_MAX_PDU];
    c->tid = (uint16_t)(c->tid + 1u);
    f[0] = (uint8_t)(c->tid >> 8);
    f[1] = (uint8_t)c->tid;
    f[2] = f[3] = 0;
    f[4] = (uint8_t)((req_n + 1) >> 8);
    f[5] = (uint8_t)(req_n + 1);
    f[6] = c->unit;
    memcpy(f + 7, req, req_n);
    /* the response timeout bounds the whole wait for the matching frame: skipped frames do not extend it */
    const int64_t deadline = now_ms() + c->response_timeout_ms;
    int rc = send_all(c, f, 7 + req_n, deadline);
    uint32_t skipped = 0;
    for (; rc == 0;) {
        uint8_t h[7];
        if ((rc = read_n(c, h, 7, deadline, 1)) < 0) break;
        const size_t n = msid_mbap_header_pdu_len(h);
        if (n == 0) {
            c->malformed++;
            snprintf(c->err, sizeof c->err, "malformed MBAP frame: protocol id %u, length %u (must be 0 and 2..%u)",
                     (unsigned)(h[2] << 8 | h[3]), (unsigned)(h[4] << 8 | h[5]), MSID_MBAP_MAX_PDU + 1);
            return -MSID_DAQ_E_PROTOCOL;
        }
        if ((rc = read_n(c, rsp, n, now_ms() + c->byte_timeout_ms, 0)) < 0) break;
        const uint16_t tid = (uint16_t)(h[0] << 8 | h[1]);
        if (tid == c->tid && h[6] == c->unit) {
            *rsp_n = n;
            return 0;
        }
        c->skipped++;   /* a stale or foreign reply: read whole, so the stream stays framed; wait on */
        skipped++;
    }
    if (rc == -MSID_DAQ_E_TIMEOUT && skipped) {
        const size_t k = strlen(c->err);
        snprintf(c->err + k, sizeof c->err - k, " after %u repl%s with another transaction or unit id", skipped,
                 skipped == 1 ? "y" : "ies");
    }
    return rc;
}
