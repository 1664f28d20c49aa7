/* The kernel asked for a CAN interface's bit timing (msid_can_bitrate.h): one RTM_GETLINK on a
 * NETLINK_ROUTE socket, its reply read by msid_can_bitrate_parse. Once before a run: the reply in a stack
 * buffer. */
#define _GNU_SOURCE
#include "msid_daq/msid_can_bitrate.h"

#include <errno.h>
#include <net/if.h>
#include <poll.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <linux/netlink.h>
#include <linux/rtnetlink.h>

/* one link's RTM_NEWLINK is some kilobytes (its statistics, VF tables aside); the kernel's own advice for
 * a netlink receive buffer is 32 KiB, and a reply larger than it is refused (MSG_TRUNC), never read cut */
#define REPLY_CAP 32768
#define WAIT_MS 1000

static int failed(msid_can_bitrate *out, const char *what, int e)
{
    memset(out, 0, sizeof *out);
    out->status = MSID_CAN_BITRATE_FAILED;
    snprintf(out->err, sizeof out->err, "rtnetlink: %s: %s", what, strerror(e));
    return -MSID_DAQ_E_IO;
}

int msid_can_bitrate_query(const char *iface, msid_can_bitrate *out)
{
    if (!out) return -MSID_DAQ_E_ARG;
    memset(out, 0, sizeof *out);
    const size_t nlen = iface ? strlen(iface) : 0;
    if (nlen == 0 || nlen >= IF_NAMESIZE) {
        out->status = MSID_CAN_BITRATE_FAILED;
        snprintf(out->err, sizeof out->err, "an interface name must be 1..%d characters", IF_NAMESIZE - 1);
        return -MSID_DAQ_E_ARG;
    }
    const unsigned idx = if_nametoindex(iface);
    if (idx == 0) {
        if (errno != ENODEV && errno != ENXIO) return failed(out, "if_nametoindex", errno);
        out->status = MSID_CAN_BITRATE_MISSING;
        snprintf(out->err, sizeof out->err, "no such interface");
        return 0;
    }
    const int fd = socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE);
    if (fd < 0) return failed(out, "socket(NETLINK_ROUTE)", errno);
    struct {
        struct nlmsghdr h;
        struct ifinfomsg i;
    } req;
    memset(&req, 0, sizeof req);
    req.h.nlmsg_len = NLMSG_LENGTH(sizeof req.i);
    req.h.nlmsg_type = RTM_GETLINK;
    req.h.nlmsg_flags = NLM_F_REQUEST;
    req.h.nlmsg_seq = 1;
    req.i.ifi_family = AF_UNSPEC;
    req.i.ifi_index = (int)idx;
    struct sockaddr_nl kernel;
    memset(&kernel, 0, sizeof kernel);
    kernel.nl_family = AF_NETLINK;
    if (sendto(fd, &req, req.h.nlmsg_len, 0, (const struct sockaddr *)&kernel, sizeof kernel) < 0) {
        const int e = errno;
        close(fd);
        return failed(out, "sending RTM_GETLINK", e);
    }
    /* unsigned char of a union with the header: the parser needs no alignment, the kernel gets it anyway */
    union {
        struct nlmsghdr h;
        unsigned char b[REPLY_CAP];
    } reply;
    for (;;) {
        struct pollfd p = {fd, POLLIN, 0};
        const int r = poll(&p, 1, WAIT_MS);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) {
            const int e = r < 0 ? errno : ETIMEDOUT;
            close(fd);
            return failed(out, "waiting for the reply to RTM_GETLINK", e);
        }
        const ssize_t n = recv(fd, reply.b, sizeof reply.b, MSG_TRUNC);
        if (n < 0 && errno == EINTR) continue;
        const int e = errno;
        close(fd);
        if (n < 0) return failed(out, "receiving the reply to RTM_GETLINK", e);
        if ((size_t)n > sizeof reply.b) return failed(out, "the reply to RTM_GETLINK is larger than 32 KiB", EMSGSIZE);
        return msid_can_bitrate_parse(reply.b, (size_t)n, out);
    }
}
