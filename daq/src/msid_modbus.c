/* Modbus TCP and RTU transports: libmodbus connects both and frames RTU; TCP requests and replies are framed
   by msid_mbap.c (stale and foreign replies skipped). Errors mapped to msid_daq_status. */
#define _DEFAULT_SOURCE
#include "msid_daq/msid_modbus.h"

#include <errno.h>
#include <modbus/modbus.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

const char *msid_mb_exception_name(uint32_t code)
{
    switch (code) {
    case 1: return "illegal function";
    case 2: return "illegal data address";
    case 3: return "illegal data value";
    case 4: return "server device failure";
    case 5: return "acknowledge (busy with a long operation)";
    case 6: return "server device busy";
    case 8: return "memory parity error";
    case 10: return "gateway path unavailable";
    case 11: return "gateway target device failed to respond";
    default: return "unknown exception";
    }
}

static int fail(msid_modbus *m, const char *what)
{
    const int e = errno;
    m->exc = 0;
    if (e >= EMBXILFUN && e <= EMBXGTAR) {
        m->exc = (uint32_t)(e - MODBUS_ENOBASE);
        snprintf(m->err, sizeof m->err, "%s: exception %u (%s)", what, m->exc, msid_mb_exception_name(m->exc));
        return -MSID_DAQ_E_EXCEPTION;
    }
    snprintf(m->err, sizeof m->err, "%s: %s", what, modbus_strerror(e));
    if (e == ETIMEDOUT) return -MSID_DAQ_E_TIMEOUT;
    if (e == EMBBADCRC) return -MSID_DAQ_E_CRC;
    if (e == EMBBADDATA || e == EMBMDATA || e == EMBBADEXC || e == EMBUNKEXC || e == EMBBADSLAVE)
        return -MSID_DAQ_E_BADDATA;
    return -MSID_DAQ_E_IO;
}

