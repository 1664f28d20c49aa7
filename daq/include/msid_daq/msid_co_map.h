/**
 * @file msid_co_map.h
 * @brief A CANopen drive described by msid-device/1 (transport "canopen") as the host's tick loop sees it:
 *        the ::msid_devio backend that carries one tick as an RPDO and a SYNC, and reads that tick's samples
 *        from the synchronous TPDOs the node sends on that SYNC.
 *
 * The mapping: the drive channels, in order, are RPDO1 (at most 8 bytes); the measure channels, in order,
 * are TPDO1 and, when they do not fit in 8 bytes or 8 objects, TPDO2 (::msid_devdesc_co_pack); all of
 * transmission type 1 (every SYNC) on the predefined connection set's COB-IDs. Values are little endian on
 * the bus, physical = raw * scale + offset as for every transport.
 *
 * One tick (::msid_devio_exchange): the frames waiting on the socket are taken, in bus order; the socket
 * receives msid's own SYNC back (CAN_RAW_RECV_OWN_MSGS), so the TPDOs behind the echo of the previous tick's
 * SYNC are that SYNC's answers (those before it answer an older SYNC: counted `late`, dropped; EMCY and
 * heartbeat are watched). They are the sample this exchange returns; then the RPDO with the tick's values and
 * this tick's SYNC are sent. So the node has a whole tick to answer, and a tick's samples are returned one
 * tick later: the demand (the FRF's input) and the actual values come from the same TPDOs of the same SYNC,
 * so the shift moves input and output alike and the FRF does not see it. A TPDO missing by the next tick is a
 * lost sample (counted; the exchange fails and the tick loop marks the sample missing, never interpolated);
 * the first TPDO behind the next SYNC's echo is then taken for that late answer and dropped, so that a late
 * answer is never placed as the next SYNC's sample (a node answers in order).
 *
 * With kernel_sync set (the description's sync = "kernel"), the SYNC is not sent by the tick: the kernel's
 * broadcast manager sends it on its own timer (msid_co_sync.h, started by the caller), and each echo of it on
 * the socket opens the window of that SYNC's answers. A tick then sends the RPDO only (the node applies it on
 * the next SYNC) and returns the answers of the last SYNC the bus carried, waiting up to wait_ns for them,
 * with that SYNC's count (1 for the first echo) in measure[sync_ch]: the tick loop places each sample at the
 * SYNC it belongs to (msid_hx's counter mode, as a device's own cycle counter), so the host's lateness moves
 * which SYNC takes a write, never which SYNC a sample is placed at. The count as read just before the RPDO
 * goes out is the exchange's counter_before, so that a SYNC between the two is seen as a straddled write.
 *
 * Ways out the backend itself sees: an EMCY other than an error reset, a heartbeat later than heartbeat_ms
 * (when the description sets it), a heartbeat or boot-up that shows the node out of operational. Each makes
 * ::msid_co_map::fatal non-empty and every later exchange fail: the caller ends the run (safe target, quick
 * stop, disable voltage, no more SYNC). Nothing here allocates; configuration by SDO is the caller's (it
 * uses ::msid_co_map_pdos for the PDOs to write).
 */
#ifndef MSID_CO_MAP_H
#define MSID_CO_MAP_H

#include <stdint.h>
#include "msid_co_eds.h"
#include "msid_co_emcy.h"
#include "msid_co_nmt.h"
#include "msid_co_pdo.h"
#include "msid_devdesc.h"
#include "msid_devio.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Counters of a run (cumulative). */
typedef struct msid_co_map_counters {
    uint64_t syncs;          /**< SYNC frames sent */
    uint64_t rpdos;          /**< RPDOs sent */
    uint64_t tpdos;          /**< TPDOs taken as a tick's samples */
    uint64_t lost;           /**< ticks whose TPDO(s) had not come by the end of the wait */
    uint64_t late;           /**< TPDOs of an earlier SYNC, found before a tick's SYNC (dropped) */
    uint64_t bad_tpdos;      /**< TPDOs of another length than the mapping's (dropped) */
    uint64_t emcy;           /**< EMCY frames (error resets included) */
    uint64_t heartbeats;     /**< heartbeat frames */
    uint64_t send_failures;  /**< RPDO or SYNC sends that failed */
    double latency_sum_s, latency_max_s;   /**< TPDO after the SYNC's echo, kernel receive times (s) */
    uint64_t latency_n;
} msid_co_map_counters;

