/* msid-devsim: a simulated msid device (firmware written for a host). main:
 * the command line, then one front end over the shared device core:
 *   main.c -> sim_can.c | sim_modbus.c -> sim_device.c -> plant.c, lib/, daq/ codecs.
 * See docs/can-protocol.md and docs/modbus-registers.md. */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "msid_daq/msid_mb_proto.h"
#include "sim_can.h"
#include "sim_modbus.h"
#include "sim_candbc.h"
#include "sim_canopen.h"
#include "sim_mbmap.h"
#include "msid_daq/msid_devdesc_file.h"

static void die(const char *m)
{
    fprintf(stderr, "msid-devsim: error: %s\n", m);
    exit(1);
}

/* ---- command line ------------------------------------------------------- */
static const char *USAGE =
    "usage: msid-devsim --iface IF [options]   (--version: print the version)\n"
    "  --iface IF            CAN interface (vcan0)\n"
    "  --base ID             base identifier, a multiple of 0x80 (default 0x200)\n"
    "  --plant FILE|builtin  plant (default: the built-in 4-state 2x2 DT plant)\n"
    "  --noise-y S           output noise std (default 0.05)   --noise-u S  input measurement noise std (0.002)\n"
    "  --noise-color A       AR(1) pole of the output noise, [0, 1) (0: white)\n"
    "  --seed N              noise seed (default 1)\n"
    "  --truth FILE          write the true FRF at the excited lines after each configuration\n"
    "  --report FILE         write counters (and injected faults) after each experiment and at exit\n"
    "  --drop-every K | --drop-frac F   drop every K-th sample frame, or each with probability F\n"
    "  --dup-every K         send every K-th sample frame twice\n"
    "  --reorder-every K     send every K-th sample frame after the next one (counted when a\n"
    "                        well-formed frame overtook it)\n"
    "  --malformed-every K   send every K-th sample frame with a wrong DLC\n"
    "  --error-every K       send an error frame (warning, passive, protocol, ack) after every K-th frame\n"
    "  --bus-off-at E:N[:D]  go bus-off at sample N of experiment E (0-based) for D samples (default 1), then restart\n"
    "  --restart-at E:N      restart the device at sample N of experiment E\n"
    "  --protocol-version V  pretend to speak protocol version V (tests)\n"
    "  --idle-exit S         exit after S seconds without host frames (default 0: never)\n"
    "  --rcvbuf BYTES        socket receive buffer\n"
    "Modbus device (msid-modbus/1, docs/modbus-registers.md) instead of CAN:\n"
    "  --modbus-tcp HOST:PORT | --modbus-rtu DEVICE   serve over Modbus TCP, or RTU on a serial port/pty\n"
    "  --baud N              RTU baud rate (default 115200)   --unit N  unit id (default 1)\n"
    "  --no-baud-emulation   RTU: reply at once (default: after the frames' wire time at --baud)\n"
    "  --ring N              ring capacity in samples (default: as many as the register map holds)\n"
    "  --est-mem BYTES       working memory for on-device estimation (extension estimate/1 of msid-modbus/1,\n"
    "                        `msid modbus measure --on-device`, and of msid-can/1, EST_CTRL SETUP; default 1 MiB)\n"
    "  --delay-every K:MS    answer every K-th request MS ms late\n"
    "  --exception-every K[:CODE]  answer every K-th request with exception CODE (default 6, busy)\n"
    "  --corrupt-every K     RTU: send every K-th reply with a bad CRC\n"
    "  --drop-at E:N         drop the connection (RTU: 1 s of silence) at sample N of experiment E\n"
    "  --stall-at E:N:D[:MS] at sample N of experiment E stop answering for MS ms (default 300) and write\n"
    "                        D samples regardless of the host, so the ring overruns\n"
    "  --never-done          (adversarial) write samples past K P and never report DONE\n"
    "  --answer-twice        (adversarial) send every reply twice\n"
    "  --index-back-at E:N   (adversarial) from sample N of experiment E report a write index 16 samples back\n"
    "  --bad-result          (adversarial) a NaN in the on-device result block\n"
    "  --garbage-tid-every K (adversarial, TCP) every K-th reply with a transaction id the host never sent\n"
    "  --drip-every K[:MS]   (adversarial) every K-th read reply one byte at a time, MS ms apart (default 2)\n"
    "  --truncate-every K    (adversarial) every K-th read reply cut to half its bytes\n"
    "  --oversize-every K    (adversarial) every K-th read reply 16 bytes longer than asked\n"
    "  --absurd-header-at E:N  (adversarial) from sample N of experiment E the header's TOTAL reads 0xFFFFFFF0\n"
    "  --restart-at E:N, --seed, --noise-*, --plant, --truth, --report, --idle-exit: as for CAN\n"
    "CAN adversarial modes:\n"
    "  --done-twice          send every DONE frame twice\n"
    "  --replay-done-at E:N  at sample N of experiment E send the last DONE frame again (a replay)\n"
    "  --lose-done E         do not send experiment E's DONE frame (lost on the bus): a QUERY answers DONE(E, n)\n";

