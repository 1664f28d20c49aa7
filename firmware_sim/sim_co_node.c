/* msid-devsim's CANopen node: NMT slave, heartbeat and EMCY producer, PDOs, SYNC consumer, CiA 402 drive. */
#include "sim_co_node.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static uint64_t node_ms(const sim_co_node *n, double host_ms)
{
    const double t = (host_ms - n->host0_ms) * (1.0 + 1e-6 * n->f.clock_ppm);
    return t > 0 ? (uint64_t)t : 0;
}

static void emit(sim_co_node *n, uint32_t id, const uint8_t *d, uint8_t len)
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = len;
    if (len) memcpy(f.data, d, len);
    n->send(n->ctx, &f);
}

static void emcy(sim_co_node *n, uint16_t code)
{
    const uint32_t cob = (uint32_t)sim_co_od_get(&n->od, 0x1014, 0);
    if (cob & 0x80000000u) return;
    const uint8_t d[8] = {(uint8_t)code, (uint8_t)(code >> 8), (uint8_t)sim_co_od_get(&n->od, 0x1001, 0)};
    emit(n, cob & 0x7FFu, d, 8);
    n->cnt.emcy_sent++;
}

static void update_status(sim_co_node *n)
{
    sim_co_od_set(&n->od, 0x6041, 0, sim_co402_statusword(&n->drive));
}

static double sync_period_s(sim_co_node *n)
{
    const uint64_t us = sim_co_od_get(&n->od, 0x1006, 0);
    return us ? (double)us * 1e-6 : 1e-3;
}

static void boot(sim_co_node *n, int reset_app)
{
    if (reset_app) {
        sim_co_od_reset(&n->od, 0x0000, 0xFFFF);
        const sim_co402_gains g = sim_co402_gains_for(sync_period_s(n));
        sim_co402_init(&n->drive, &g);
        sim_twomass_init(&n->plant, &n->mech, sync_period_s(n));
        n->w_meas = 0;
        n->fault_done = 0;
    } else
        sim_co_od_reset(&n->od, 0x1000, 0x1FFF);
    update_status(n);
    sim_co_od_set(&n->od, 0x6061, 0, sim_co_od_get(&n->od, 0x6060, 0));
    memset(n->tpdo_syncs, 0, sizeof n->tpdo_syncs);
    memset(n->rpdo_pending, 0, sizeof n->rpdo_pending);
    n->sdo.state = 0;
    const uint8_t zero = 0;
    emit(n, 0x700u + n->id, &zero, 1);
    n->cnt.boots++;
    n->nmt = SIM_CO_NMT_PREOP;
    n->boot_ms = n->now_ms;
    const uint64_t hb = sim_co_od_get(&n->od, 0x1017, 0);
    n->next_hb_ms = hb ? n->now_ms + hb : 0;
}

/* ---- PDO rules (CiA 301 7.5.2.35 ff.) ----------------------------------- */

static int pdo_of(uint16_t index, int *tx, int *num, int *is_map)
{
    if (index >= 0x1400 && index <= 0x1403) { *tx = 0, *num = index - 0x1400, *is_map = 0; return 1; }
    if (index >= 0x1600 && index <= 0x1603) { *tx = 0, *num = index - 0x1600, *is_map = 1; return 1; }
    if (index >= 0x1800 && index <= 0x1803) { *tx = 1, *num = index - 0x1800, *is_map = 0; return 1; }
    if (index >= 0x1A00 && index <= 0x1A03) { *tx = 1, *num = index - 0x1A00, *is_map = 1; return 1; }
    return 0;
}

static uint16_t comm_index(int tx, int num) { return (uint16_t)((tx ? 0x1800 : 0x1400) + num); }
static uint16_t map_index(int tx, int num) { return (uint16_t)((tx ? 0x1A00 : 0x1600) + num); }

static int pdo_valid(sim_co_node *n, int tx, int num)
{
    return !(sim_co_od_get(&n->od, comm_index(tx, num), 1) & 0x80000000u);
}

static uint32_t le32(const uint8_t *d, size_t len)
{
    uint32_t x = 0;
    for (size_t k = 0; k < len && k < 4; ++k) x |= (uint32_t)d[k] << (8 * k);
    return x;
}

