/* msid-devsim as a Modbus device with its own register map (msid-device/1): a PLC or drive that msid measures
 * with host-timed excitation. The registers the description names are served over libmodbus TCP or RTU
 * (real libmodbus on both ends); any other address is refused with exception 2, as a device refuses what it
 * does not map; only the drive channels' registers can be written. Each request first runs the device's cycles
 * due by its arrival (sim_mapdev.c), so the answer holds what the last cycle published. Faults: slow answers,
 * exception responses, no function 23, a dropped connection, a device that dies. docs/devices.md. */
#define _GNU_SOURCE
#include "sim_mbmap.h"
#include "sim_mb_server.h"

#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "msid_daq/msid_mb_proto.h"

typedef struct sim_mbmap {
    sim_device *d;
    sim_mapdev dev;
    const msid_devdesc *desc;
    uint16_t hr[65536], ir[65536];
    uint8_t hr_mapped[65536], ir_mapped[65536], hr_writable[65536];
    modbus_mapping_t map;
    sim_mb_server srv;
    modbus_t *mb;   /* srv's */
    int rtu;
    double last_request;
    struct {
        uint64_t requests, replies, exceptions, delayed, refused_address, refused_fc23, dropped, writes;
        uint64_t writes_not_safe;   /* writes that left a drive channel at another value than its safe one */
    } mc;
} sim_mbmap;

static void sleep_s(const sim_mbmap *m, double s) { sim_sleep_s(m->d->stop, s); }

/* ---- the register map ----------------------------------------------------------------------------- */

/* A value encoded into a channel's registers; a value its type cannot hold saturates, as a device's does. */
static void put_value(const msid_dev_chan *c, double v, uint16_t *regs)
{
    if (msid_dev_encode(c, v, regs) == 0) return;
    const double lo[] = {0, -32768.0, 0, -2147483648.0, 0}, hi[] = {0, 32767.0, 65535.0, 2147483647.0, 4294967295.0};
    if (c->type >= MSID_DEV_INT16 && c->type <= MSID_DEV_UINT32 && isfinite(v)) {
        const double raw = (v - c->offset) / c->scale;
        const double sat = raw < lo[c->type] ? lo[c->type] : hi[c->type];
        msid_dev_encode(c, sat * c->scale + c->offset, regs);
    }
}

static uint16_t *regs_of(sim_mbmap *m, const msid_dev_chan *c)
{
    return c->table == MSID_DEV_HOLDING ? &m->hr[c->addr] : &m->ir[c->addr];
}

static void publish(sim_mbmap *m)
{
    for (uint32_t q = 0; q < m->desc->n_measure; ++q) {
        const msid_dev_chan *c = &m->desc->measure[q];
        double v = m->dev.value[q];
        if (c->role == MSID_DEV_ROLE_COUNTER && c->type != MSID_DEV_FLOAT32 && c->type != MSID_DEV_FLOAT64) {
            /* a counter wraps at its register's range, as a device's does */
            const double M = msid_dev_type_regs(c->type) == 1 ? 65536.0 : 4294967296.0;
            v = fmod(v, M);
            if ((c->type == MSID_DEV_INT16 && v >= 32768.0) || (c->type == MSID_DEV_INT32 && v >= 2147483648.0))
                v -= M;
            v = v * c->scale + c->offset;
        }
        put_value(c, v, regs_of(m, c));
    }
}

/* The setpoints as the drive registers hold them (after a write). */
static void take_setpoints(sim_mbmap *m)
{
    int not_safe = 0;
    for (uint32_t i = 0; i < m->desc->n_drive; ++i) {
        const msid_dev_chan *c = &m->desc->drive[i];
        const double v = msid_dev_decode(c, &m->hr[c->addr]);
        if (isfinite(v)) m->dev.setpoint[i] = v;
        uint16_t safe[4];
        put_value(c, c->safe, safe);
        not_safe |= memcmp(safe, &m->hr[c->addr], 2 * msid_dev_type_regs(c->type)) != 0;
    }
    m->mc.writes_not_safe += (uint64_t)not_safe;
}

