/* msid-devsim's CANopen front end: one sim_co_node on SocketCAN, its timers run between frames. */
#define _GNU_SOURCE
#include "sim_canopen.h"

#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "msid_daq/msid_socketcan.h"

typedef struct sim_canopen {
    sim_co_node node;
    msid_socketcan can;
    uint64_t send_busy;
    msid_co_od_entry entries[SIM_CO_OD_MAX];
    msid_co_eds eds;
} sim_canopen;

static void fatal(const char *m)
{
    fprintf(stderr, "msid-devsim: error: %s\n", m);
    exit(1);
}

static void send_frame(void *ctx, const msid_can_frame *f)
{
    sim_canopen *s = ctx;
    const int r = msid_can_send(&s->can.tr, f, 100);
    if (r == -MSID_DAQ_E_BUSY) { s->send_busy++; return; }
    if (r < 0) {
        fprintf(stderr, "msid-devsim: error: send: %s\n", msid_can_error(&s->can.tr));
        exit(1);
    }
}

static void report_body(FILE *fp, const void *ctx)
{
    const sim_canopen *s = ctx;
    const sim_co_counts *c = &s->node.cnt;
    fprintf(fp,
            "{\"syncs\": %llu, \"tpdo_sent\": %llu, \"tpdo_dropped\": %llu, \"tpdo_inhibited\": %llu, "
            "\"rpdo_taken\": %llu, \"rpdo_bad\": %llu, \"heartbeats\": %llu, \"emcy_sent\": %llu, \"boots\": %llu, "
            "\"sdo_aborts\": %llu, \"send_busy\": %llu, \"late_syncs\": %llu, \"sdo_downloads\": %llu}\n",
            (unsigned long long)c->syncs, (unsigned long long)c->tpdo_sent, (unsigned long long)c->tpdo_dropped,
            (unsigned long long)c->tpdo_inhibited, (unsigned long long)c->rpdo_taken, (unsigned long long)c->rpdo_bad,
            (unsigned long long)c->heartbeats, (unsigned long long)c->emcy_sent, (unsigned long long)c->boots,
            (unsigned long long)s->node.sdo.aborts_sent, (unsigned long long)s->send_busy,
            (unsigned long long)c->late_syncs, (unsigned long long)c->sdo_downloads);
}

int sim_canopen_main(sim_device *d, const sim_canopen_opts *o)
{
    static sim_canopen ctx;
    sim_canopen *s = &ctx;
    if (msid_co_eds_load(o->eds, &s->eds, s->entries, SIM_CO_OD_MAX) != 0) fatal(s->eds.err);
    msid_socketcan_cfg sc;
    memset(&sc, 0, sizeof sc);
    sc.iface = d->o.iface;
    if (msid_socketcan_open(&s->can, &sc) < 0) fatal(s->can.err);
    char err[400];
    double last_frame = sim_now_s();
    if (sim_co_node_init(&s->node, &s->eds, o->node, &o->f, send_frame, s, 1e3 * last_frame, err, sizeof err) != 0)
        fatal(err);
    printf("msid-devsim: ready on can %s (CANopen node %u, EDS %s, clock %+g ppm)\n", d->o.iface, o->node, o->eds,
           o->f.clock_ppm);
    fflush(stdout);
    while (!*d->stop) {
        const double now = sim_now_s();
        double w = sim_co_node_next_ms(&s->node) * 1e-3 - now;
        if (!(w < 0.2)) w = 0.2;   /* look at the stop flag and --idle-exit often enough */
        if (w < 0) w = 0;
        struct timespec ts = {(time_t)w, (long)((w - floor(w)) * 1e9)};
        struct pollfd p = {s->can.fd, POLLIN, 0};
        if (ppoll(&p, 1, &ts, NULL) > 0) {
            msid_can_frame fr[16];
            const int n = msid_can_recv(&s->can.tr, fr, 16, 0);
            for (int i = 0; i < n; ++i) {
                if (fr[i].id & MSID_CAN_ERR_FLAG) continue;
                last_frame = sim_now_s();
                sim_co_node_rx(&s->node, &fr[i], 1e3 * last_frame);
            }
        }
        sim_co_node_poll(&s->node, 1e3 * sim_now_s());
        if (d->o.idle_exit > 0 && sim_now_s() - last_frame > d->o.idle_exit) break;
    }
    sim_write_atomic(d->o.report, report_body, s);
    msid_can_close(&s->can.tr);
    return 0;
}
