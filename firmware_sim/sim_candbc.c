/* msid-devsim as a CAN node described by msid-device/1 and a DBC: a drive or ECU that msid measures with
 * host-timed excitation. The node runs its cycle on its own clock (sim_mapdev.c: the plant, the clock offset);
 * between cycles it takes every command frame the host sends (the latest setpoint of each drive channel is
 * applied from the next cycle on); at each cycle it sends its status messages with what the cycle published:
 * the outputs, the input it applied (read back), its cycle counter. Written as a node's firmware would be: one
 * loop, fixed memory, the frames packed by the DBC's layout. Faults: dropped and late status cycles, a node
 * that dies; the report holds the node's own applied setpoints, so that a test asserts the safe value in the
 * node's state. docs/devices.md. */
#define _GNU_SOURCE
#include "sim_candbc.h"

#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "msid_daq/msid_can_map.h"
#include "msid_daq/msid_socketcan.h"

typedef struct sim_candbc {
    sim_device *d;
    sim_mapdev dev;
    const msid_devdesc *desc;
    const sim_candbc_faults *f;
    msid_dbc dbc;
    msid_can_map map;          /* the description resolved against the DBC: which signal each channel is */
    msid_socketcan can;
    double last_command;       /* host time of the last command frame (s) */
    struct {
        uint64_t commands, status_cycles, frames_sent, dropped, late, send_failures, bad_commands;
        uint64_t commands_not_safe;   /* command frames that left a drive channel at another value than its safe one */
    } c;
} sim_candbc;

static void fatal(const char *what)
{
    fprintf(stderr, "msid-devsim: error: %s\n", what);
    exit(1);
}

static uint64_t dbc_mem[1u << 17];   /* 1 MiB: the DBC's tables */
static char dbc_text[4u << 20];

static void load_dbc(sim_candbc *s)
{
    FILE *fp = fopen(s->desc->dbc, "rb");
    if (!fp) {
        char e[700];
        snprintf(e, sizeof e, "cannot read the DBC %s", s->desc->dbc);
        fatal(e);
    }
    const size_t n = fread(dbc_text, 1, sizeof dbc_text, fp);
    fclose(fp);
    if (n == sizeof dbc_text) fatal("the DBC is larger than 4 MiB");
    if (msid_dbc_mem_size(dbc_text, n) > sizeof dbc_mem ||
        msid_dbc_init(&s->dbc, dbc_text, n, dbc_mem, sizeof dbc_mem) != 0) {
        char e[800];
        snprintf(e, sizeof e, "%s: %s", s->desc->dbc, s->dbc.err[0] ? s->dbc.err : "larger than 1 MiB of tables");
        fatal(e);
    }
    if (msid_can_map_init(&s->map, s->desc, &s->dbc, NULL) != 0) fatal(s->map.err);
}

/* ---- the report ------------------------------------------------------------------------------------ */

static void report_body(FILE *fp, const void *ctx)
{
    const sim_candbc *s = ctx;
    fprintf(fp, "{\"format\": \"msid-devsim-map-report/1\", \"transport\": \"can\", \"cycles\": %llu, "
                "\"commands\": %llu, \"status_cycles\": %llu, \"frames_sent\": %llu,\n",
            (unsigned long long)s->dev.cycles, (unsigned long long)s->c.commands,
            (unsigned long long)s->c.status_cycles, (unsigned long long)s->c.frames_sent);
    fprintf(fp, " \"commands_not_safe\": %llu, \"bad_commands\": %llu, \"send_failures\": %llu,\n",
            (unsigned long long)s->c.commands_not_safe, (unsigned long long)s->c.bad_commands,
            (unsigned long long)s->c.send_failures);
    fprintf(fp, " \"injected\": {\"dropped\": %llu, \"late\": %llu},\n", (unsigned long long)s->c.dropped,
            (unsigned long long)s->c.late);
    fprintf(fp, " \"cycle_hz\": %.17g, \"clock_ppm\": %.17g,\n \"setpoints\": {", s->dev.o.cycle_hz, s->dev.o.ppm);
    for (uint32_t i = 0; i < s->desc->n_drive; ++i)
        fprintf(fp, "%s\"%s\": %.17g", i ? ", " : "", s->desc->drive[i].name, s->dev.setpoint[i]);
    fprintf(fp, "}}\n");
}