static int rd_input(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst)
{
    msid_modbus *m = ctx;
    if (n == 0 || n > MODBUS_MAX_READ_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    const int r = modbus_read_input_registers(m->mb, (int)addr, (int)n, dst);
    return r == (int)n ? 0 : r < 0 ? fail(m, "read input registers") : -MSID_DAQ_E_BADDATA;
}

static int rd_holding(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst)
{
    msid_modbus *m = ctx;
    if (n == 0 || n > MODBUS_MAX_READ_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    const int r = modbus_read_registers(m->mb, (int)addr, (int)n, dst);
    return r == (int)n ? 0 : r < 0 ? fail(m, "read holding registers") : -MSID_DAQ_E_BADDATA;
}

static int wr_holding(void *ctx, uint32_t addr, uint32_t n, const uint16_t *src)
{
    msid_modbus *m = ctx;
    if (n == 0 || n > MODBUS_MAX_WRITE_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    const int r = modbus_write_registers(m->mb, (int)addr, (int)n, src);
    return r == (int)n ? 0 : r < 0 ? fail(m, "write holding registers") : -MSID_DAQ_E_BADDATA;
}

/* ---- TCP: our own MBAP framing (msid_mbap.c), so that a stale or foreign reply is skipped, not taken
   for the answer. Request PDUs as the Modbus Application Protocol v1.1b3 specifies them:
   FC 03/04 section 6.3/6.4 (address, count), FC 16 section 6.12 (address, count, byte count, values). */
static int tcp_exchange(msid_modbus *m, const char *what, const uint8_t *req, size_t req_n, uint8_t *rsp, size_t *rsp_n)
{
    msid_mbap *c = &m->mbap;
    c->fd = modbus_get_socket(m->mb);
    m->exc = 0;
    const int rc = msid_mbap_request(c, req, req_n, rsp, rsp_n);
    if (rc < 0) {
        snprintf(m->err, sizeof m->err, "%s: %s", what, c->err);
        return rc;
    }
    if (rsp[0] == (req[0] | 0x80u) && *rsp_n == 2) {
        m->exc = rsp[1];
        snprintf(m->err, sizeof m->err, "%s: exception %u (%s)", what, m->exc, msid_mb_exception_name(m->exc));
        return -MSID_DAQ_E_EXCEPTION;
    }
    if (rsp[0] != req[0]) {
        snprintf(m->err, sizeof m->err, "%s: reply with function code %u to a request of function code %u", what,
                 rsp[0], req[0]);
        return -MSID_DAQ_E_BADDATA;
    }
    return 0;
}

static int tcp_read(msid_modbus *m, uint8_t fc, uint32_t addr, uint32_t n, uint16_t *dst, const char *what)
{
    if (n == 0 || n > MODBUS_MAX_READ_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    const uint8_t req[5] = {fc, (uint8_t)(addr >> 8), (uint8_t)addr, (uint8_t)(n >> 8), (uint8_t)n};
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    size_t len = 0;
    const int rc = tcp_exchange(m, what, req, sizeof req, rsp, &len);
    if (rc < 0) return rc;
    if (len != 2 + 2 * (size_t)n || rsp[1] != 2 * n) {
        snprintf(m->err, sizeof m->err, "%s: a reply of %zu bytes, byte count %u, to a read of %u registers", what, len,
                 rsp[1], n);
        return -MSID_DAQ_E_BADDATA;
    }
    for (uint32_t i = 0; i < n; ++i) dst[i] = (uint16_t)(rsp[2 + 2 * i] << 8 | rsp[3 + 2 * i]);
    return 0;
}

static int tcp_rd_input(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst)
{
    return tcp_read(ctx, 4, addr, n, dst, "read input registers");
}

static int tcp_rd_holding(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst)
{
    return tcp_read(ctx, 3, addr, n, dst, "read holding registers");
}

static int tcp_wr_holding(void *ctx, uint32_t addr, uint32_t n, const uint16_t *src)
{
    msid_modbus *m = ctx;
    if (n == 0 || n > MODBUS_MAX_WRITE_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    uint8_t req[6 + 2 * MODBUS_MAX_WRITE_REGISTERS], rsp[MSID_MBAP_MAX_PDU];
    req[0] = 16;
    req[1] = (uint8_t)(addr >> 8);
    req[2] = (uint8_t)addr;
    req[3] = (uint8_t)(n >> 8);
    req[4] = (uint8_t)n;
    req[5] = (uint8_t)(2 * n);
    for (uint32_t i = 0; i < n; ++i) {
        req[6 + 2 * i] = (uint8_t)(src[i] >> 8);
        req[7 + 2 * i] = (uint8_t)src[i];
    }
    size_t len = 0;
    const int rc = tcp_exchange(m, "write holding registers", req, 6 + 2 * (size_t)n, rsp, &len);
    if (rc < 0) return rc;
    if (len != 5 || memcmp(rsp + 1, req + 1, 4) != 0) {
        snprintf(m->err, sizeof m->err, "write holding registers: a reply that does not echo the address and count");
        return -MSID_DAQ_E_BADDATA;
    }
    return 0;
}

static uint64_t tcp_skipped(void *ctx) { return ((msid_modbus *)ctx)->mbap.skipped; }

static void flush_(void *ctx) { modbus_flush(((msid_modbus *)ctx)->mb); }

/* wait: the first connection, where a refused TCP connection (nothing listens yet: a device starting
 * up) is tried again; a reconnection during a run has the transport's own retries. */
static int connect_(msid_modbus *m, int wait)
{
    int rc = modbus_connect(m->mb);
    for (int waited = 0; wait && rc != 0 && !m->cfg.rtu && errno == ECONNREFUSED && waited < MSID_MODBUS_CONNECT_WAIT_MS;
         waited += 50) {
        const struct timespec t = {0, 50L * 1000 * 1000};
        nanosleep(&t, NULL);
        modbus_close(m->mb);
        rc = modbus_connect(m->mb);
    }
    if (rc == 0) {
        modbus_flush(m->mb);
        return 0;
    }
    if (m->cfg.rtu)
        snprintf(m->err, sizeof m->err, "cannot open the serial port %s: %s", m->device, modbus_strerror(errno));
    else
        snprintf(m->err, sizeof m->err, "cannot connect to %s:%d: %s", m->host, m->cfg.port, modbus_strerror(errno));
    return -MSID_DAQ_E_CONNECT;
}

static int reconnect_(void *ctx)
{
    msid_modbus *m = ctx;
    modbus_close(m->mb);
    return connect_(m, 0);
}

static uint32_t exc_(void *ctx) { return ((msid_modbus *)ctx)->exc; }
static const char *err_(void *ctx) { return ((msid_modbus *)ctx)->err; }

static void close_(void *ctx)
{
    msid_modbus *m = ctx;
    if (m->mb) {
        modbus_close(m->mb);
        modbus_free(m->mb);
        m->mb = NULL;
    }
}

static const msid_mb_backend TCP = {"tcp",        tcp_rd_input, tcp_rd_holding, tcp_wr_holding, flush_, reconnect_,
                                    exc_,         err_,         close_,         tcp_skipped};
static const msid_mb_backend RTU = {"rtu", rd_input, rd_holding, wr_holding, flush_, reconnect_, exc_, err_, close_, NULL};

int msid_modbus_open(msid_modbus *m, const msid_modbus_cfg *c)
{
    memset(m, 0, sizeof *m);
    m->cfg = *c;
    if (c->rtu) {
        if (!c->device || strlen(c->device) >= sizeof m->device || c->baud <= 0 ||
            (c->parity != 'N' && c->parity != 'E' && c->parity != 'O') || c->data_bits < 5 || c->data_bits > 8 ||
            c->stop_bits < 1 || c->stop_bits > 2 || c->unit < 1 || c->unit > 247) {
            snprintf(m->err, sizeof m->err, "bad RTU settings");
            return -MSID_DAQ_E_ARG;
        }
        snprintf(m->device, sizeof m->device, "%s", c->device);
        m->mb = modbus_new_rtu(m->device, c->baud, c->parity, c->data_bits, c->stop_bits);
    } else {
        if (!c->host || strlen(c->host) >= sizeof m->host || c->port <= 0 || c->port > 65535 || c->unit < 0 ||
            c->unit > 255) {
            snprintf(m->err, sizeof m->err, "bad TCP settings");
            return -MSID_DAQ_E_ARG;
        }
        snprintf(m->host, sizeof m->host, "%s", c->host);
        m->mb = modbus_new_tcp(m->host, c->port);
    }
    m->cfg.host = m->host;
    m->cfg.device = m->device;
    if (!m->mb) {
        snprintf(m->err, sizeof m->err, "libmodbus: %s", modbus_strerror(errno));
        return -MSID_DAQ_E_ARG;
    }
    modbus_set_error_recovery(m->mb, MODBUS_ERROR_RECOVERY_NONE);
    modbus_set_slave(m->mb, c->unit);
    modbus_set_response_timeout(m->mb, c->response_timeout_ms / 1000, (c->response_timeout_ms % 1000) * 1000);
    modbus_set_byte_timeout(m->mb, c->byte_timeout_ms / 1000, (c->byte_timeout_ms % 1000) * 1000);
    m->mbap.fd = -1;
    m->mbap.unit = (uint8_t)c->unit;
    m->mbap.response_timeout_ms = c->response_timeout_ms ? c->response_timeout_ms : 1;
    m->mbap.byte_timeout_ms = c->byte_timeout_ms ? c->byte_timeout_ms : 1;
    m->tr.be = c->rtu ? &RTU : &TCP;
    m->tr.ctx = m;
    const int r = connect_(m, 1);
    if (r < 0) {
        modbus_free(m->mb);
        m->mb = NULL;
    }
    return r;
}