/** The backend's state (caller-owned). */
typedef struct msid_co_map {
    msid_devio io;                    /**< the tick loop's device */
    const msid_devdesc *d;            /**< resolved (scales known); lives as long as the map */
    const msid_can_transport *t;      /**< a socket that receives its own frames, filtered to the node's */
    uint8_t node;
    uint32_t n_tpdo;                  /**< 1 or 2 */
    uint8_t rpdo_len, tpdo_len[MSID_DEV_CO_TPDOS];
    uint8_t rpdo_off[MSID_DEV_MAX_DRIVE];        /**< byte offset of each drive channel in RPDO1 */
    uint8_t tpdo_of[MSID_DEV_MAX_MEASURE];       /**< 0: TPDO1, 1: TPDO2 */
    uint8_t tpdo_off[MSID_DEV_MAX_MEASURE];      /**< byte offset in its TPDO */
    int send_timeout_ms;              /**< a full send queue is retried this long */
    int64_t wait_ns;                  /**< how long an exchange waits for the previous SYNC's answers when they
                                           are not all in yet (0: not at all) */
    int operational;                  /**< 1 while the node should be operational (heartbeat states watched) */
    msid_co_hb hb;                    /**< heartbeat consumer (time_ms 0: none) */
    msid_co_emcy last_emcy;           /**< the last EMCY with an error */
    double value[MSID_DEV_MAX_MEASURE + 1];   /**< the last values read (and the SYNC count, kernel_sync) */
    uint8_t buf[MSID_DEV_CO_TPDOS][8];    /**< the TPDOs of the last SYNC as they came */
    uint32_t got;                     /**< bit k: TPDO k+1 of the last SYNC is in buf */
    uint32_t echo_due;                /**< SYNCs sent whose echo has not been taken yet */
    uint32_t owed;                    /**< bit k: the previous SYNC's TPDO k+1 was not in when this SYNC went out:
                                           the first one behind this SYNC's echo is that late answer */
    uint32_t owed_taken;              /**< bit k: this window took an owed answer */
    uint64_t syncs_sent;
    uint64_t echo_ns;                 /**< kernel receive time of the last SYNC's echo (0: unknown) */
    int kernel_sync;                  /**< 1: the kernel's timer sends the SYNC (see the file's head), 0: each tick */
    int32_t sync_ch;                  /**< kernel_sync: the measure slot that receives the SYNC's count
                                           (d->n_measure: one past the description's channels) */
    uint64_t echoes;                  /**< kernel_sync: echoes of the kernel's SYNC seen (the last SYNC's count) */
    int64_t period_ns;                /**< kernel_sync: the SYNC's period */
    int64_t unechoed_since;           /**< kernel_sync: when the first RPDO after the last echo went out (0: none) */
    msid_co_map_counters cnt;
    char fatal[240];                  /**< why the run must end ("" while it may go on) */
    char err[240];                    /**< detail of the last failure */
    char describe[96];                /**< "RPDO1 (2 bytes) + SYNC + TPDO1 (8 bytes) + TPDO2 (4 bytes)" */
} msid_co_map;

/**
 * @brief Set up the backend of a CANopen description (msid_devdesc_check passed, scales resolved).
 * @param node 1..127
 * @param heartbeat_ms consumer time of the node's heartbeat (0: not watched)
 * @return 0, or -MSID_DAQ_E_ARG with m->err
 */
int msid_co_map_init(msid_co_map *m, const msid_devdesc *d, unsigned node, unsigned heartbeat_ms,
                     const msid_can_transport *t);

