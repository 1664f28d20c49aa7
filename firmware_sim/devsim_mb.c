/* msid-devsim's Modbus front end: the same device (design from parameter records,
 * excitation from lib/, plant, noise) served as msid-modbus/1 over libmodbus TCP or
 * RTU, with fault injection. Fixed memory: the register map is static (a
 * modbus_mapping_t over static arrays). See docs/modbus-registers.md. */
#define _GNU_SOURCE
#include "devsim.h"

#include <arpa/inet.h>
#include <errno.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "msid_daq/msid_mb_proto.h"

#define MAX_CLIENTS 8

static uint16_t HR[MSID_MB_HR_COUNT];
static uint16_t IR[65536];
static uint8_t served[65536];            /* ring slot read by the host since it was written */
static modbus_mapping_t MAP;
static modbus_t *MB;
static int rtu, listen_fd = -1, clients[MAX_CLIENTS], n_clients;

static uint32_t mstate = MSID_MB_STATE_IDLE, merr, mdetail, mexp;
static uint32_t enc, word_order, R, W;   /* latched at commit */
static uint64_t w, s0, overruns;         /* write index and segment start (run), overruns (run) */
static uint32_t segment, restarts_total, cfg_records;
static uint16_t cmd_done, cfg_done;
static int restart_done, drop_done, stall_done;
static uint64_t stall_force;
static double stall_until, silent_until, last_request;

static struct {
    uint64_t requests, replies, unanswered, delayed, dropped, exceptions, corrupted, stalls, stall_samples;
    uint64_t restarts, overrun_samples, samples, experiments_done;
} MC;
#define MAX_RANGES 256
static struct { uint32_t e; uint64_t a, b; } ranges[MAX_RANGES];   /* overwritten unread: [a, b) of experiment e */
static int n_ranges;

static void die(const char *what, const char *detail)
{
    fprintf(stderr, "msid-devsim: error: %s%s%s\n", what, detail ? ": " : "", detail ? detail : "");
    exit(1);
}

static void sleep_s(double s)
{
    if (s <= 0) return;
    struct timespec t = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    while (nanosleep(&t, &t) != 0 && errno == EINTR && !stop_flag) {}
}

/* ---- reports -------------------------------------------------------------- */
static void report_body(FILE *f)
{
    fprintf(f, "{\"format\": \"msid-devsim-modbus-report/1\", \"transport\": \"%s\", \"config_crc\": %u,\n",
            rtu ? "rtu" : "tcp", configured ? CFG.crc : 0);
    fprintf(f, " \"requests\": %llu, \"replies\": %llu, \"unanswered\": %llu, \"samples\": %llu, "
               "\"experiments_done\": %llu, \"ring_samples\": %u, \"sample_regs\": %u,\n",
            (unsigned long long)MC.requests, (unsigned long long)MC.replies, (unsigned long long)MC.unanswered,
            (unsigned long long)MC.samples, (unsigned long long)MC.experiments_done, R, W);
    fprintf(f, " \"injected\": {\"delayed\": %llu, \"dropped\": %llu, \"exceptions\": %llu, \"corrupted\": %llu, "
               "\"stalls\": %llu, \"stall_samples\": %llu, \"restarts\": %llu},\n",
            (unsigned long long)MC.delayed, (unsigned long long)MC.dropped, (unsigned long long)MC.exceptions,
            (unsigned long long)MC.corrupted, (unsigned long long)MC.stalls, (unsigned long long)MC.stall_samples,
            (unsigned long long)MC.restarts);
    fprintf(f, " \"overrun_samples\": %llu, \"overrun_ranges\": [", (unsigned long long)MC.overrun_samples);
    for (int i = 0; i < n_ranges; ++i)
        fprintf(f, "%s[%u, %llu, %llu]", i ? ", " : "", ranges[i].e, (unsigned long long)ranges[i].a,
                (unsigned long long)ranges[i].b);
    fprintf(f, "]}\n");
}

