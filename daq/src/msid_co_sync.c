/* The SYNC producer over CAN_BCM (msid_co_sync.h). */
#define _GNU_SOURCE
#include "msid_daq/msid_co_sync.h"

#include <errno.h>
#include <net/if.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>
#include <linux/can.h>
#include <linux/can/bcm.h>

/* TX_SETUP with up to 240 frames, the counter's values in turn: the head, then the frames (the head's
   flexible array, written as bytes) */
#define SETUP_BYTES (sizeof(struct bcm_msg_head) + MSID_CO_SYNC_COUNTER_MAX * sizeof(struct can_frame))

static int failed(msid_co_sync *s, const char *what, int e)
{
    int rc = -MSID_DAQ_E_IO;
    if (e == EAFNOSUPPORT || e == EPROTONOSUPPORT) rc = -MSID_DAQ_E_NOSUPPORT;
    else if (e == EPERM || e == EACCES) rc = -MSID_DAQ_E_PERM;
    else if (e == ENODEV || e == ENXIO) rc = -MSID_DAQ_E_NODEV;
    if (rc == -MSID_DAQ_E_NOSUPPORT)
        snprintf(s->err, sizeof s->err, "SYNC: this kernel has no CAN broadcast manager (CAN_BCM): modprobe can-bcm");
    else
        snprintf(s->err, sizeof s->err, "SYNC: %s: %s", what, strerror(e));
    if (s->fd >= 0) close(s->fd);
    s->fd = -1;
    return rc;
}

int msid_co_sync_start(msid_co_sync *s, const char *iface, uint32_t period_us, unsigned counter)
{
    if (!s) return -MSID_DAQ_E_ARG;
    memset(s, 0, sizeof *s);
    s->fd = -1;
    if (!iface || !iface[0] || strlen(iface) >= IFNAMSIZ || period_us < 100 || period_us > 1000000 || counter == 1 ||
        counter > MSID_CO_SYNC_COUNTER_MAX) {
        snprintf(s->err, sizeof s->err, "SYNC: interface, period (100..1000000 us) or counter (0, 2..240) out of range");
        return -MSID_DAQ_E_ARG;
    }
    s->fd = socket(PF_CAN, SOCK_DGRAM, CAN_BCM);
    if (s->fd < 0) return failed(s, "socket(CAN_BCM)", errno);
    const unsigned ifindex = if_nametoindex(iface);
    if (!ifindex) return failed(s, iface, errno ? errno : ENODEV);
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = (int)ifindex;
    if (connect(s->fd, (struct sockaddr *)&addr, sizeof addr) < 0) return failed(s, iface, errno);
    static _Alignas(8) unsigned char buf[SETUP_BYTES];  /* 3.8 KiB: not on a real-time thread's stack */
    memset(buf, 0, sizeof buf);
    struct bcm_msg_head head;
    memset(&head, 0, sizeof head);
    head.opcode = TX_SETUP;
    head.flags = SETTIMER | STARTTIMER;
    head.count = 0;
    head.ival2.tv_sec = (long)(period_us / 1000000u);
    head.ival2.tv_usec = (long)(period_us % 1000000u);
    head.can_id = 0x080;
    head.nframes = counter ? counter : 1;
    memcpy(buf, &head, sizeof head);
    for (unsigned i = 0; i < head.nframes; i++) {
        struct can_frame f;
        memset(&f, 0, sizeof f);
        f.can_id = 0x080;
        f.can_dlc = counter ? 1 : 0;
        f.data[0] = (uint8_t)(counter ? i + 1 : 0);
        memcpy(buf + sizeof head + i * sizeof f, &f, sizeof f);
    }
    const size_t len = sizeof head + head.nframes * sizeof(struct can_frame);
    if (write(s->fd, buf, len) != (ssize_t)len) return failed(s, "TX_SETUP", errno);
    s->period_us = period_us;
    s->counter = counter;
    return 0;
}

void msid_co_sync_stop(msid_co_sync *s)
{
    if (!s || s->fd < 0) return;
    struct bcm_msg_head h;
    memset(&h, 0, sizeof h);
    h.opcode = TX_DELETE;
    h.can_id = 0x080;
    (void)!write(s->fd, &h, sizeof h);  /* closing deletes it as well */
    close(s->fd);
    s->fd = -1;
}