/* (a second string: one literal would pass the 4095 characters a C compiler must support) */
static const char *USAGE_MAP =
    "A device with its own register map, described by msid-device/1 (docs/devices.md), that the host excites\n"
    "tick by tick (msid measure --map): the plant (a DT state space at the device's cycle rate, inputs = drive\n"
    "channels, outputs = output channels) runs on the device's own clock:\n"
    "  --map FILE            serve FILE's registers (with --modbus-tcp or --modbus-rtu)\n"
    "  --cycle-hz F          the device's cycle rate (default: the description's cycle_hz, else 1000)\n"
    "  --clock-ppm X         the device's clock against the host's, ppm (default 0)\n"
    "  --no-fc23             refuse function 23 (read/write in one transaction) with exception 1\n"
    "  --drop-after N        close the connection instead of answering request N + 1\n"
    "  --die-after N         exit at once instead of answering request N + 1 (a device that dies)\n"
    "  --delay-every K:MS, --exception-every K[:CODE], --seed, --noise-y, --noise-u, --report, --idle-exit as above\n"
    "  --plant builtin-siso  a lightly damped two-mass plant (1 input, 1 output), for SISO descriptions\n"
    "A CAN description (transport = \"can\", its DBC): a node on --iface IF that takes the command messages and\n"
    "sends its status messages once per cycle of its own clock:\n"
    "  --map FILE --iface IF serve FILE's DBC signals on IF\n"
    "  --drop-every K        (CAN) every K-th status cycle sends nothing\n"
    "  --late-every K[:US]   (CAN) every K-th status cycle's frames are sent US microseconds late (default 500)\n"
    "  --die-after N         (CAN) exit at once after N status cycles; --cycle-hz, --clock-ppm, --noise-*, --report,\n"
    "                        --idle-exit as for Modbus\n";
static const char USAGE_CO[] =
    "A CANopen node (CiA 301, a CiA 402 servo drive stepping a two-mass plant once per SYNC):\n"
    "  --canopen N --iface IF  serve node N (1..127) on IF\n"
    "  --eds FILE            its object dictionary (default: the tests' drive402.eds)\n"
    "  --sdo-abort IDX:SUB[:CODE]  abort SDO reads and writes of IDX:SUB with CODE (default 0x08000020)\n"
    "  --emcy-at N           at the N-th SYNC a drive fault: EMCY 0x2310, error register 0x03, state fault\n"
    "  --heartbeat-stop-after S  send no heartbeat S seconds (node clock) after boot-up\n"
    "  --refuse-map IDX:SUB  refuse mapping IDX:SUB into a PDO (object cannot be mapped)\n"
    "  --clock-ppm X         the node's own clock (heartbeat, inhibit time, SDO timeout) against the host's\n"
    "  --drop-every K        every K-th TPDO due is not sent; --report, --idle-exit as above\n"
    "  --late-sync-every K[:MS]  take every K-th SYNC MS ms (default 30) late, and the frames behind it in order\n"
    "  --noise-y S --seed N  white Gaussian noise of std S rad/s on the velocity it measures: reported (0x606C)\n"
    "                        and fed back by its velocity loop (CSV, CSP), whose gains follow the SYNC period 0x1006\n";

static uint64_t num_u(const char *opt, const char *v)
{
    char *e;
    errno = 0;
    const unsigned long long x = strtoull(v, &e, 0);
    if (!*v || *e || errno || v[0] == '-') {
        fprintf(stderr, "msid-devsim: error: %s: '%s' is not a non-negative integer\n", opt, v);
        exit(2);
    }
    return x;
}

static double num_d(const char *opt, const char *v, double lo, double hi)
{
    char *e;
    const double x = strtod(v, &e);
    if (!*v || *e || !(x >= lo && x <= hi)) {
        fprintf(stderr, "msid-devsim: error: %s: '%s' must be a number in [%g, %g]\n", opt, v, lo, hi);
        exit(2);
    }
    return x;
}