/* The abort a mapping entry earns (0: it may be mapped). */
static uint32_t map_entry_rule(sim_co_node *n, int tx, uint32_t m)
{
    if (m == 0) return 0;
    const uint16_t index = (uint16_t)(m >> 16);
    const uint8_t sub = (uint8_t)(m >> 8), bits = (uint8_t)m;
    const sim_co_var *v = sim_co_od_find(&n->od, index, sub);
    if (!v) return sim_co_od_has_index(&n->od, index) ? SIM_CO_ABORT_NO_SUB : SIM_CO_ABORT_NO_OBJECT;
    if (n->f.refuse_index && index == n->f.refuse_index && sub == n->f.refuse_sub) return SIM_CO_ABORT_NO_MAP;
    if (!v->mappable || !v->size || bits != 8u * v->size) return SIM_CO_ABORT_NO_MAP;
    if (tx && v->access == MSID_CO_WO) return SIM_CO_ABORT_NO_MAP;
    if (!tx && (v->access == MSID_CO_RO || v->access == MSID_CO_CONST)) return SIM_CO_ABORT_NO_MAP;
    return 0;
}

static uint32_t pdo_rule(sim_co_node *n, const sim_co_var *v, uint32_t value)
{
    int tx, num, is_map;
    if (!pdo_of(v->index, &tx, &num, &is_map)) return 0;
    const int valid = pdo_valid(n, tx, num);
    if (!is_map) {
        if (v->sub == 1) {
            if (value & 0x20000000u) return SIM_CO_ABORT_RANGE;   /* 29-bit identifiers are not served */
            const uint32_t cob = (uint32_t)sim_co_od_get(&n->od, v->index, 1);
            if (valid && !(value & 0x80000000u) && (value & 0x7FFu) != (cob & 0x7FFu)) return SIM_CO_ABORT_RANGE;
            if (!(value & 0x80000000u) && ((value & 0x7FFu) == 0 || (value & 0x7FFu) > 0x7FFu)) return SIM_CO_ABORT_RANGE;
        } else if (v->sub == 2) {
            const int ok = value <= 240u || value == 254u || value == 255u || (tx && (value == 252u || value == 253u));
            if (!ok) return SIM_CO_ABORT_RANGE;
        } else if (v->sub == 3 && valid)
            return SIM_CO_ABORT_RANGE;   /* the inhibit time only while the PDO is not valid */
        return 0;
    }
    if (valid || n->nmt == SIM_CO_NMT_OPERATIONAL) return SIM_CO_ABORT_STATE;
    const uint16_t mi = map_index(tx, num);
    if (v->sub >= 1) {
        if (sim_co_od_get(&n->od, mi, 0)) return SIM_CO_ABORT_STATE;   /* entries only while the count is 0 */
        return map_entry_rule(n, tx, value);
    }
    if (value > 8) return SIM_CO_ABORT_VALUE_HIGH;
    unsigned bits = 0;
    for (uint8_t k = 1; k <= value; ++k) {
        const uint32_t m = (uint32_t)sim_co_od_get(&n->od, mi, k);
        const uint32_t a = map_entry_rule(n, tx, m);
        if (a) return a;
        if (!m) return SIM_CO_ABORT_NO_MAP;
        bits += m & 0xFFu;
    }
    return bits > 64 ? SIM_CO_ABORT_MAP_LEN : 0;
}

/* ---- writes: SDO and RPDO ------------------------------------------------- */

static uint32_t on_write(void *ctx, sim_co_var *v, const uint8_t *data, size_t len)
{
    sim_co_node *n = ctx;
    if (n->f.abort_code && v->index == n->f.abort_index && v->sub == n->f.abort_sub) return n->f.abort_code;
    const uint32_t value = le32(data, len);
    uint32_t a = pdo_rule(n, v, value);
    if (a) return a;
    if (v->index == 0x6060 && v->sub == 0) {
        const int8_t m = (int8_t)value;
        if (m != 0 && m != MSID_CO402_MODE_CSP && m != MSID_CO402_MODE_CSV && m != MSID_CO402_MODE_CST)
            return SIM_CO_ABORT_RANGE;
    }
    if (v->index == 0x6076 && v->sub == 0 && value == 0) return SIM_CO_ABORT_RANGE;
    if (v->index == 0x1006 && v->sub == 0 && value && value < 100u) return SIM_CO_ABORT_RANGE;  /* >= 100 us */
    sim_co_od_store(&n->od, v, data, len);
    if (v->index == 0x6040 && v->sub == 0) {
        sim_co402_controlword(&n->drive, (uint16_t)value);
        update_status(n);
        if ((uint16_t)value & 0x80u && sim_co_od_get(&n->od, 0x1001, 0) &&
            n->drive.state == MSID_CO402_SWITCH_ON_DISABLED) {
            sim_co_od_set(&n->od, 0x1001, 0, 0);
            emcy(n, 0x0000);   /* error reset */
        }
    } else if (v->index == 0x6060 && v->sub == 0)
        sim_co_od_set(&n->od, 0x6061, 0, value);
    else if (v->index == 0x1017 && v->sub == 0)
        n->next_hb_ms = value ? n->now_ms + value : 0;
    else if (v->index == 0x1006 && v->sub == 0) {
        double x[4];
        memcpy(x, n->plant.x, sizeof x);
        sim_twomass_init(&n->plant, &n->mech, sync_period_s(n));
        memcpy(n->plant.x, x, sizeof x);
        n->drive.g = sim_co402_gains_for(sync_period_s(n));   /* the loop stays tuned to the SYNC it runs on */
    }
    return 0;
}

