/**
 * @file sim_co_node.h
 * @brief msid-devsim's CANopen node: a CiA 402 servo drive (CiA 301 NMT slave, heartbeat producer 0x1017,
 *        EMCY producer 0x1014, SDO server, PDOs configured by SDO, SYNC consumer) stepping its plant
 *        (sim_twomass.h) once per SYNC, with fault injection. Frames in through sim_co_node_rx, out through
 *        the send function it is given, so the unit tests drive it with frames in memory.
 *
 * At each SYNC (pre-operational or operational): (1) in operational, every valid TPDO of transmission type
 * 0..240 whose count of SYNCs is reached (type n: every n-th, 0 taken as 1) is sent with the values the
 * dictionary holds, i.e. the state x[k] the last step left and the demand that drove it; (2) the targets
 * the synchronous RPDOs brought since the last SYNC are written; (3) the drive computes its demand
 * tau[k] from the targets and x[k] (0 outside "operation enabled") and the plant steps to x[k+1]; 0x6064,
 * 0x606C, 0x6074 and 0x6077 (the ideal current loop: actual = demand) are updated.
 *
 * The node's own clock (heartbeat period, TPDO inhibit time, SDO timeout, heartbeat stop) runs
 * (1 + clock_ppm 1e-6) times the host's; its plant runs on SYNC, the master's clock, with step 0x1006
 * (1 ms while 0x1006 is 0).
 */
#ifndef MSID_SIM_CO_NODE_H
#define MSID_SIM_CO_NODE_H

#include <stdint.h>

#include "msid/msid_rng.h"
#include "msid_daq/msid_can_transport.h"
#include "sim_co402.h"
#include "sim_co_od.h"
#include "sim_co_sdo.h"
#include "sim_twomass.h"

/** Faults the node can be given (all off when zero). */
typedef struct sim_co_faults {
    uint32_t abort_code;      /**< SDO reads and writes of abort_index:abort_sub aborted with it (0: none) */
    uint16_t abort_index;
    uint8_t abort_sub;
    uint64_t emcy_at_sync;    /**< at the n-th SYNC (1-based) a drive fault: EMCY 0x2310, error register
                                   0x03, "fault" until a fault reset (0: none) */
    double hb_stop_after_s;   /**< heartbeats end this long (node clock, s) after boot (0: never) */
    uint16_t refuse_index;    /**< a mapping of refuse_index:refuse_sub is refused as not mappable (0: none) */
    uint8_t refuse_sub;
    double clock_ppm;         /**< the node's clock against the host's, ppm, |x| <= 1e4 */
    uint64_t drop_every;      /**< the k-th, 2k-th, ... TPDO due is not sent (0: none) */
    uint64_t late_sync_every; /**< the k-th, 2k-th, ... SYNC is taken late_sync_ms late, as a SYNC the bus or the
                                   node's interrupt held up: it and every frame behind it wait, then are taken in
                                   order (the plant still steps once per SYNC; 0: none) */
    uint64_t late_sync_ms;    /**< node time, ms */
    double noise_vel;         /**< std of white Gaussian noise on the velocity the drive measures, rad/s: the
                                   velocity it reports (0x606C) and the one its velocity loop (CSV, CSP) feeds
                                   back are that one measurement, as an encoder's noise; the plant moves with
                                   the demand (0: none) */
    uint64_t seed;            /**< of that noise */
} sim_co_faults;

/** NMT states as the heartbeat shows them. */
enum { SIM_CO_NMT_BOOT = 0x00, SIM_CO_NMT_STOPPED = 0x04, SIM_CO_NMT_OPERATIONAL = 0x05, SIM_CO_NMT_PREOP = 0x7F };

/** Counters. */
typedef struct sim_co_counts {
    uint64_t syncs, tpdo_sent, tpdo_dropped, tpdo_inhibited, rpdo_taken, rpdo_bad, heartbeats, emcy_sent, boots;
    uint64_t late_syncs;      /**< SYNCs held by late_sync_every */
    uint64_t sdo_downloads;   /**< SDO download (write) requests initiated */
} sim_co_counts;

/** Frames a late SYNC holds behind it at most (more are taken at once, out of order). */
#define SIM_CO_HELD_MAX 64u

/** The node (caller-owned, about 20 kB). */
typedef struct sim_co_node {
    sim_co_od od;
    sim_co_sdo_srv sdo;
    sim_co402 drive;
    sim_twomass plant;
    sim_twomass_par mech;
    uint8_t id;
    uint8_t nmt;
    void (*send)(void *ctx, const msid_can_frame *f);
    void *ctx;
    sim_co_faults f;
    msid_rng rng;               /**< the velocity noise's (f.seed) */
    sim_co_counts cnt;
    uint64_t boot_ms;           /**< node time of the last boot-up */
    uint64_t next_hb_ms;        /**< node time of the next heartbeat (0: none due) */
    uint32_t tpdo_syncs[4];     /**< SYNCs counted towards each TPDO's transmission type */
    uint64_t tpdo_last_ms[4];   /**< node time each TPDO was last sent (inhibit time) */
    uint64_t tpdo_due;          /**< TPDOs due so far (drop_every counts these) */
    uint8_t rpdo_buf[4][8];     /**< the last frame of each RPDO, not yet applied */
    uint8_t rpdo_pending[4];
    int fault_done;
    double host0_ms;            /**< host time at init, ms */
    double w_meas;              /**< the velocity the drive measured for the state it holds (0x606C), rad/s */
    uint64_t now_ms;            /**< node time of the last call, ms */
    uint64_t syncs_in;          /**< SYNC frames received (late_sync_every counts these) */
    msid_can_frame held[SIM_CO_HELD_MAX];   /**< a late SYNC and the frames behind it, in order */
    uint32_t n_held;
    uint64_t held_until_ms;     /**< node time they are taken */
} sim_co_node;

/**
 * @brief Build the node from an EDS (msid_co_eds_load), boot it (boot-up frame sent, pre-operational).
 * @param host_ms host monotonic time, ms
 * @return 0, or -1 with err naming what is wrong (the EDS lacks an entry the drive needs, ...)
 */
int sim_co_node_init(sim_co_node *n, const msid_co_eds *eds, unsigned node, const sim_co_faults *f,
                     void (*send)(void *ctx, const msid_can_frame *f), void *ctx, double host_ms, char *err,
                     size_t err_len);

/** @brief Take one frame received at host time host_ms (NMT, SYNC, SDO request, RPDO; others ignored). */
void sim_co_node_rx(sim_co_node *n, const msid_can_frame *f, double host_ms);

/** @brief Run the node's timers (heartbeat, SDO timeout) at host time host_ms. */
void sim_co_node_poll(sim_co_node *n, double host_ms);

/** @brief The host time (ms) the node's next timer falls due (heartbeat or SDO timeout; +inf if none). */
double sim_co_node_next_ms(const sim_co_node *n);

#endif
