/* Wrapper functions over the Modbus transport backend table (libmodbus style). */
#include "msid_daq/msid_mb_transport.h"

#include <stddef.h>

int msid_mb_read_input(const msid_mb_transport *t, uint32_t addr, uint32_t n, uint16_t *dst)
{
    return t->be->read_input(t->ctx, addr, n, dst);
}

int msid_mb_read_holding(const msid_mb_transport *t, uint32_t addr, uint32_t n, uint16_t *dst)
{
    return t->be->read_holding(t->ctx, addr, n, dst);
}

int msid_mb_write_holding(const msid_mb_transport *t, uint32_t addr, uint32_t n, const uint16_t *src)
{
    return t->be->write_holding(t->ctx, addr, n, src);
}

int msid_mb_write_read(const msid_mb_transport *t, uint32_t waddr, uint32_t nw, const uint16_t *src, uint32_t raddr,
                       uint32_t nr, uint16_t *dst)
{
    if (!t->be->write_read) return -MSID_DAQ_E_NOSUPPORT;
    return t->be->write_read(t->ctx, waddr, nw, src, raddr, nr, dst);
}

void msid_mb_set_timeouts(const msid_mb_transport *t, uint32_t response_ms, uint32_t byte_ms)
{
    if (t->be->set_timeouts) t->be->set_timeouts(t->ctx, response_ms ? response_ms : 1, byte_ms ? byte_ms : 1);
}

void msid_mb_flush(const msid_mb_transport *t) { t->be->flush(t->ctx); }

int msid_mb_reconnect(const msid_mb_transport *t) { return t->be->reconnect(t->ctx); }

uint32_t msid_mb_exception(const msid_mb_transport *t) { return t->be->exception(t->ctx); }

const char *msid_mb_error(const msid_mb_transport *t) { return t->be->error(t->ctx); }

const char *msid_mb_backend_name(const msid_mb_transport *t) { return t->be->name; }

void msid_mb_close(msid_mb_transport *t)
{
    if (!t->be) return;
    t->be->close(t->ctx);
    t->be = NULL;
}

uint64_t msid_mb_skipped(const msid_mb_transport *t) { return t->be->skipped ? t->be->skipped(t->ctx) : 0; }