/* ---- the register map ------------------------------------------------------ */
static void update_header(void)
{
    msid_mb_header h;
    memset(&h, 0, sizeof h);
    h.magic = MSID_MB_MAGIC;
    h.version = MSID_MB_PROTO_VERSION;
    h.state = mstate;
    h.experiment = mexp;
    h.error = merr;
    h.detail = mdetail;
    h.nu = PD.nu;
    h.ny = PD.ny;
    h.encoding = enc;
    h.word_order = word_order;
    h.sample_regs = W;
    h.ring_addr = MSID_MB_RING_ADDR;
    h.ring_samples = R;
    h.write_index = (uint32_t)(w - (O.back_exp == (int)mexp && n_sample >= O.back_at && w >= 16 ? 16 : 0));
    h.seg_start = (uint32_t)s0;
    h.segment = segment & 0xFFFFu;
    h.restarts = restarts_total & 0xFFFFu;
    h.overruns = (uint32_t)overruns;
    h.period_count = configured && DES.period ? (uint32_t)((w - s0) / DES.period) : 0;
    h.total = (uint32_t)n_total;
    h.crc = configured ? CFG.crc : 0;
    h.period = configured ? DES.period : 0;
    h.cmd_done = cmd_done;
    h.cfg_done = cfg_done;
    h.cfg_records = cfg_records;
    h.rate = configured ? CFG.rate_hz : 0;
    h.lines = configured ? DES.n_lines : 0;
    h.experiments = configured ? DES.n_experiments : 0;
    h.periods = configured ? CFG.periods : 0;
    msid_mb_header_encode(IR, &h);
}

static void fail_state(uint32_t err, uint32_t detail)
{
    mstate = MSID_MB_STATE_ERROR;
    merr = err;
    mdetail = detail;
}

static void apply_records(void)
{
    uint32_t n = HR[MSID_MB_HR_CFG_COUNT];
    if (n > MSID_MB_CFG_RECORDS) n = MSID_MB_CFG_RECORDS;
    uint8_t rec[MSID_MB_CFG_RECORDS][8];
    msid_mb_unpack_records(rec, HR + MSID_MB_HR_CFG_REC, n);
    for (uint32_t i = 0; i < n; ++i) {
        if (rec[i][0] == MSID_CAN_P_BEGIN) cfg_records = 0, merr = mdetail = 0;
        const int r = msid_params_feed(&CFG, rec[i], 8, MSID_CAN_PROTO_VERSION);
        cfg_records++;
        if (r < 0) {
            configured = 0;
            fail_state((uint32_t)-r, 0);
            return;
        }
        if (r == 1) {
            const uint32_t e = HR[MSID_MB_HR_ENCODING], wo = HR[MSID_MB_HR_WORD_ORDER];
            if (!msid_mb_value_regs(e) || wo > MSID_MB_DCBA) { configured = 0; fail_state(MSID_CAN_ERR_CFG, 0); return; }
            uint32_t ms;
            const uint32_t err = sim_configure(&ms);
            if (err) { fail_state(err, ms); return; }
            enc = e;
            word_order = wo;
            W = msid_mb_sample_regs(enc, PD.nu + PD.ny);
            R = msid_mb_ring_samples(W);
            if (O.ring && O.ring < R) R = O.ring;
            mstate = MSID_MB_STATE_CONFIGURED;
            merr = mdetail = 0;
        }
    }
}

static void execute(void)
{
    const uint32_t cmd = HR[MSID_MB_HR_CMD], e = HR[MSID_MB_HR_CMD_EXP];
    const uint32_t periods = msid_mb_get_u32(HR + MSID_MB_HR_CMD_PERIODS);
    if (cmd == MSID_MB_CMD_START) {
        if (mstate == MSID_MB_STATE_RUNNING) return;
        if (!configured) { fail_state(MSID_CAN_ERR_NOT_CONFIGURED, 0); return; }
        const int err = sim_start(e, periods);
        if (err) { fail_state((uint32_t)err, 0); return; }
        mexp = e;
        w = s0 = overruns = 0;
        segment = 0;
        restart_done = drop_done = stall_done = 0;
        stall_force = 0;
        memset(served, 0, sizeof served);
        mstate = MSID_MB_STATE_RUNNING;
        merr = mdetail = 0;
    } else if (cmd == MSID_MB_CMD_STOP) {
        if (mstate == MSID_MB_STATE_RUNNING) mstate = MSID_MB_STATE_CONFIGURED;
    } else if (cmd == MSID_MB_CMD_RESET) {
        configured = 0;
        msid_params_reset(&CFG);
        mstate = MSID_MB_STATE_IDLE;
        merr = mdetail = 0;
    }
}

