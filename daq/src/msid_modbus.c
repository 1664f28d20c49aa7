/* Modbus TCP and RTU transports: libmodbus connects both and frames RTU; TCP requests and replies are framed
   by msid_mbap.c (stale and foreign replies skipped); RTU drops what waits on the line before each request.
   Errors mapped to msid_daq_status. */
#define _DEFAULT_SOURCE
#include "msid_daq/msid_modbus.h"

#include <arpa/inet.h>
#include <errno.h>
#include <modbus/modbus.h>
#include <netdb.h>
#include <stdio.h>
#include <string.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
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

/* An RTU frame has no transaction id: an answer that came after its request timed out would be taken for the
   answer to the next request (same function, same count), and every read after it would be one request stale.
   Before a request nothing is owed to us, so whatever waits on the line is such an answer: dropped, counted.
   After a request that failed, its answer may still be on its way (a slow device, or one still answering
   earlier requests): a request sent now would meet it on the line, and a device that queues requests would
   fall further behind with every tick. So the line is first left quiet for a response timeout (at most
   RTU_QUIET_MAX_MS), whatever arrives meanwhile dropped, for at most RTU_DRAIN_ROUNDS quiet windows; the ticks
   this costs are counted as missed by the caller's clock. */
enum { RTU_QUIET_MAX_MS = 100, RTU_DRAIN_ROUNDS = 8 };

static void rtu_drop_stale(msid_modbus *m)
{
    const int fd = modbus_get_socket(m->mb);
    if (fd < 0) return;
    int waiting = 0;
    if (ioctl(fd, FIONREAD, &waiting) == 0 && waiting > 0) {
        tcflush(fd, TCIFLUSH);
        m->rtu_stale++;
    }
    if (!m->rtu_owed) return;
    m->rtu_owed = 0;
    uint32_t q = m->cfg.response_timeout_ms;
    const int quiet = (int)(q == 0 ? 1 : q > RTU_QUIET_MAX_MS ? RTU_QUIET_MAX_MS : q);
    for (int round = 0; round < RTU_DRAIN_ROUNDS; ++round) {
        struct pollfd p = {fd, POLLIN, 0};
        const int r = poll(&p, 1, quiet);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0 || !(p.revents & POLLIN)) return;   // quiet (or the line failed: the request will say so)
        tcflush(fd, TCIFLUSH);
        m->rtu_stale++;
    }
}

/* An RTU request that failed other than by an exception reply: its answer may still come (rtu_drop_stale). */
static int rtu_failed(msid_modbus *m, const char *what)
{
    const int rc = fail(m, what);
    if (rc != -MSID_DAQ_E_EXCEPTION) m->rtu_owed = 1;
    return rc;
}