/* ---- command frames -------------------------------------------------------------------------------- */

/* A command frame: every drive channel it carries becomes the setpoint (a multiplexed one when the frame's switch
 * selects it); a frame too short for a signal is refused whole. */
static void take_command(sim_candbc *s, const msid_can_frame *fr)
{
    const msid_devdesc *d = s->desc;
    for (uint32_t k = 0; k < s->map.n_cmd; ++k) {
        if (s->map.cmd[k].m->id != fr->id) continue;
        double v[MSID_DEV_MAX_DRIVE];
        for (uint32_t i = 0; i < d->n_drive; ++i) {
            v[i] = s->dev.setpoint[i];
            if (s->map.cmd_of[i] != k) continue;
            const msid_dbc_signal *sg = s->map.dsig[i];
            double phys;
            if (msid_dbc_present(&s->dbc, sg, fr->data, fr->len) != 1) continue;
            if (msid_dbc_decode(sg, fr->data, fr->len, &phys) != 0) {
                s->c.bad_commands++;
                return;
            }
            v[i] = phys * d->drive[i].scale + d->drive[i].offset;
        }
        s->c.commands++;
        int unsafe = 0;
        for (uint32_t i = 0; i < d->n_drive; ++i) {
            s->dev.setpoint[i] = v[i];
            const double q = 0.5 * fabs(s->map.dsig[i]->factor * d->drive[i].scale);   /* half a raw step */
            unsafe |= fabs(v[i] - d->drive[i].safe) > q + 1e-9 * (1.0 + fabs(d->drive[i].safe));
        }
        if (unsafe) s->c.commands_not_safe++;
        else s->c.commands_not_safe = 0;   /* counts the commands since the last safe one */
        s->last_command = sim_now_s();
        return;
    }
}

/* ---- status frames --------------------------------------------------------------------------------- */

/* A published value written into its signal; a value the signal cannot hold saturates at the signal's raw range,
 * as a node's firmware clamps. */
static void put(const msid_dbc_signal *sg, const msid_dev_chan *c, double v, uint8_t *data, size_t len)
{
    const double phys = (v - c->offset) / c->scale;
    if (msid_dbc_encode(sg, phys, data, len) == 0 || sg->type != MSID_DBC_INT || !isfinite(phys)) return;
    const double raw = (phys - sg->offset) / sg->factor;
    const double lo = sg->is_signed ? -ldexp(1.0, (int)sg->length - 1) : 0.0;
    const double hi = sg->is_signed ? ldexp(1.0, (int)sg->length - 1) - 1 : ldexp(1.0, (int)sg->length) - 1;
    const double r = raw < lo ? lo : hi;
    const int64_t ri = (int64_t)r;
    (void)msid_dbc_set_raw(sg, (uint64_t)ri & (sg->length >= 64 ? ~0ull : ((1ull << sg->length) - 1)), data, len);
}

/* The status messages of the cycle just run. */
static void send_status(sim_candbc *s)
{
    const msid_devdesc *d = s->desc;
    const uint64_t k = ++s->c.status_cycles;
    if (s->f->die_after && k > s->f->die_after) {   /* a node that dies: gone, no goodbye */
        sim_write_atomic(s->d->o.report, report_body, s);
        _exit(9);
    }
    if (s->f->drop_every && k % s->f->drop_every == 0) {
        s->c.dropped++;
        return;
    }
    if (s->f->late_every && k % s->f->late_every == 0) {
        s->c.late++;
        usleep((useconds_t)s->f->late_us);
    }
    for (uint32_t m = 0; m < s->map.n_st; ++m) {
        msid_can_frame fr;
        memset(&fr, 0, sizeof fr);
        const msid_dbc_message *msg = s->map.st[m].m;
        fr.id = msg->id;
        fr.len = (uint8_t)msg->dlc;
        if (fr.len > 8) fr.flags = MSID_CANF_FD;
        for (uint32_t q = 0; q < d->n_measure; ++q) {
            if (s->map.st_of[q] != m) continue;
            const msid_dbc_signal *sg = s->map.msig[q];
            if (d->measure[q].role == MSID_DEV_ROLE_COUNTER) {
                const uint64_t mask = sg->length >= 64 ? ~0ull : ((1ull << sg->length) - 1);
                (void)msid_dbc_set_raw(sg, (uint64_t)s->dev.value[q] & mask, fr.data, fr.len);
            } else {
                put(sg, &d->measure[q], s->dev.value[q], fr.data, fr.len);
            }
        }
        if (msid_can_send(&s->can.tr, &fr, 5) < 0) s->c.send_failures++;
        else s->c.frames_sent++;
    }
}