static uint32_t on_read(void *ctx, const sim_co_var *v)
{
    const sim_co_node *n = ctx;
    if (n->f.abort_code && v->index == n->f.abort_index && v->sub == n->f.abort_sub) return n->f.abort_code;
    return 0;
}

/* ---- PDOs ------------------------------------------------------------------ */

/* The mapped entries of a PDO (the count of those the node holds, in order; a mapping the rules let in has
   them all) and their byte offsets: entry k at off[k] .. off[k + 1]. */
static unsigned mapped(sim_co_node *n, int tx, int num, sim_co_var *v[8], unsigned off[9])
{
    const uint16_t mi = map_index(tx, num);
    const unsigned cnt = (unsigned)sim_co_od_get(&n->od, mi, 0);
    unsigned k = 0;
    off[0] = 0;
    for (; k < cnt && k < 8; ++k) {
        const uint32_t m = (uint32_t)sim_co_od_get(&n->od, mi, (uint8_t)(k + 1));
        v[k] = sim_co_od_find(&n->od, (uint16_t)(m >> 16), (uint8_t)(m >> 8));
        const unsigned b = (m & 0xFFu) / 8u;
        if (!v[k] || !v[k]->size || b != v[k]->size || off[k] + b > 8) break;
        off[k + 1] = off[k] + b;
    }
    return k;
}

static void send_tpdo(sim_co_node *n, int num)
{
    sim_co_var *v[8];
    unsigned off[9];
    const unsigned cnt = mapped(n, 1, num, v, off);
    uint8_t d[8];
    for (unsigned k = 0; k < cnt; ++k) {
        size_t len;
        const uint8_t *src = sim_co_od_bytes(&n->od, v[k], &len);
        memcpy(&d[off[k]], src, off[k + 1] - off[k]);
    }
    const unsigned pos = off[cnt];
    n->tpdo_due++;
    if (n->f.drop_every && n->tpdo_due % n->f.drop_every == 0) { n->cnt.tpdo_dropped++; return; }
    const uint64_t inhibit_100us = sim_co_od_get(&n->od, comm_index(1, num), 3);
    if (inhibit_100us && n->tpdo_last_ms[num] && (n->now_ms - n->tpdo_last_ms[num]) * 10u < inhibit_100us) {
        n->cnt.tpdo_inhibited++;
        return;
    }
    n->tpdo_last_ms[num] = n->now_ms ? n->now_ms : 1;
    emit(n, (uint32_t)sim_co_od_get(&n->od, comm_index(1, num), 1) & 0x7FFu, d, (uint8_t)pos);
    n->cnt.tpdo_sent++;
}

static void apply_rpdo(sim_co_node *n, int num)
{
    sim_co_var *v[8];
    unsigned off[9];
    const unsigned cnt = mapped(n, 0, num, v, off);
    for (unsigned k = 0; k < cnt; ++k) (void)on_write(n, v[k], &n->rpdo_buf[num][off[k]], off[k + 1] - off[k]);
    n->cnt.rpdo_taken++;
}

static void take_rpdo(sim_co_node *n, int num, const msid_can_frame *f)
{
    sim_co_var *v[8];
    unsigned off[9];
    const unsigned cnt = mapped(n, 0, num, v, off);
    if (f->len < off[cnt]) {
        /* CiA 301: a PDO shorter than its mapping is not processed; EMCY 0x8210 */
        n->cnt.rpdo_bad++;
        emcy(n, 0x8210);
        return;
    }
    memcpy(n->rpdo_buf[num], f->data, 8);
    const uint64_t type = sim_co_od_get(&n->od, comm_index(0, num), 2);
    if (type <= 240u) n->rpdo_pending[num] = 1;
    else apply_rpdo(n, num);
}