/* ---- sample production ------------------------------------------------------ */
static void write_sample(void)
{
    const uint32_t C = PD.nu + PD.ny, vr = msid_mb_value_regs(enc);
    double row[MSID_MAX_CHANNELS];
    sim_row(row);
    const uint32_t slot = (uint32_t)(w % R);
    if (w >= R && !served[slot]) {
        const uint64_t lost = w - R;
        overruns++;
        MC.overrun_samples++;
        if (n_ranges > 0 && ranges[n_ranges - 1].e == mexp && ranges[n_ranges - 1].b == lost) ranges[n_ranges - 1].b++;
        else if (n_ranges < MAX_RANGES) { ranges[n_ranges].e = mexp; ranges[n_ranges].a = lost; ranges[n_ranges].b = lost + 1; n_ranges++; }
    }
    uint16_t *s = IR + MSID_MB_RING_ADDR + (size_t)slot * W;
    s[0] = (uint16_t)w;
    for (uint32_t c = 0; c < C; ++c) msid_mb_encode_value(s + 1 + c * vr, row[c], enc, word_order, (double)CFG.scale);
    served[slot] = 0;
    w++;
    n_sample++;
    MC.samples++;
    if (n_sample >= n_total && !O.never_done) {
        mstate = MSID_MB_STATE_DONE;
        MC.experiments_done++;
        sim_write_atomic(O.report, report_body);
    }
}

static void drop_connection(void)
{
    MC.dropped++;
    if (rtu) { silent_until = now_s() + 1.0; return; }
    for (int i = 0; i < n_clients; ++i) close(clients[i]);
    n_clients = 0;
}

static double run_time(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)(t.tv_sec - t_start.tv_sec) + 1e-9 * (double)(t.tv_nsec - t_start.tv_nsec);
}

/* Produce what is due; returns seconds until the next sample is due (-1: waiting for the host). */
static double produce(void)
{
    for (int k = 0; k < 65536 && mstate == MSID_MB_STATE_RUNNING && !stop_flag; ++k) {
        const int here = (int)mexp;
        if (O.restart_exp == here && !restart_done && n_sample == O.restart_at) {
            restart_done = 1;
            segment++;
            restarts_total++;
            MC.restarts++;
            s0 = w;
            sim_restart_segment();
        }
        if (O.drop_exp == here && !drop_done && n_sample == O.drop_at) { drop_done = 1; drop_connection(); }
        if (O.stall_exp == here && !stall_done && n_sample == O.stall_at) {
            stall_done = 1;
            stall_until = now_s() + 1e-3 * (double)O.stall_ms;
            stall_force = O.stall_samples;
            MC.stalls++;
        }
        if (stall_force) {
            stall_force--;
            MC.stall_samples++;
        } else if (CFG.rate_hz) {
            const double due = run_time() * CFG.rate_hz;
            if ((double)w >= due) return ((double)w + 1 - due) / CFG.rate_hz;
        } else if (w >= R && !served[w % R]) {
            return -1;
        }
        write_sample();
    }
    return mstate == MSID_MB_STATE_RUNNING ? 0 : -1;
}

/* ---- requests ------------------------------------------------------------------ */
static uint16_t crc16(const uint8_t *p, size_t n)
{
    uint16_t c = 0xFFFF;
    for (size_t i = 0; i < n; ++i) {
        c ^= p[i];
        for (int b = 0; b < 8; ++b) c = (c & 1) ? (uint16_t)((c >> 1) ^ 0xA001) : (uint16_t)(c >> 1);
    }
    return c;
}