static void build_map(sim_mbmap *m)
{
    const msid_devdesc *d = m->desc;
    for (uint32_t i = 0; i < d->n_drive + d->n_measure; ++i) {
        const msid_dev_chan *c = i < d->n_drive ? &d->drive[i] : &d->measure[i - d->n_drive];
        const uint32_t n = msid_dev_type_regs(c->type);
        for (uint32_t k = 0; k < n; ++k) {
            if (c->table == MSID_DEV_HOLDING) {
                m->hr_mapped[c->addr + k] = 1;
                if (i < d->n_drive) m->hr_writable[c->addr + k] = 1;
            } else {
                m->ir_mapped[c->addr + k] = 1;
            }
        }
    }
    for (uint32_t i = 0; i < d->n_drive; ++i) put_value(&d->drive[i], d->drive[i].safe, &m->hr[d->drive[i].addr]);
    m->map.nb_registers = 65536;
    m->map.tab_registers = m->hr;
    m->map.nb_input_registers = 65536;
    m->map.tab_input_registers = m->ir;
    static uint8_t bits[1];
    m->map.tab_bits = m->map.tab_input_bits = bits;
}

/* Whether [a, a + n) is mapped (and, for a write, writable). */
static int range_ok(const uint8_t *flags, uint32_t a, uint32_t n)
{
    if (n == 0 || a + n > 65536u) return 0;
    for (uint32_t k = 0; k < n; ++k)
        if (!flags[a + k]) return 0;
    return 1;
}

/* The request's registers exist in the map: exception 2 otherwise (1 for function 23 when it is off). */
static int refusal(sim_mbmap *m, const uint8_t *q, int hl)
{
    const uint32_t fc = q[hl], a = (uint32_t)q[hl + 1] << 8 | q[hl + 2], n = (uint32_t)q[hl + 3] << 8 | q[hl + 4];
    switch (fc) {
    case 3: return range_ok(m->hr_mapped, a, n) ? 0 : 2;
    case 4: return range_ok(m->ir_mapped, a, n) ? 0 : 2;
    case 6: return range_ok(m->hr_writable, a, 1) ? 0 : 2;
    case 16: return range_ok(m->hr_writable, a, n) ? 0 : 2;
    case 23: {
        if (m->d->o.no_fc23) return 1;
        const uint32_t wa = (uint32_t)q[hl + 5] << 8 | q[hl + 6], wn = (uint32_t)q[hl + 7] << 8 | q[hl + 8];
        return range_ok(m->hr_mapped, a, n) && range_ok(m->hr_writable, wa, wn) ? 0 : 2;
    }
    default: return 1;
    }
}

/* ---- requests ------------------------------------------------------------------------------------ */

static void report_body(FILE *f, const void *ctx)
{
    const sim_mbmap *m = ctx;
    fprintf(f, "{\"format\": \"msid-devsim-map-report/1\", \"transport\": \"%s\", \"cycles\": %llu, \"requests\": %llu, "
               "\"replies\": %llu, \"writes\": %llu,\n",
            m->rtu ? "rtu" : "tcp", (unsigned long long)m->dev.cycles, (unsigned long long)m->mc.requests,
            (unsigned long long)m->mc.replies, (unsigned long long)m->mc.writes);
    fprintf(f, " \"writes_not_safe\": %llu,\n", (unsigned long long)m->mc.writes_not_safe);
    fprintf(f, " \"injected\": {\"exceptions\": %llu, \"delayed\": %llu, \"dropped\": %llu},\n",
            (unsigned long long)m->mc.exceptions, (unsigned long long)m->mc.delayed, (unsigned long long)m->mc.dropped);
    fprintf(f, " \"refused\": {\"address\": %llu, \"fc23\": %llu},\n", (unsigned long long)m->mc.refused_address,
            (unsigned long long)m->mc.refused_fc23);
    fprintf(f, " \"cycle_hz\": %.17g, \"clock_ppm\": %.17g,\n \"setpoints\": {", m->dev.o.cycle_hz, m->dev.o.ppm);
    for (uint32_t i = 0; i < m->desc->n_drive; ++i)
        fprintf(f, "%s\"%s\": %.17g", i ? ", " : "", m->desc->drive[i].name, m->dev.setpoint[i]);
    fprintf(f, "}}\n");
}