/* ---- SYNC ------------------------------------------------------------------ */

static void drive_step(sim_co_node *n)
{
    sim_co402_io io;
    io.mode = (int8_t)sim_co_od_get(&n->od, 0x6061, 0);
    io.target_torque = (int16_t)sim_co_od_get(&n->od, 0x6071, 0);
    io.target_vel = (int32_t)sim_co_od_get(&n->od, 0x60FF, 0);
    io.target_pos = (int32_t)sim_co_od_get(&n->od, 0x607A, 0);
    io.torque_offset = (int16_t)sim_co_od_get(&n->od, 0x60B2, 0);   /* 0 when the EDS has no 0x60B2 */
    io.rated_mnm = (uint32_t)sim_co_od_get(&n->od, 0x6076, 0);
    io.omega = n->w_meas;   /* the loop feeds back what the drive measured and 0x606C shows */
    io.theta = n->plant.x[0];
    io.ts = n->plant.ts;
    int16_t pm;
    const double tau = sim_co402_demand(&n->drive, &io, &pm);
    sim_twomass_step(&n->plant, tau);
    sim_co_od_set(&n->od, 0x6074, 0, (uint16_t)pm);
    sim_co_od_set(&n->od, 0x6077, 0, (uint16_t)pm);
    const double w_noise = n->f.noise_vel > 0 ? n->f.noise_vel * msid_rng_normal(&n->rng) : 0.0;
    n->w_meas = n->plant.x[1] + w_noise;
    sim_co_od_set(&n->od, 0x606C, 0, (uint32_t)sim_co402_vel_to_bus(n->w_meas));
    sim_co_od_set(&n->od, 0x6064, 0, (uint32_t)sim_co402_pos_to_bus(n->plant.x[0]));
}

static void on_sync(sim_co_node *n)
{
    n->cnt.syncs++;
    if (n->f.emcy_at_sync && n->cnt.syncs == n->f.emcy_at_sync && !n->fault_done) {
        n->fault_done = 1;
        sim_co402_fault(&n->drive);
        update_status(n);
        sim_co_od_set(&n->od, 0x1001, 0, 0x03);   /* generic and current */
        emcy(n, 0x2310);                          /* continuous over-current */
    }
    if (n->nmt == SIM_CO_NMT_OPERATIONAL) {
        for (int k = 0; k < 4; ++k) {
            if (!pdo_valid(n, 1, k)) continue;
            const uint64_t type = sim_co_od_get(&n->od, comm_index(1, k), 2);
            if (type > 240u) continue;
            if (++n->tpdo_syncs[k] >= (type ? type : 1u)) {
                n->tpdo_syncs[k] = 0;
                send_tpdo(n, k);
            }
        }
        for (int k = 0; k < 4; ++k)
            if (n->rpdo_pending[k]) { n->rpdo_pending[k] = 0; apply_rpdo(n, k); }
    }
    drive_step(n);
}

/* ---- frames and timers ----------------------------------------------------- */

static void on_nmt(sim_co_node *n, const msid_can_frame *f)
{
    if (f->len < 2 || (f->data[1] != 0 && f->data[1] != n->id)) return;
    switch (f->data[0]) {
    case 0x01: n->nmt = SIM_CO_NMT_OPERATIONAL; break;
    case 0x02: n->nmt = SIM_CO_NMT_STOPPED; break;
    case 0x80: n->nmt = SIM_CO_NMT_PREOP; break;
    case 0x81: boot(n, 1); break;
    case 0x82: boot(n, 0); break;
    default: break;
    }
}

static void take_frame(sim_co_node *n, const msid_can_frame *f)
{
    if (f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) return;
    const uint32_t id = f->id & 0x7FFu;
    if (id == 0) { on_nmt(n, f); return; }
    if (n->nmt == SIM_CO_NMT_STOPPED) return;
    if (id == 0x080u) { on_sync(n); return; }
    if (id == 0x600u + n->id) {
        if (f->len >= 1 && f->data[0] >> 5 == 1u) n->cnt.sdo_downloads++;
        msid_can_frame r;
        if (sim_co_sdo_rx(&n->sdo, f, &r, n->now_ms)) n->send(n->ctx, &r);
        return;
    }
    if (n->nmt != SIM_CO_NMT_OPERATIONAL) return;
    for (int k = 0; k < 4; ++k) {
        const uint32_t cob = (uint32_t)sim_co_od_get(&n->od, comm_index(0, k), 1);
        if (!(cob & 0x80000000u) && (cob & 0x7FFu) == id) { take_rpdo(n, k, f); return; }
    }
}