/**
 * @brief Take the SYNC from the kernel's timer (see the file's head), sent every period_us (> 0): after
 *        ::msid_co_map_init, before the first exchange; exchanges then fill measure[d->n_measure] with the SYNC's count, so the caller's
 *        measure buffers hold d->n_measure + 1 values.
 */
void msid_co_map_kernel_sync(msid_co_map *m, uint32_t period_us);

/** kernel_sync: ticks that see no echo of the SYNC for this many periods after an RPDO fail (no SYNC runs). */
#define MSID_CO_MAP_ECHO_PERIODS 10

/**
 * @brief The PDO configurations the description needs: RPDO1 from the drive channels, TPDO1 (and TPDO2)
 *        from the measure channels, transmission type 1, predefined COB-IDs.
 * @param tpdo [MSID_DEV_CO_TPDOS]; m->n_tpdo of them are filled
 */
void msid_co_map_pdos(const msid_co_map *m, msid_co_pdo_cfg *rpdo, msid_co_pdo_cfg *tpdo);

/**
 * @brief Offer a frame that arrived outside a tick (the SDO client's other-frame hook): EMCY and heartbeat
 *        are watched, TPDOs are counted late. now_ms: the io clock.
 */
void msid_co_map_offer(msid_co_map *m, const msid_can_frame *f, uint64_t now_ms);

/** @brief A drive channel's value as the bytes of its object (little endian): 0, or -1 when it does not fit. */
int msid_co_map_encode(const msid_dev_chan *c, double v, uint8_t *bytes);

/** @brief The physical value of a channel's object bytes (little endian). */
double msid_co_map_decode(const msid_dev_chan *c, const uint8_t *bytes);

/** Bit rate assumed for the bus budget when the device URI gives none (a virtual CAN has none): 1 Mbit/s,
 *  classic CAN's highest, so that only a rate no classic bus carries is refused then. */
#define MSID_CO_MAP_BITRATE_DEFAULT 1000000u
/** Share of the bit rate the cyclic frames (SYNC, RPDO, TPDOs) may take: the rest is room for heartbeats,
 *  EMCY, other nodes' frames and the lower-priority frames' arbitration delays. */
#define MSID_CO_MAP_BUS_SHARE 0.7

/**
 * @brief The bus budget of the run before anything is sent: the SYNC (no data), RPDO1 and the TPDO(s) of the
 *        mapping every cycle, at their worst-case length (msid_co_bus.h), within ::MSID_CO_MAP_BUS_SHARE of
 *        bitrate at rate_hz.
 * @param bitrate bit/s of the bus (> 0)
 * @param max_rate receives the highest SYNC rate (Hz) the bus carries for this mapping (may be NULL)
 * @return 0, or -MSID_DAQ_E_ARG with err saying the bits a cycle takes and the rate the bus carries
 */
int msid_co_map_check_bus(const msid_co_map *m, uint32_t bitrate, double rate_hz, double *max_rate, char *err,
                          size_t len);

/**
 * @brief Every entry the run reads or writes, against the node's EDS/DCF, before anything is written: each
 *        channel's object (in the file, of the CiA 301 type its `type` names: int16 INTEGER16, uint16
 *        UNSIGNED16, int32 INTEGER32, uint32 UNSIGNED32, float32 REAL32; PDO-mappable; a drive channel
 *        writable, a measure channel readable), the PDO parameters written (0x1400/0x1600, 0x1800/0x1A00 of
 *        the PDOs used; a TPDO's inhibit time 0x18xx:03 only when the file has it), the controlword 0x6040
 *        and statusword 0x6041, the modes 0x6060/0x6061, the cycle period 0x1006, the producer heartbeat time
 *        0x1017 (heartbeat_ms) and the rated torque 0x6076 (read when the description gives none).
 * @param m after ::msid_co_map_init (m->d's rated_torque still NAN when the node's 0x6076 is to be read)
 * @return 0, or -MSID_DAQ_E_ARG with err naming the entry, its use (the channel and its line in the
 *         description), the problem and the file
 */
int msid_co_map_check_eds(const msid_co_map *m, const msid_co_eds *eds, char *err, size_t len);

#ifdef __cplusplus
}
#endif
#endif