static void pair(const char *opt, const char *v, int *e, uint64_t *n, uint64_t *d)
{
    char buf[64];
    snprintf(buf, sizeof buf, "%s", v);
    char *a = strtok(buf, ":"), *b = strtok(NULL, ":"), *c = strtok(NULL, ":");
    if (!a || !b || (!d && c)) {
        fprintf(stderr, "msid-devsim: error: %s wants E:N%s (got '%s')\n", opt, d ? "[:D]" : "", v);
        exit(2);
    }
    *e = (int)num_u(opt, a);
    *n = num_u(opt, b);
    if (d) *d = c ? num_u(opt, c) : 1;
}

/* K:V or K (V = def) */
static void kv(const char *opt, const char *v, uint64_t *k, uint64_t *val, uint64_t def)
{
    char buf[64];
    snprintf(buf, sizeof buf, "%s", v);
    char *a = strtok(buf, ":"), *b = strtok(NULL, ":"), *c = strtok(NULL, ":");
    if (!a || c || (!b && def == UINT64_MAX)) {
        fprintf(stderr, "msid-devsim: error: %s wants K:%s (got '%s')\n", opt, def == UINT64_MAX ? "V" : "[V]", v);
        exit(2);
    }
    *k = num_u(opt, a);
    *val = b ? num_u(opt, b) : def;
}

/* IDX:SUB[:CODE] of an object dictionary entry (code: NULL when none is taken) */
static void entry_opt(const char *opt, const char *v, uint16_t *index, uint8_t *sub, uint32_t *code, uint32_t def)
{
    char buf[64];
    snprintf(buf, sizeof buf, "%s", v);
    char *a = strtok(buf, ":"), *b = strtok(NULL, ":"), *c = strtok(NULL, ":");
    if (!a || !b || (c && !code) || strtok(NULL, ":")) {
        fprintf(stderr, "msid-devsim: error: %s wants IDX:SUB%s (got '%s')\n", opt, code ? "[:CODE]" : "", v);
        exit(2);
    }
    const uint64_t i = num_u(opt, a), s = num_u(opt, b), k = c ? num_u(opt, c) : def;
    if (i < 1 || i > 0xFFFF || s > 0xFF || k > 0xFFFFFFFFu || (code && k == 0)) {
        fprintf(stderr, "msid-devsim: error: %s: '%s' is not an entry 0x0001..0xFFFF:0..0xFF%s\n", opt, v,
                code ? " with a non-zero 32-bit code" : "");
        exit(2);
    }
    *index = (uint16_t)i, *sub = (uint8_t)s;
    if (code) *code = (uint32_t)k;
}

static volatile sig_atomic_t stop_flag;
static void on_signal(int s) { (void)s; stop_flag = 1; }

static void load_plant(const char *plant, sim_plant_def *pd)
{
    if (!strcmp(plant, "builtin")) sim_builtin_plant(pd);
    else if (!strcmp(plant, "builtin-siso")) sim_builtin_siso_plant(pd);
    else {
        char err[512];
        if (sim_parse_plant(plant, pd, err, sizeof err) != 0) die(err);
    }
}

