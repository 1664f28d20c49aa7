/**
 * @file msid_can_decoder.h
 * @brief msid-can/1 frames -> sample rows -> ::msid_meas.
 *
 * The decoder follows the device: a STATUS RUNNING(e) frame opens experiment
 * e in the measurement, sample frames are assembled into rows [u; y] (a row
 * may span several frames), and STATUS DONE(e, n) closes it after checking
 * that samples 0..n-1 all arrived. A small reorder window (W samples) puts
 * reordered frames back in place and drops duplicates. A sample still
 * incomplete when it leaves the window is missing: it is declared to the
 * core with ::msid_meas_push_gap, so every period it touches is discarded and
 * counted, never averaged in. Sequence gaps are counted here; kernel drops
 * (SO_RXQ_OVFL) are the transport's, kept apart. A device restart (a
 * segment-start sample after the window) closes the segment and opens a new
 * one (::msid_meas_begin again: the skip periods apply again). Error frames
 * are decoded into the bus state; bus-off and controller overflow also
 * discard the current period (::msid_meas_mark_gap). Rows, gaps and segments
 * reach the core through the shared ::msid_stream. Malformed frames (wrong
 * length, FD flag, chunk, or period marker) are counted and ignored.
 * Same frames in, same rows and gaps out: live and replayed runs give
 * bit-identical statistics. No allocation: memory comes from the caller.
 */
#ifndef MSID_CAN_DECODER_H
#define MSID_CAN_DECODER_H

#include "msid/msid_meas.h"
#include "msid_can_proto.h"
#include "msid_can_transport.h"
#include "msid_stream.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Largest reorder window, in samples. */
#define MSID_CAN_MAX_WINDOW 256u

/** Bus state from error frames. */
typedef enum msid_can_bus_state {
    MSID_CAN_BUS_ACTIVE = 0, MSID_CAN_BUS_WARNING = 1, MSID_CAN_BUS_PASSIVE = 2,
    MSID_CAN_BUS_OFF = 3, MSID_CAN_BUS_RESTARTED = 4
} msid_can_bus_state;

/** Configuration. */
typedef struct msid_can_decoder_cfg {
    uint32_t base;          /**< base identifier (multiple of 0x80) */
    uint32_t n_inputs;      /**< nu */
    uint32_t n_outputs;     /**< ny; nu + ny <= MSID_MAX_CHANNELS */
    uint32_t encoding;      /**< MSID_CAN_ENC_S16 or MSID_CAN_ENC_F32 */
    uint32_t fd;            /**< 1: CAN FD sample frames */
    double scale;           /**< int16 step; a float32 value is taken as the decimal it stands for (0.001f: 0.001, as the DBC) */
    uint32_t period;        /**< P: checks the period-start markers */
    uint32_t window;        /**< reorder window in samples, 1..MSID_CAN_MAX_WINDOW (0: 16) */
    uint32_t block;         /**< rows per ::msid_meas_push (0: 256) */
    msid_meas *meas;        /**< the measurement to feed */
    uint64_t samples_total; /**< K P: samples per experiment segment the design allows (0: unchecked). A DONE
                                 frame announcing more, or a sample index at or beyond it, is malformed: the
                                 experiment closes at K P, so a hostile count cannot size the work. */
} msid_can_decoder_cfg;

/** Counters (cumulative over the run). */
typedef struct msid_can_counters {
    uint64_t frames;          /**< device and bus frames offered (host CTRL/CFG frames not included) */
    uint64_t host_frames;     /**< the host's own CTRL/CFG frames (seen in logs) */
    uint64_t sample_frames;   /**< sample frames used */
    uint64_t samples;         /**< complete rows pushed */
    uint64_t samples_lost;    /**< samples declared missing (pushed as gaps) */
    uint64_t frames_missing;  /**< frames those samples lacked */
    uint64_t gap_events;      /**< runs of missing samples */
    uint64_t duplicates;      /**< frames received twice (ignored) */
    uint64_t reordered;       /**< frames that came after a later frame and were put back in place */
    uint64_t late;            /**< frames for samples already pushed or declared missing */
    uint64_t malformed;       /**< wrong length, FD flag, chunk, marker, or beyond the announced end */
    uint64_t foreign;         /**< sample frames of no open experiment, or identifiers outside the device's */
    uint64_t status_frames;   /**< STATUS frames */
    uint64_t error_frames;    /**< error frames */
    uint64_t err_warning, err_passive, err_bus_off, err_restarted, err_protocol, err_ack, err_ctrl_overflow,
             err_other;      /**< error frames by class */
    uint64_t restarts;        /**< device restarts seen in the sample stream (new segments) */
    uint64_t periods_marked;  /**< periods discarded for bus-off or controller overflow */
    uint64_t experiments_done;/**< experiments closed by DONE */
    uint64_t done_beyond;     /**< DONE frames announcing more than samples_total samples (closed at samples_total) */
    uint64_t stream_ns;       /**< sum over experiments of the time from their first to their last sample frame
                                   (receive timestamps; 0 without timestamps) */
} msid_can_counters;