static int rd_input(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst)
{
    msid_modbus *m = ctx;
    rtu_drop_stale(m);
    if (n == 0 || n > MODBUS_MAX_READ_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    const int r = modbus_read_input_registers(m->mb, (int)addr, (int)n, dst);
    return r == (int)n ? 0 : r < 0 ? rtu_failed(m, "read input registers") : -MSID_DAQ_E_BADDATA;
}

static int rd_holding(void *ctx, uint32_t addr, uint32_t n, uint16_t *dst)
{
    msid_modbus *m = ctx;
    rtu_drop_stale(m);
    if (n == 0 || n > MODBUS_MAX_READ_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    const int r = modbus_read_registers(m->mb, (int)addr, (int)n, dst);
    return r == (int)n ? 0 : r < 0 ? rtu_failed(m, "read holding registers") : -MSID_DAQ_E_BADDATA;
}

static int wr_holding(void *ctx, uint32_t addr, uint32_t n, const uint16_t *src)
{
    msid_modbus *m = ctx;
    rtu_drop_stale(m);
    if (n == 0 || n > MODBUS_MAX_WRITE_REGISTERS || addr + n > 65536u) return -MSID_DAQ_E_ARG;
    const int r = modbus_write_registers(m->mb, (int)addr, (int)n, src);
    return r == (int)n ? 0 : r < 0 ? rtu_failed(m, "write holding registers") : -MSID_DAQ_E_BADDATA;
}

/* ---- TCP: our own MBAP framing (msid_mbap.c), so that a stale or foreign reply is skipped, not taken
   for the answer. Request PDUs as the Modbus Application Protocol v1.1b3 specifies them:
   FC 03/04 section 6.3/6.4 (address, count), FC 16 section 6.12 (address, count, byte count, values). */
static int tcp_exchange(msid_modbus *m, const char *what, const uint8_t *req, size_t req_n, uint8_t *rsp, size_t *rsp_n)
{
    msid_mbap *c = &m->mbap;
    c->fd = modbus_get_socket(m->mb);
    m->exc = 0;
    if (c->fd < 0) {   /* a reconnect after a lost connection failed: an I/O error, not a bad request */
        snprintf(m->err, sizeof m->err, "%s: not connected (the device closed the connection and refused a new one)",
                 what);
        return -MSID_DAQ_E_IO;
    }
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

/* The registers of a read reply (FC 03, 04, 23: function, byte count, values). */
static int read_reply(msid_modbus *m, const char *what, const uint8_t *rsp, size_t len, uint32_t n, uint16_t *dst)
{
    if (len != 2 + 2 * (size_t)n || rsp[1] != 2 * n) {
        snprintf(m->err, sizeof m->err, "%s: a reply of %zu bytes, byte count %u, to a read of %u registers", what, len,
                 rsp[1], n);
        return -MSID_DAQ_E_BADDATA;
    }
    for (uint32_t i = 0; i < n; ++i) dst[i] = (uint16_t)(rsp[2 + 2 * i] << 8 | rsp[3 + 2 * i]);
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
    return read_reply(m, what, rsp, len, n, dst);
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

/* FC 23 (section 6.17): read address, read count, write address, write count, byte count, values; the reply
 * carries the read registers. */
static int tcp_write_read(void *ctx, uint32_t waddr, uint32_t nw, const uint16_t *src, uint32_t raddr, uint32_t nr,
                          uint16_t *dst)
{
    msid_modbus *m = ctx;
    if (nw == 0 || nw > 121 || nr == 0 || nr > 125 || waddr + nw > 65536u || raddr + nr > 65536u)
        return -MSID_DAQ_E_ARG;
    uint8_t req[10 + 2 * 121], rsp[MSID_MBAP_MAX_PDU];
    const uint8_t head[10] = {23, (uint8_t)(raddr >> 8), (uint8_t)raddr, (uint8_t)(nr >> 8), (uint8_t)nr,
                              (uint8_t)(waddr >> 8), (uint8_t)waddr, (uint8_t)(nw >> 8), (uint8_t)nw, (uint8_t)(2 * nw)};
    memcpy(req, head, sizeof head);
    for (uint32_t i = 0; i < nw; ++i) {
        req[10 + 2 * i] = (uint8_t)(src[i] >> 8);
        req[11 + 2 * i] = (uint8_t)src[i];
    }
    size_t len = 0;
    const int rc = tcp_exchange(m, "read/write registers", req, 10 + 2 * (size_t)nw, rsp, &len);
    if (rc < 0) return rc;
    return read_reply(m, "read/write registers", rsp, len, nr, dst);
}

static int rtu_write_read(void *ctx, uint32_t waddr, uint32_t nw, const uint16_t *src, uint32_t raddr, uint32_t nr,
                          uint16_t *dst)
{
    msid_modbus *m = ctx;
    rtu_drop_stale(m);
    if (nw == 0 || nw > 121 || nr == 0 || nr > 125 || waddr + nw > 65536u || raddr + nr > 65536u)
        return -MSID_DAQ_E_ARG;
    const int r = modbus_write_and_read_registers(m->mb, (int)waddr, (int)nw, src, (int)raddr, (int)nr, dst);
    return r == (int)nr ? 0 : r < 0 ? rtu_failed(m, "read/write registers") : -MSID_DAQ_E_BADDATA;
}

static void set_timeouts_(void *ctx, uint32_t response_ms, uint32_t byte_ms)
{
    msid_modbus *m = ctx;
    modbus_set_response_timeout(m->mb, response_ms / 1000, (response_ms % 1000) * 1000);
    modbus_set_byte_timeout(m->mb, byte_ms / 1000, (byte_ms % 1000) * 1000);
    m->mbap.response_timeout_ms = response_ms;
    m->mbap.byte_timeout_ms = byte_ms;
    m->cfg.response_timeout_ms = response_ms;
    m->cfg.byte_timeout_ms = byte_ms;
}

static uint64_t tcp_skipped(void *ctx) { return ((msid_modbus *)ctx)->mbap.skipped; }
static uint64_t rtu_skipped(void *ctx) { return ((msid_modbus *)ctx)->rtu_stale; }

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
        snprintf(m->err, sizeof m->err, strchr(m->host, ':') ? "cannot connect to [%s]:%d: %s" : "cannot connect to %s:%d: %s",
                 m->host, m->cfg.port, modbus_strerror(errno));
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

static const msid_mb_backend TCP = {"tcp",       tcp_rd_input, tcp_rd_holding, tcp_wr_holding, flush_,
                                    reconnect_,  exc_,         err_,           close_,         tcp_skipped,
                                    tcp_write_read, set_timeouts_};
static const msid_mb_backend RTU = {"rtu",  rd_input, rd_holding, wr_holding,     flush_,       reconnect_,
                                    exc_,   err_,     close_,     rtu_skipped,    rtu_write_read, set_timeouts_};

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
        /* The name or address (IPv4 or IPv6) is resolved here first, so that a host that does not resolve is
           said so (libmodbus's protocol-independent backend would report a refused connection); the backend
           then connects to each of its addresses in turn. */
        struct addrinfo hints, *ai = NULL;
        memset(&hints, 0, sizeof hints);
        hints.ai_family = AF_UNSPEC;
        hints.ai_socktype = SOCK_STREAM;
        const int g = getaddrinfo(m->host, NULL, &hints, &ai);
        if (g != 0 || !ai) {
            snprintf(m->err, sizeof m->err, "cannot resolve host '%s': %s", m->host,
                     g != 0 ? gai_strerror(g) : "no address");
            if (ai) freeaddrinfo(ai);
            return -MSID_DAQ_E_CONNECT;
        }
        freeaddrinfo(ai);
        char service[8];
        snprintf(service, sizeof service, "%d", c->port);
        m->mb = modbus_new_tcp_pi(m->host, service);
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
