/* SocketCAN transport: raw CAN socket with FD frames, filters, error frames,
 * kernel timestamps and drop counts. */
#define _GNU_SOURCE
#include "msid_daq/msid_socketcan.h"

#include <errno.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include <linux/can.h>
#include <linux/can/raw.h>

#ifndef SO_RXQ_OVFL
#define SO_RXQ_OVFL 40
#endif

#define BATCH 64

static void set_err(msid_socketcan *s, const char *fmt, const char *a, int e)
{
    snprintf(s->err, sizeof s->err, fmt, a, e ? strerror(e) : "");
}

static int recv_frames(void *ctx, msid_can_frame *out, int n, int timeout_ms)
{
    msid_socketcan *s = ctx;
    if (n <= 0) return -MSID_DAQ_E_ARG;
    if (n > BATCH) n = BATCH;
    struct canfd_frame buf[BATCH];
    struct iovec iov[BATCH];
    struct mmsghdr mm[BATCH];
    char ctl[BATCH][CMSG_SPACE(sizeof(struct timespec)) + CMSG_SPACE(sizeof(uint32_t)) + 32];
    for (;;) {
        struct pollfd p = {s->fd, POLLIN, 0};
        int r = poll(&p, 1, timeout_ms);
        if (r < 0) {
            if (errno == EINTR) continue;
            set_err(s, "poll on %s: %s", "CAN socket", errno);
            return -MSID_DAQ_E_IO;
        }
        if (r == 0) return -MSID_DAQ_E_TIMEOUT;
        for (int i = 0; i < n; ++i) {
            iov[i].iov_base = &buf[i];
            iov[i].iov_len = sizeof buf[i];
            memset(&mm[i].msg_hdr, 0, sizeof mm[i].msg_hdr);
            mm[i].msg_hdr.msg_iov = &iov[i];
            mm[i].msg_hdr.msg_iovlen = 1;
            mm[i].msg_hdr.msg_control = ctl[i];
            mm[i].msg_hdr.msg_controllen = sizeof ctl[i];
        }
        int k = recvmmsg(s->fd, mm, (unsigned)n, MSG_DONTWAIT, NULL);
        if (k < 0) {
            if (errno == EINTR || errno == EAGAIN) continue;
            if (errno == ENETDOWN) { set_err(s, "CAN interface went down%s%s", "", 0); return -MSID_DAQ_E_DOWN; }
            set_err(s, "recvmmsg on %s: %s", "CAN socket", errno);
            return -MSID_DAQ_E_IO;
        }
        int got = 0;
        for (int i = 0; i < k; ++i) {
            const unsigned len = mm[i].msg_len;
            if ((len != CAN_MTU && len != CANFD_MTU) || (mm[i].msg_hdr.msg_flags & MSG_TRUNC)) {
                s->st.bad_length++;
                continue;
            }
            msid_can_frame *f = &out[got++];
            const struct canfd_frame *c = &buf[i];
            f->id = c->can_id;
            f->flags = 0;
            if (len == CANFD_MTU) {
                f->flags |= MSID_CANF_FD;
                if (c->flags & CANFD_BRS) f->flags |= MSID_CANF_BRS;
                if (c->flags & CANFD_ESI) f->flags |= MSID_CANF_ESI;
                f->len = c->len > 64 ? 64 : c->len;
            } else {
                f->len = c->len > 8 ? 8 : c->len;
            }
            memcpy(f->data, c->data, f->len);
            f->t_ns = 0;
            for (struct cmsghdr *cm = CMSG_FIRSTHDR(&mm[i].msg_hdr); cm; cm = CMSG_NXTHDR(&mm[i].msg_hdr, cm)) {
                if (cm->cmsg_level != SOL_SOCKET) continue;
                if (cm->cmsg_type == SO_TIMESTAMPNS) {
                    struct timespec ts;
                    memcpy(&ts, CMSG_DATA(cm), sizeof ts);
                    f->t_ns = (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
                    s->st.timestamps++;
                } else if (cm->cmsg_type == SO_RXQ_OVFL) {
                    uint32_t v;
                    memcpy(&v, CMSG_DATA(cm), sizeof v);
                    s->last_ovfl = v;
                    s->have_ovfl = 1;
                    s->st.kernel_drops = v;
                }
            }
        }
        s->st.frames += (uint64_t)got;
        if (got > 0) return got;
        /* every read of this batch was rejected: wait again */
    }
}

static int send_frame(void *ctx, const msid_can_frame *f, int timeout_ms)
{
    msid_socketcan *s = ctx;
    struct canfd_frame c;
    memset(&c, 0, sizeof c);
    const int fdf = (f->flags & MSID_CANF_FD) != 0;
    if (fdf && !s->fd_frames) { set_err(s, "CAN FD frame on a socket opened for classic CAN%s%s", "", 0); return -MSID_DAQ_E_ARG; }
    if (f->len > (fdf ? 64 : 8)) { set_err(s, "frame length out of range%s%s", "", 0); return -MSID_DAQ_E_ARG; }
    c.can_id = f->id;
    c.len = f->len;
    if (fdf) c.flags = (uint8_t)(((f->flags & MSID_CANF_BRS) ? CANFD_BRS : 0) | ((f->flags & MSID_CANF_ESI) ? CANFD_ESI : 0));
    memcpy(c.data, f->data, f->len);
    const size_t mtu = fdf ? CANFD_MTU : CAN_MTU;
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (;;) {
        ssize_t w = send(s->fd, &c, mtu, MSG_DONTWAIT);
        if (w == (ssize_t)mtu) return 0;
        if (w >= 0) { set_err(s, "short write on %s%s", "CAN socket", 0); return -MSID_DAQ_E_IO; }
        if (errno == EINTR) continue;
        if (errno == ENOBUFS || errno == EAGAIN) {
            /* the device queue is full (the qdisc dropped the frame): wait for room, then retry */
            const int e = errno;
            struct timespec t;
            clock_gettime(CLOCK_MONOTONIC, &t);
            const long el = (long)(t.tv_sec - t0.tv_sec) * 1000 + (t.tv_nsec - t0.tv_nsec) / 1000000;
            if (timeout_ms >= 0 && el >= timeout_ms) {
                snprintf(s->err, sizeof s->err, "the CAN send queue stayed full (%s) for %d ms",
                         e == ENOBUFS ? "ENOBUFS" : "EAGAIN", timeout_ms);
                return -MSID_DAQ_E_BUSY;
            }
            s->st.send_retries++;   /* counted only when the frame is sent again */
            struct pollfd p = {s->fd, POLLOUT, 0};
            if (poll(&p, 1, 1) >= 0) {
                const struct timespec nap = {0, 100000};
                nanosleep(&nap, NULL);   /* POLLOUT is often ready at once on CAN: do not spin */
            }
            continue;
        }
        if (errno == ENETDOWN) { set_err(s, "CAN interface is down%s%s", "", 0); return -MSID_DAQ_E_DOWN; }
        if (errno == EPERM || errno == EACCES) { set_err(s, "send: %s%s", "", errno); return -MSID_DAQ_E_PERM; }
        set_err(s, "send on %s: %s", "CAN socket", errno);
        return -MSID_DAQ_E_IO;
    }
}

static void stats(void *ctx, msid_can_link_stats *st) { *st = ((msid_socketcan *)ctx)->st; }
static const char *error(void *ctx) { return ((msid_socketcan *)ctx)->err; }
static void close_sock(void *ctx)
{
    msid_socketcan *s = ctx;
    if (s->fd >= 0) close(s->fd);
    s->fd = -1;
}

static const msid_can_backend SOCKETCAN = {"socketcan", recv_frames, send_frame, stats, error, close_sock};

static int fail(msid_socketcan *s, int code)
{
    if (s->fd >= 0) close(s->fd);
    s->fd = -1;
    return -code;
}

static long read_rmem_max(void)
{
    FILE *f = fopen("/proc/sys/net/core/rmem_max", "r");
    long v = -1;
    if (f) { if (fscanf(f, "%ld", &v) != 1) v = -1; fclose(f); }
    return v;
}

int msid_socketcan_open(msid_socketcan *s, const msid_socketcan_cfg *cfg)
{
    memset(s, 0, sizeof *s);
    s->fd = -1;
    if (!cfg || !cfg->iface || !cfg->iface[0] || strlen(cfg->iface) >= IFNAMSIZ || cfg->n_filters < 0 ||
        cfg->n_filters > MSID_SOCKETCAN_MAX_FILTERS || cfg->rcvbuf < 0) {
        snprintf(s->err, sizeof s->err, "bad SocketCAN options (interface name missing or too long)");
        return -MSID_DAQ_E_ARG;
    }
    const char *ifn = cfg->iface;
    s->fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (s->fd < 0) {
        const int e = errno;
        if (e == EAFNOSUPPORT || e == EPROTONOSUPPORT) {
            snprintf(s->err, sizeof s->err, "this kernel has no SocketCAN (AF_CAN): load the can and can-raw modules "
                                            "(modprobe can-raw), or run inside the vcan VM (tests/vcan/vm.py)");
            return fail(s, MSID_DAQ_E_NOSUPPORT);
        }
        if (e == EPERM || e == EACCES) { set_err(s, "no permission to open a raw CAN socket%s: %s", "", e); return fail(s, MSID_DAQ_E_PERM); }
        set_err(s, "socket(AF_CAN)%s: %s", "", e);
        return fail(s, MSID_DAQ_E_IO);
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    strncpy(ifr.ifr_name, ifn, IFNAMSIZ - 1);
    if (ioctl(s->fd, SIOCGIFINDEX, &ifr) < 0) {
        snprintf(s->err, sizeof s->err, "no CAN interface '%s' (ip -details link show lists the interfaces)", ifn);
        return fail(s, MSID_DAQ_E_NODEV);
    }
    s->ifindex = ifr.ifr_ifindex;
    if (ioctl(s->fd, SIOCGIFFLAGS, &ifr) == 0 && !(ifr.ifr_flags & IFF_UP)) {
        snprintf(s->err, sizeof s->err, "CAN interface '%s' is down (ip link set %s up)", ifn, ifn);
        return fail(s, MSID_DAQ_E_DOWN);
    }
    if (cfg->fd_frames) {
        memset(&ifr, 0, sizeof ifr);
        strncpy(ifr.ifr_name, ifn, IFNAMSIZ - 1);
        if (ioctl(s->fd, SIOCGIFMTU, &ifr) < 0 || ifr.ifr_mtu != CANFD_MTU) {
            snprintf(s->err, sizeof s->err, "interface '%s' does not carry CAN FD (MTU %d, needs %d: ip link set %s mtu 72)",
                     ifn, ifr.ifr_mtu, (int)CANFD_MTU, ifn);
            return fail(s, MSID_DAQ_E_NOFD);
        }
        const int on = 1;
        if (setsockopt(s->fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
            set_err(s, "CAN_RAW_FD_FRAMES%s: %s", "", errno);
            return fail(s, MSID_DAQ_E_NOFD);
        }
        s->fd_frames = 1;
    }
    if (cfg->n_filters > 0) {
        struct can_filter flt[MSID_SOCKETCAN_MAX_FILTERS];
        for (int i = 0; i < cfg->n_filters; ++i) { flt[i].can_id = cfg->filter_id[i]; flt[i].can_mask = cfg->filter_mask[i]; }
        if (setsockopt(s->fd, SOL_CAN_RAW, CAN_RAW_FILTER, flt, (socklen_t)(sizeof flt[0] * (size_t)cfg->n_filters)) < 0) {
            set_err(s, "CAN_RAW_FILTER%s: %s", "", errno);
            return fail(s, MSID_DAQ_E_IO);
        }
    }
    if (cfg->err_frames) {
        const can_err_mask_t m = CAN_ERR_MASK;
        if (setsockopt(s->fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &m, sizeof m) < 0) {
            set_err(s, "CAN_RAW_ERR_FILTER%s: %s", "", errno);
            return fail(s, MSID_DAQ_E_IO);
        }
    }
    if (cfg->recv_own) {
        const int on = 1;
        setsockopt(s->fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &on, sizeof on);
    }
    const int on = 1;
    if (setsockopt(s->fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) < 0 ||
        setsockopt(s->fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) < 0) {
        set_err(s, "SO_TIMESTAMPNS/SO_RXQ_OVFL%s: %s", "", errno);
        return fail(s, MSID_DAQ_E_IO);
    }
    if (cfg->rcvbuf > 0) {
        const long mx = read_rmem_max();
        if (mx >= 0 && cfg->rcvbuf > mx) {
            if (setsockopt(s->fd, SOL_SOCKET, SO_RCVBUFFORCE, &cfg->rcvbuf, sizeof cfg->rcvbuf) < 0) {
                const int e = errno;
                if (e == EPERM || e == EACCES) {
                    snprintf(s->err, sizeof s->err,
                             "no permission for a %d-byte receive buffer: above net.core.rmem_max (%ld) it needs "
                             "CAP_NET_ADMIN (run as root, or raise rmem_max with sysctl)", cfg->rcvbuf, mx);
                    return fail(s, MSID_DAQ_E_PERM);
                }
                set_err(s, "SO_RCVBUFFORCE%s: %s", "", e);
                return fail(s, MSID_DAQ_E_IO);
            }
        } else if (setsockopt(s->fd, SOL_SOCKET, SO_RCVBUF, &cfg->rcvbuf, sizeof cfg->rcvbuf) < 0) {
            set_err(s, "SO_RCVBUF%s: %s", "", errno);
            return fail(s, MSID_DAQ_E_IO);
        }
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = s->ifindex;
    if (bind(s->fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        const int e = errno;
        if (e == ENODEV) snprintf(s->err, sizeof s->err, "'%s' is not a CAN interface", ifn);
        else set_err(s, "bind to %s: %s", ifn, e);
        return fail(s, e == ENODEV ? MSID_DAQ_E_NODEV : e == EPERM || e == EACCES ? MSID_DAQ_E_PERM : MSID_DAQ_E_IO);
    }
    s->tr.be = &SOCKETCAN;
    s->tr.ctx = s;
    return 0;
}