static void drop_clients(sim_mbmap *m)
{
    sim_mb_server_drop(&m->srv);
    m->mc.dropped++;
}

static void serve(sim_mbmap *m, const uint8_t *q, int len)
{
    const sim_opts *o = &m->d->o;
    m->mc.requests++;
    const uint64_t k = m->mc.requests;
    if (o->die_after && k > o->die_after) {   /* a device that dies: gone, no goodbye */
        sim_write_atomic(o->report, report_body, m);
        _exit(9);
    }
    if (o->drop_after && k == o->drop_after + 1) { drop_clients(m); return; }
    if (o->delay_every && k % o->delay_every == 0) {
        m->mc.delayed++;
        sleep_s(m, 1e-3 * (double)o->delay_ms);
    }
    m->last_request = sim_now_s();
    sim_mapdev_advance(&m->dev, m->last_request);
    publish(m);
    const int hl = modbus_get_header_length(m->mb);
    if (o->exc_every && k % o->exc_every == 0) {
        m->mc.exceptions++;
        modbus_reply_exception(m->mb, q, (unsigned)o->exc_code);
        return;
    }
    const int why = refusal(m, q, hl);
    if (why) {
        if (why == 1) m->mc.refused_fc23++;
        else m->mc.refused_address++;
        modbus_reply_exception(m->mb, q, (unsigned)why);
        return;
    }
    if (m->rtu && o->emulate_baud) {
        const uint32_t fc = q[hl], n = (uint32_t)q[hl + 3] << 8 | q[hl + 4];
        const double rq = fc == 16 ? 9.0 + 2 * n : fc == 23 ? 13.0 + 2 * ((uint32_t)q[hl + 7] << 8 | q[hl + 8]) : 8.0;
        const double rp = (fc == 3 || fc == 4 || fc == 23) ? 5.0 + 2 * n : 8.0;
        const double t35 = o->baud > 19200 ? 1.75e-3 : 35.0 / o->baud;
        sleep_s(m, (rq + rp) * 10.0 / o->baud + 2 * t35);
    }
    if (modbus_reply(m->mb, q, len, &m->map) < 0) return;
    m->mc.replies++;
    const uint32_t fc = q[hl];
    if (fc == 6 || fc == 16 || fc == 23) {
        m->mc.writes++;
        take_setpoints(m);
    }
}

static void open_server(sim_mbmap *m)
{
    const sim_opts *o = &m->d->o;
    const uint32_t unit = m->desc->unit ? m->desc->unit : o->unit;
    sim_mb_server_open(&m->srv, o, unit);
    m->mb = m->srv.mb;
    m->rtu = m->srv.rtu;
    if (m->rtu)
        printf("msid-devsim: ready on modbus-rtu %s (%u baud%s, unit %u, described by %s, cycle %g Hz)\n", o->mb_rtu,
               o->baud, o->emulate_baud ? " emulated" : "", unit, m->desc->source, m->dev.o.cycle_hz);
    else
        printf("msid-devsim: ready on modbus-tcp %s:%u (described by %s, cycle %g Hz)\n", m->srv.host, m->srv.port,
               m->desc->source, m->dev.o.cycle_hz);
    fflush(stdout);
}

static void serve_cb(void *ctx, const uint8_t *q, int len) { serve(ctx, q, len); }

int sim_mbmap_main(sim_device *d, const msid_devdesc *desc, const sim_mapdev_opts *mo)
{
    static sim_mbmap ctx;
    sim_mbmap *m = &ctx;
    memset(m, 0, sizeof *m);
    m->d = d;
    m->desc = desc;
    char err[320];
    if (sim_mapdev_init(&m->dev, desc, &d->pd, mo, err, sizeof err) != 0) sim_die(err, NULL);
    build_map(m);
    signal(SIGPIPE, SIG_IGN);
    open_server(m);
    m->last_request = sim_now_s();
    while (!*d->stop) {
        sim_mb_server_poll(&m->srv, 200, serve_cb, m);
        if (d->o.idle_exit > 0 && sim_now_s() - m->last_request > d->o.idle_exit) break;
    }
    sim_mapdev_advance(&m->dev, sim_now_s());
    sim_write_atomic(d->o.report, report_body, m);
    sim_mb_server_close(&m->srv);
    return 0;
}