/** Last device status seen. */
typedef struct msid_can_device {
    int have_info;            /**< an INFO frame was seen */
    uint32_t version, nu, ny, cfg_crc;
    int have_state;
    uint32_t state, experiment, error, value;
    int have_counters;
    uint32_t tec, rec, restarts, tx_dropped;
} msid_can_device;

/** Ring slot (internal). */
typedef struct msid_can_slot {
    int64_t n;                /**< sample index, -1 empty */
    uint64_t mask;            /**< chunks received */
    int emitted;
} msid_can_slot;

/** Decoder (caller-owned). */
typedef struct msid_can_decoder {
    msid_can_decoder_cfg cfg;
    uint32_t C, chunks, per;
    uint64_t full;
    msid_can_slot *slot;      /**< [W] */
    double *row;              /**< [W * C] */
    msid_stream st;           /**< rows and gaps -> msid_meas; st.next is the next sample to emit */
    int open;                 /**< experiment open */
    uint32_t exp;
    int64_t last_s;           /**< last (sample, chunk) received, for reorder counting */
    uint32_t last_k;
    int seen;                 /**< a sample frame of this segment was seen */
    int done_exp;             /**< last experiment closed by DONE (-1 none) */
    uint64_t t_first, t_last; /**< receive times of the experiment's first and last sample frames */
    msid_can_bus_state bus;
    msid_can_counters cnt;
    msid_can_device dev;
} msid_can_decoder;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_can_decoder_mem_size(const msid_can_decoder_cfg *cfg);

/** @brief Initialise. @return MSID_OK, MSID_E_NULL, MSID_E_DIMS, MSID_E_ARG, MSID_E_MEM_SIZE, MSID_E_MEM_ALIGN. */
msid_status msid_can_decoder_init(msid_can_decoder *d, const msid_can_decoder_cfg *cfg, void *mem, size_t len);

/**
 * @brief Process one frame (any identifier; error frames included).
 * @return MSID_OK or the first error of the core (sticky), e.g. MSID_E_CAPACITY.
 */
msid_status msid_can_decoder_feed(msid_can_decoder *d, const msid_can_frame *f);

/** @brief Close an open experiment without a DONE frame (e.g. the device went silent): pending samples are flushed, missing ones declared. */
msid_status msid_can_decoder_abort(msid_can_decoder *d);

/**
 * @brief Apply the 8-byte payload of a STATUS frame to *v (STATE, INFO or COUNTERS).
 * @return the multiplexer it held (MSID_CAN_ST_*), or -1 for an unknown one (v unchanged).
 */
int msid_can_device_update(msid_can_device *v, const uint8_t *data);

/**
 * @brief The int16 step a host decodes with: the decimal an int16 step uploaded as float32 stands for
 *        (0.001f -> 0.001; the shortest %.{1..9}g that reads back as the same float32; a step that is
 *        not a float32 value is kept). A device that estimates on its int16 codes decodes them with it
 *        too, so both see the same doubles (on-device estimation, msid_can_est.h).
 */
double msid_can_step_decimal(double step);

/** @brief The bus state after frame f: an error frame's bus-off, restarted, passive, warning or active class; any other frame leaves s. */
msid_can_bus_state msid_can_bus_state_after(msid_can_bus_state s, const msid_can_frame *f);

/** @brief Name of a bus state ("active", "warning", "passive", "bus-off", "restarted"). */
const char *msid_can_bus_state_name(msid_can_bus_state s);

#ifdef __cplusplus
}
#endif
#endif