int main(int argc, char **argv)
{
    static sim_device dev;
    static _Alignas(64) uint8_t arena[48u << 20];   /* the device's fixed memory */
    sim_device_init(&dev, arena, sizeof arena);
    dev.stop = &stop_flag;
    sim_opts *const o = &dev.o;
    const char *plant = "builtin";
    const char *map = NULL;
    sim_canopen_opts co;
    memset(&co, 0, sizeof co);
    co.eds = MSID_DEVSIM_DEFAULT_EDS;
    int co_on = 0;
    sim_mapdev_opts mo = {0, 0, 0, 0, 0};
    uint64_t late_every = 0, late_us = 0;
    double co_noise = 0;   /* the CANopen node's velocity noise: none unless --noise-y says (the others' default is not its) */
    for (int i = 1; i < argc; ++i) {
        const char *a = argv[i];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) { fputs(USAGE, stdout); fputs(USAGE_MAP, stdout); fputs(USAGE_CO, stdout); return 0; }
        if (!strcmp(a, "--version")) {
            printf("msid-devsim %s (msid-can/%u, msid-modbus/%u)\n", MSID_VERSION, MSID_CAN_PROTO_VERSION,
                   MSID_MB_PROTO_VERSION);
            return 0;
        }
        if (!strcmp(a, "--no-baud-emulation")) { o->emulate_baud = 0; continue; }
        if (!strcmp(a, "--never-done")) { o->never_done = 1; continue; }
        if (!strcmp(a, "--answer-twice")) { o->answer_twice = 1; continue; }
        if (!strcmp(a, "--bad-result")) { o->bad_result = 1; continue; }
        if (!strcmp(a, "--done-twice")) { o->done_twice = 1; continue; }
        if (!strcmp(a, "--no-fc23")) { o->no_fc23 = 1; continue; }
        if (i + 1 >= argc) { fprintf(stderr, "msid-devsim: error: unknown option or missing value: %s\n%s", a, USAGE); return 2; }
        const char *v = argv[++i];
        if (!strcmp(a, "--iface")) o->iface = v;
        else if (!strcmp(a, "--base")) o->base = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--plant")) plant = v;
        else if (!strcmp(a, "--noise-y")) o->sigma_y = co_noise = num_d(a, v, 0, 1e6);
        else if (!strcmp(a, "--noise-u")) o->sigma_u = num_d(a, v, 0, 1e6);
        else if (!strcmp(a, "--noise-color")) o->color = num_d(a, v, 0, 0.999999);
        else if (!strcmp(a, "--seed")) o->seed = num_u(a, v);
        else if (!strcmp(a, "--truth")) o->truth = v;
        else if (!strcmp(a, "--report")) o->report = v;
        else if (!strcmp(a, "--drop-every")) o->drop_every = num_u(a, v);
        else if (!strcmp(a, "--drop-frac")) o->drop_frac = num_d(a, v, 0, 1);
        else if (!strcmp(a, "--dup-every")) o->dup_every = num_u(a, v);
        else if (!strcmp(a, "--reorder-every")) o->reorder_every = num_u(a, v);
        else if (!strcmp(a, "--malformed-every")) o->malformed_every = num_u(a, v);
        else if (!strcmp(a, "--error-every")) o->error_every = num_u(a, v);
        else if (!strcmp(a, "--bus-off-at")) pair(a, v, &o->busoff_exp, &o->busoff_at, &o->busoff_len);
        else if (!strcmp(a, "--restart-at")) pair(a, v, &o->restart_exp, &o->restart_at, NULL);
        else if (!strcmp(a, "--protocol-version")) o->version = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--idle-exit")) o->idle_exit = num_d(a, v, 0, 1e9);
        else if (!strcmp(a, "--rcvbuf")) o->rcvbuf = (int)num_u(a, v);
        else if (!strcmp(a, "--modbus-tcp")) o->mb_tcp = v;
        else if (!strcmp(a, "--map")) map = v;
        else if (!strcmp(a, "--canopen")) co.node = (unsigned)num_u(a, v), co_on = 1;
        else if (!strcmp(a, "--eds")) co.eds = v;
        else if (!strcmp(a, "--sdo-abort")) entry_opt(a, v, &co.f.abort_index, &co.f.abort_sub, &co.f.abort_code, 0x08000020u);
        else if (!strcmp(a, "--emcy-at")) co.f.emcy_at_sync = num_u(a, v);
        else if (!strcmp(a, "--heartbeat-stop-after")) co.f.hb_stop_after_s = num_d(a, v, 1e-3, 1e9);
        else if (!strcmp(a, "--late-sync-every")) kv(a, v, &co.f.late_sync_every, &co.f.late_sync_ms, 30);
        else if (!strcmp(a, "--refuse-map")) entry_opt(a, v, &co.f.refuse_index, &co.f.refuse_sub, NULL, 0);
        else if (!strcmp(a, "--cycle-hz")) mo.cycle_hz = num_d(a, v, 1e-3, 1e6);
        else if (!strcmp(a, "--clock-ppm")) mo.ppm = num_d(a, v, -1e4, 1e4);
        else if (!strcmp(a, "--drop-after")) o->drop_after = num_u(a, v);
        else if (!strcmp(a, "--late-every")) kv(a, v, &late_every, &late_us, 500);
        else if (!strcmp(a, "--die-after")) o->die_after = num_u(a, v);
        else if (!strcmp(a, "--modbus-rtu")) o->mb_rtu = v;
        else if (!strcmp(a, "--baud")) o->baud = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--unit")) o->unit = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--ring")) o->ring = (uint32_t)num_u(a, v);
        else if (!strcmp(a, "--est-mem")) o->est_mem = num_u(a, v);
        else if (!strcmp(a, "--delay-every")) kv(a, v, &o->delay_every, &o->delay_ms, UINT64_MAX);
        else if (!strcmp(a, "--exception-every")) kv(a, v, &o->exc_every, &o->exc_code, 6);
        else if (!strcmp(a, "--corrupt-every")) o->corrupt_every = num_u(a, v);
        else if (!strcmp(a, "--drop-at")) pair(a, v, &o->drop_exp, &o->drop_at, NULL);
        else if (!strcmp(a, "--index-back-at")) pair(a, v, &o->back_exp, &o->back_at, NULL);
        else if (!strcmp(a, "--garbage-tid-every")) o->garbage_tid_every = num_u(a, v);
        else if (!strcmp(a, "--drip-every")) kv(a, v, &o->drip_every, &o->drip_ms, 2);
        else if (!strcmp(a, "--truncate-every")) o->truncate_every = num_u(a, v);
        else if (!strcmp(a, "--oversize-every")) o->oversize_every = num_u(a, v);
        else if (!strcmp(a, "--absurd-header-at")) pair(a, v, &o->absurd_exp, &o->absurd_at, NULL);
        else if (!strcmp(a, "--replay-done-at")) pair(a, v, &o->replay_exp, &o->replay_at, NULL);
        else if (!strcmp(a, "--lose-done")) o->lose_done_exp = (int)num_d(a, v, 0, 255);
        else if (!strcmp(a, "--stall-at")) {
            uint64_t d4[4] = {0, 0, 0, 300};
            char buf[64];
            snprintf(buf, sizeof buf, "%s", v);
            int k = 0;
            for (char *t = strtok(buf, ":"); t && k < 5; t = strtok(NULL, ":")) d4[k < 4 ? k : 3] = num_u(a, t), ++k;
            if (k < 3 || k > 4) { fprintf(stderr, "msid-devsim: error: --stall-at wants E:N:D[:MS] (got '%s')\n", v); return 2; }
            o->stall_exp = (int)d4[0]; o->stall_at = d4[1]; o->stall_samples = d4[2]; o->stall_ms = d4[3];
        }
        else { fprintf(stderr, "msid-devsim: error: unknown option %s\n%s", a, USAGE); return 2; }
    }
    if (co_on) {
        if (!o->iface) die("--canopen N is served with --iface IF");
        if (map || o->mb_tcp || o->mb_rtu) die("--canopen takes none of --map, --modbus-tcp, --modbus-rtu");
        if (co.node < 1 || co.node > 127) die("--canopen: the node id must be 1..127");
        co.f.clock_ppm = mo.ppm;
        co.f.drop_every = o->drop_every;
        co.f.noise_vel = co_noise;   /* --noise-y: on the velocity the node reports (rad/s) */
        co.f.seed = o->seed;
        signal(SIGTERM, on_signal);
        signal(SIGINT, on_signal);
        return sim_canopen_main(&dev, &co);
    }
    if (map) {
        static msid_devdesc desc;
        char err[512];
        if (msid_devdesc_load(map, &desc, err, sizeof err) != 0) die(err);
        if (desc.transport == MSID_DEV_CANOPEN) die("--map: a CANopen drive is served with --canopen N --iface IF");
        if (desc.transport == MSID_DEV_CAN && !o->iface) die("--map: a CAN description is served with --iface IF");
        if (desc.transport == MSID_DEV_MODBUS && !o->mb_tcp && !o->mb_rtu)
            die("--map needs --modbus-tcp HOST:PORT or --modbus-rtu DEVICE");
        if ((o->iface != NULL) + (o->mb_tcp != NULL) + (o->mb_rtu != NULL) > 1)
            die("give one of --iface, --modbus-tcp, --modbus-rtu");
        if (!(mo.cycle_hz > 0)) mo.cycle_hz = isnan(desc.cycle_hz) ? 1000.0 : desc.cycle_hz;
        mo.sigma_y = o->sigma_y;
        mo.sigma_u = o->sigma_u;
        mo.seed = o->seed;
        load_plant(!strcmp(plant, "builtin") && desc.n_drive == 1 ? "builtin-siso" : plant, &dev.pd);
        signal(SIGTERM, on_signal);
        signal(SIGINT, on_signal);
        if (desc.transport == MSID_DEV_CAN) {
            const sim_candbc_faults cf = {o->drop_every, late_every, late_us, o->die_after};
            return sim_candbc_main(&dev, &desc, &mo, &cf);
        }
        return sim_mbmap_main(&dev, &desc, &mo);
    }
    if (o->mb_tcp || o->mb_rtu) {
        if (o->iface || (o->mb_tcp && o->mb_rtu)) die("give one of --iface, --modbus-tcp, --modbus-rtu");
        load_plant(plant, &dev.pd);
        signal(SIGTERM, on_signal);
        signal(SIGINT, on_signal);
        return sim_modbus_main(&dev);
    }
    if (!o->iface) { fprintf(stderr, "msid-devsim: error: missing --iface\n%s", USAGE); return 2; }
    if ((o->base & 0x7F) || o->base > 0x780) die("--base must be a multiple of 0x80 up to 0x780");
    if (o->version > 255) die("--protocol-version must be 0..255");
    load_plant(plant, &dev.pd);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    return sim_can_main(&dev);
}