/* RTU: the reply to a read, with one data bit flipped after the CRC was computed. */
static int send_corrupt(const uint8_t *q, int hl, uint32_t addr, uint32_t cnt)
{
    const uint16_t *src = q[hl] == 4 ? IR : HR;
    const uint32_t lim = q[hl] == 4 ? 65536u : MSID_MB_HR_COUNT;
    if (cnt == 0 || cnt > 125 || addr + cnt > lim) return 0;
    uint8_t f[260];
    size_t n = 0;
    f[n++] = q[0];
    f[n++] = q[hl];
    f[n++] = (uint8_t)(2 * cnt);
    for (uint32_t i = 0; i < cnt; ++i) { f[n++] = (uint8_t)(src[addr + i] >> 8); f[n++] = (uint8_t)src[addr + i]; }
    const uint16_t c = crc16(f, n);
    f[3] ^= 0x01;
    f[n++] = (uint8_t)c;
    f[n++] = (uint8_t)(c >> 8);
    return write(modbus_get_socket(MB), f, n) == (ssize_t)n;
}

static void serve(const uint8_t *q, int len)
{
    MC.requests++;
    last_request = now_s();
    const int hl = modbus_get_header_length(MB);
    const uint32_t fc = q[hl], addr = (uint32_t)q[hl + 1] << 8 | q[hl + 2], cnt = (uint32_t)q[hl + 3] << 8 | q[hl + 4];
    if (last_request < stall_until || last_request < silent_until) { MC.unanswered++; return; }
    const uint64_t k = MC.requests;
    update_header();
    if (O.exc_every && k % O.exc_every == 0) {
        MC.exceptions++;
        modbus_reply_exception(MB, q, (unsigned)O.exc_code);
        return;
    }
    if (O.delay_every && k % O.delay_every == 0) {
        MC.delayed++;
        sleep_s(1e-3 * (double)O.delay_ms);
    }
    if (rtu && O.emulate_baud) {
        const double rq = fc == 16 ? 9.0 + 2 * cnt : 8.0, rp = (fc == 3 || fc == 4) ? 5.0 + 2 * cnt : 8.0;
        const double t35 = O.baud > 19200 ? 1.75e-3 : 35.0 / O.baud;
        sleep_s((rq + rp) * 10.0 / O.baud + 2 * t35);
    }
    if (rtu && O.corrupt_every && k % O.corrupt_every == 0 && (fc == 3 || fc == 4) && send_corrupt(q, hl, addr, cnt)) {
        MC.corrupted++;
        return;
    }
    if (modbus_reply(MB, q, len, &MAP) < 0) return;
    MC.replies++;
    if (O.answer_twice && modbus_reply(MB, q, len, &MAP) >= 0) MC.replies++;   /* adversarial: a duplicate */
    if (fc == 4 && addr + cnt > MSID_MB_RING_ADDR && W && R) {
        const uint32_t a = addr > MSID_MB_RING_ADDR ? addr - MSID_MB_RING_ADDR : 0;
        const uint32_t b = addr + cnt - MSID_MB_RING_ADDR;
        for (uint32_t slot = a / W; slot < R && slot * W < b; ++slot)
            if (slot * W >= a && (slot + 1) * W <= b) served[slot] = 1;   /* whole samples only */
    }
    if (fc == 16 || fc == 6) {
        const uint32_t end = fc == 6 ? addr + 1 : addr + cnt;
        if (addr <= MSID_MB_HR_CMD_SEQ && end > MSID_MB_HR_CMD_SEQ && HR[MSID_MB_HR_CMD_SEQ] != cmd_done) {
            cmd_done = HR[MSID_MB_HR_CMD_SEQ];
            execute();
        }
        if (addr <= MSID_MB_HR_CFG_SEQ && end > MSID_MB_HR_CFG_SEQ && HR[MSID_MB_HR_CFG_SEQ] != cfg_done) {
            cfg_done = HR[MSID_MB_HR_CFG_SEQ];
            if (mstate != MSID_MB_STATE_RUNNING) apply_records();
        }
    }
}