/* The held frames, in order, once their late SYNC is due. */
static void release_held(sim_co_node *n)
{
    if (!n->n_held || n->now_ms < n->held_until_ms) return;
    const uint32_t k = n->n_held;
    n->n_held = 0;
    for (uint32_t i = 0; i < k; ++i) take_frame(n, &n->held[i]);
}

void sim_co_node_rx(sim_co_node *n, const msid_can_frame *f, double host_ms)
{
    n->now_ms = node_ms(n, host_ms);
    release_held(n);
    const int sync = (f->id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) == 0 && f->id == 0x080u;
    if (sync) n->syncs_in++;
    if (!n->n_held && sync && n->f.late_sync_every && n->syncs_in % n->f.late_sync_every == 0) {
        n->held_until_ms = n->now_ms + n->f.late_sync_ms;
        n->cnt.late_syncs++;
    } else if (!n->n_held || n->n_held >= SIM_CO_HELD_MAX) {
        take_frame(n, f);
        return;
    }
    n->held[n->n_held++] = *f;   /* the late SYNC, or a frame behind it: taken in order when it is due */
}

void sim_co_node_poll(sim_co_node *n, double host_ms)
{
    n->now_ms = node_ms(n, host_ms);
    release_held(n);
    msid_can_frame r;
    if (sim_co_sdo_poll(&n->sdo, &r, n->now_ms)) n->send(n->ctx, &r);
    if (!n->next_hb_ms || n->now_ms < n->next_hb_ms) return;
    const uint64_t hb = sim_co_od_get(&n->od, 0x1017, 0);
    n->next_hb_ms = hb ? n->next_hb_ms + hb : 0;
    if (n->next_hb_ms && n->next_hb_ms <= n->now_ms) n->next_hb_ms = n->now_ms + hb;   /* slept through some */
    if (n->f.hb_stop_after_s > 0 && (double)(n->now_ms - n->boot_ms) >= 1e3 * n->f.hb_stop_after_s) return;
    emit(n, 0x700u + n->id, &n->nmt, 1);
    n->cnt.heartbeats++;
}

double sim_co_node_next_ms(const sim_co_node *n)
{
    double t = INFINITY;
    const double k = 1.0 + 1e-6 * n->f.clock_ppm;
    if (n->next_hb_ms) t = n->host0_ms + (double)n->next_hb_ms / k;
    if (n->n_held) {
        const double h = n->host0_ms + (double)n->held_until_ms / k;
        if (h < t) t = h;
    }
    if (n->sdo.state) {
        const double s = n->host0_ms + (double)(n->sdo.last_ms + SIM_CO_SDO_TIMEOUT_MS) / k;
        if (s < t) t = s;
    }
    return t;
}

int sim_co_node_init(sim_co_node *n, const msid_co_eds *eds, unsigned node, const sim_co_faults *f,
                     void (*send)(void *ctx, const msid_can_frame *f), void *ctx, double host_ms, char *err,
                     size_t err_len)
{
    memset(n, 0, sizeof *n);
    if (node < 1 || node > 127) {
        snprintf(err, err_len, "node id %u is not 1..127", node);
        return -1;
    }
    if (sim_co_od_init(&n->od, eds, node) != 0) {
        snprintf(err, err_len, "%s: %s", eds->source, n->od.err);
        return -1;
    }
    static const uint16_t need[] = {0x1001, 0x1017, 0x6040, 0x6041, 0x6060, 0x6061, 0x6064, 0x606C,
                                    0x6071, 0x6074, 0x6076, 0x6077, 0x607A, 0x60FF};
    for (size_t k = 0; k < sizeof need / sizeof need[0]; ++k) {
        const sim_co_var *v = sim_co_od_find(&n->od, need[k], 0);
        if (!v || !v->size) {
            snprintf(err, err_len, "%s: the drive needs entry 0x%04X:00 (a basic type), which the file lacks",
                     eds->source, need[k]);
            return -1;
        }
    }
    n->id = (uint8_t)node;
    n->f = *f;
    msid_rng_seed(&n->rng, f->seed);
    n->send = send;
    n->ctx = ctx;
    n->host0_ms = host_ms;
    n->mech = sim_twomass_default();
    sim_co_sdo_init(&n->sdo, &n->od, node, on_write, on_read, n);
    boot(n, 1);
    return 0;
}
