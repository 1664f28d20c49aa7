/* Wrapper functions over the CAN transport backend table (libmodbus style). */
#include "msid_daq/msid_can_transport.h"

#include <stddef.h>

int msid_can_recv(const msid_can_transport *t, msid_can_frame *f, int n, int timeout_ms)
{
    return t->be->recv(t->ctx, f, n, timeout_ms);
}

int msid_can_send(const msid_can_transport *t, const msid_can_frame *f, int timeout_ms)
{
    return t->be->send(t->ctx, f, timeout_ms);
}

void msid_can_get_stats(const msid_can_transport *t, msid_can_link_stats *s)
{
    t->be->stats(t->ctx, s);
}

const char *msid_can_error(const msid_can_transport *t)
{
    return t->be->error(t->ctx);
}

void msid_can_close(msid_can_transport *t)
{
    if (!t->be) return;
    t->be->close(t->ctx);
    t->be = NULL;
}
