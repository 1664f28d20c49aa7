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