static void open_server(void)
{
    MAP.nb_registers = MSID_MB_HR_COUNT;
    MAP.tab_registers = HR;
    MAP.nb_input_registers = 65536;
    MAP.tab_input_registers = IR;
    static uint8_t bits[1];
    MAP.tab_bits = MAP.tab_input_bits = bits;
    if (O.mb_rtu) {
        rtu = 1;
        MB = modbus_new_rtu(O.mb_rtu, (int)O.baud, 'N', 8, 1);
        if (!MB) die("libmodbus", modbus_strerror(errno));
        if (O.unit < 1 || O.unit > 247) die("--unit must be 1..247", NULL);
        modbus_set_slave(MB, (int)O.unit);
        if (modbus_connect(MB) != 0) die(O.mb_rtu, modbus_strerror(errno));
        printf("msid-devsim: ready on modbus-rtu %s (%u baud%s, unit %u, %u input(s), %u output(s), %s plant)\n",
               O.mb_rtu, O.baud, O.emulate_baud ? " emulated" : "", O.unit, PD.nu, PD.ny,
               PD.ct ? "continuous-time" : "discrete-time");
    } else {
        char host[128];
        snprintf(host, sizeof host, "%s", O.mb_tcp);
        char *colon = strrchr(host, ':');
        if (!colon) die("--modbus-tcp wants HOST:PORT", O.mb_tcp);
        *colon = 0;
        MB = modbus_new_tcp(host, atoi(colon + 1));
        if (!MB) die("libmodbus", modbus_strerror(errno));
        listen_fd = modbus_tcp_listen(MB, MAX_CLIENTS);
        if (listen_fd < 0) die(O.mb_tcp, modbus_strerror(errno));
        struct sockaddr_in sa;
        socklen_t sl = sizeof sa;
        getsockname(listen_fd, (struct sockaddr *)&sa, &sl);
        printf("msid-devsim: ready on modbus-tcp %s:%u (%u input(s), %u output(s), %s plant)\n", host,
               ntohs(sa.sin_port), PD.nu, PD.ny, PD.ct ? "continuous-time" : "discrete-time");
    }
    fflush(stdout);
}

int sim_modbus_main(void)
{
    signal(SIGPIPE, SIG_IGN);
    open_server();
    uint8_t q[MODBUS_MAX_ADU_LENGTH];
    last_request = now_s();
    mstate = MSID_MB_STATE_IDLE;
    while (!stop_flag) {
        const double next = produce();
        int tmo = next < 0 ? 200 : (int)(next * 1000.0);
        if (mstate == MSID_MB_STATE_RUNNING && next < 0) tmo = 20;
        if (tmo > 200) tmo = 200;
        struct pollfd pf[MAX_CLIENTS + 1];
        int np = 0;
        if (rtu) pf[np++] = (struct pollfd){modbus_get_socket(MB), POLLIN, 0};
        else {
            pf[np++] = (struct pollfd){listen_fd, POLLIN, 0};
            for (int i = 0; i < n_clients; ++i) pf[np++] = (struct pollfd){clients[i], POLLIN, 0};
        }
        if (poll(pf, (nfds_t)np, tmo) < 0) continue;
        for (int i = 0; i < np; ++i) {
            if (!(pf[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
            if (!rtu && pf[i].fd == listen_fd) {
                const int c = accept(listen_fd, NULL, NULL);
                if (c < 0) continue;
                if (n_clients == MAX_CLIENTS) { close(clients[0]); memmove(clients, clients + 1, sizeof(int) * --n_clients); }
                clients[n_clients++] = c;
                continue;
            }
            modbus_set_socket(MB, pf[i].fd);
            const int n = modbus_receive(MB, q);
            if (n > 0) serve(q, n);
            else if (n < 0 && rtu) modbus_flush(MB);
            else if (n < 0) {
                close(pf[i].fd);
                for (int j = 0; j < n_clients; ++j)
                    if (clients[j] == pf[i].fd) { clients[j] = clients[--n_clients]; break; }
            }
        }
        if (O.idle_exit > 0 && now_s() - last_request > O.idle_exit) break;
    }
    sim_write_atomic(O.report, report_body);
    for (int i = 0; i < n_clients; ++i) close(clients[i]);
    if (listen_fd >= 0) close(listen_fd);
    if (rtu) modbus_close(MB);
    modbus_free(MB);
    return 0;
}
