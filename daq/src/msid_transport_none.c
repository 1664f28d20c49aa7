/* Transports left out of the build (CMake -DMSID_WITH_MODBUS=OFF, or AUTO without libmodbus;
 * -DMSID_WITH_CAN=OFF): the same entry points, failing with one message that names the option.
 * Everything else of daq/ (codecs, decoders, candump replay, the ring poller) is always built. */
#include "msid_daq/msid_modbus.h"
#include "msid_daq/msid_socketcan.h"
#include "msid_daq/msid_co_sync.h"
#include "msid_daq/msid_can_bitrate.h"

#include <stdio.h>
#include <string.h>

#if !MSID_WITH_MODBUS
const char *msid_mb_exception_name(uint32_t code)
{
    (void)code;
    return "exception (names not built: MSID_WITH_MODBUS=OFF)";
}

int msid_modbus_open(msid_modbus *m, const msid_modbus_cfg *cfg)
{
    memset(m, 0, sizeof *m);
    if (cfg) m->cfg = *cfg;
    snprintf(m->err, sizeof m->err,
             "this msid was built without Modbus: install libmodbus-dev and configure with -DMSID_WITH_MODBUS=ON");
    return -MSID_DAQ_E_NOSUPPORT;
}
#endif

#if !MSID_WITH_CAN
int msid_socketcan_open(msid_socketcan *s, const msid_socketcan_cfg *cfg)
{
    (void)cfg;
    memset(s, 0, sizeof *s);
    snprintf(s->err, sizeof s->err, "this msid was built without SocketCAN: configure with -DMSID_WITH_CAN=ON");
    return -MSID_DAQ_E_NOSUPPORT;
}

int msid_co_sync_start(msid_co_sync *s, const char *iface, uint32_t period_us, unsigned counter)
{
    (void)iface, (void)period_us, (void)counter;
    memset(s, 0, sizeof *s);
    s->fd = -1;
    snprintf(s->err, sizeof s->err, "this msid was built without SocketCAN: configure with -DMSID_WITH_CAN=ON");
    return -MSID_DAQ_E_NOSUPPORT;
}

void msid_co_sync_stop(msid_co_sync *s) { (void)s; }

static int bitrate_none(msid_can_bitrate *out)
{
    if (!out) return -MSID_DAQ_E_ARG;
    memset(out, 0, sizeof *out);
    out->status = MSID_CAN_BITRATE_FAILED;
    snprintf(out->err, sizeof out->err, "this msid was built without SocketCAN: configure with -DMSID_WITH_CAN=ON");
    return -MSID_DAQ_E_NOSUPPORT;
}

int msid_can_bitrate_parse(const void *reply, size_t len, msid_can_bitrate *out)
{
    (void)reply, (void)len;
    return bitrate_none(out);
}

int msid_can_bitrate_query(const char *iface, msid_can_bitrate *out)
{
    (void)iface;
    return bitrate_none(out);
}

const char *msid_can_bitrate_status_name(msid_can_bitrate_status s)
{
    return s == MSID_CAN_BITRATE_FAILED ? "failed" : "(names not built: MSID_WITH_CAN=OFF)";
}
#endif