/* ---- the loop -------------------------------------------------------------------------------------- */

/* Host time of the start of device cycle n (the device's clock runs (1 + ppm 1e-6) times the host's). */
static double cycle_time(const sim_candbc *s, uint64_t n)
{
    return s->dev.t0 + (double)n / (s->dev.o.cycle_hz * (1.0 + 1e-6 * s->dev.o.ppm));
}

/* Take the command frames until host time `until` (s). */
static void listen_until(sim_candbc *s, double until)
{
    for (;;) {
        const double now = sim_now_s();
        if (now >= until || *s->d->stop) return;
        const double w = until - now;
        struct timespec ts = {(time_t)w, (long)((w - floor(w)) * 1e9)};
        struct pollfd p = {s->can.fd, POLLIN, 0};
        if (ppoll(&p, 1, &ts, NULL) <= 0) continue;
        msid_can_frame fr[16];
        const int n = msid_can_recv(&s->can.tr, fr, 16, 0);
        for (int i = 0; i < n; ++i)
            if (!(fr[i].id & MSID_CAN_ERR_FLAG)) take_command(s, &fr[i]);
    }
}

int sim_candbc_main(sim_device *d, const msid_devdesc *desc, const sim_mapdev_opts *mo, const sim_candbc_faults *f)
{
    static sim_candbc ctx;
    sim_candbc *s = &ctx;
    memset(s, 0, sizeof *s);
    s->d = d;
    s->desc = desc;
    s->f = f;
    load_dbc(s);
    char err[320];
    if (sim_mapdev_init(&s->dev, desc, &d->pd, mo, err, sizeof err) != 0) fatal(err);
    msid_socketcan_cfg sc;
    memset(&sc, 0, sizeof sc);
    sc.iface = d->o.iface;
    for (uint32_t k = 0; k < s->map.n_cmd && k < MSID_SOCKETCAN_MAX_FILTERS; ++k) {
        const uint32_t id = s->map.cmd[k].m->id;
        sc.filter_id[k] = id;
        sc.filter_mask[k] = (id & MSID_CAN_EFF_FLAG ? 0x1FFFFFFFu : 0x7FFu) | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
        sc.n_filters = (int)k + 1;
    }
    if (s->map.n_cmd > MSID_SOCKETCAN_MAX_FILTERS) sc.n_filters = 0;
    for (uint32_t k = 0; k < s->map.n_st; ++k) sc.fd_frames |= s->map.st[k].m->dlc > 8;
    for (uint32_t k = 0; k < s->map.n_cmd; ++k) sc.fd_frames |= s->map.cmd[k].m->dlc > 8;
    if (msid_socketcan_open(&s->can, &sc) < 0) fatal(s->can.err);
    printf("msid-devsim: ready on can %s (described by %s, DBC %s, cycle %g Hz, clock %+g ppm)\n", d->o.iface,
           desc->source, desc->dbc, s->dev.o.cycle_hz, s->dev.o.ppm);
    fflush(stdout);
    s->dev.t0 = sim_now_s();
    s->last_command = s->dev.t0;
    while (!*d->stop) {
        listen_until(s, cycle_time(s, s->dev.cycles));
        if (*d->stop) break;
        /* the cycles due by now (a node woken late runs the ones it slept through: its counter shows them) */
        sim_mapdev_advance(&s->dev, sim_now_s());
        send_status(s);
        if (d->o.idle_exit > 0 && sim_now_s() - s->last_command > d->o.idle_exit) break;
    }
    sim_write_atomic(d->o.report, report_body, s);
    msid_can_close(&s->can.tr);
    return 0;
}
