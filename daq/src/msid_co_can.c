/* The CANopen objects' io over a CAN transport. */
#include "msid_daq/msid_co_can.h"

#include <stdio.h>
#include <string.h>

static void keep_error(msid_co_can *c)
{
    snprintf(c->err, sizeof c->err, "%s", msid_can_error(c->t));
}

static int co_send(void *ctx, const msid_can_frame *f)
{
    msid_co_can *c = ctx;
    const int rc = msid_can_send(c->t, f, c->send_timeout_ms);
    if (rc < 0) keep_error(c);
    return rc;
}

static int co_recv(void *ctx, msid_can_frame *f, int timeout_ms)
{
    msid_co_can *c = ctx;
    if (c->at >= c->n) {
        const int rc = msid_can_recv(c->t, c->buf, MSID_CO_CAN_BATCH, timeout_ms);
        if (rc < 0) {
            if (rc != -MSID_DAQ_E_TIMEOUT) keep_error(c);
            return rc;
        }
        c->n = rc;
        c->at = 0;
    }
    *f = c->buf[c->at++];
    return 1;
}

int msid_co_can_io(msid_co_can *c, const msid_can_transport *t, int send_timeout_ms, msid_co_io *io)
{
    if (!c || !t || !io || send_timeout_ms < 1 || send_timeout_ms > 60000) return -MSID_DAQ_E_ARG;
    memset(c, 0, sizeof *c);
    c->t = t;
    c->send_timeout_ms = send_timeout_ms;
    memset(io, 0, sizeof *io);
    io->ctx = c;
    io->send = co_send;
    io->recv = co_recv;
    return 0;
}
