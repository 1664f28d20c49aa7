/**
 * @file msid_can_session.h
 * @brief The CAN device session: one msid-can/1 device on a ::msid_can_transport,
 *        the CAN counterpart of the Modbus client and poller (msid_mb_acq.h).
 *
 * A session walks the device through a measurement, in this order:
 *  1. ::msid_can_session_identify: QUERY, wait for the device's INFO frame and
 *     check its protocol version (s->dev holds inputs, outputs, CRC).
 *  2. ::msid_can_session_attach: hand over the ::msid_can_decoder (sized from
 *     the device's outputs) that feeds the measurement. Frames received before
 *     it (identification) are fed to it first, so its counters cover the whole
 *     session exactly as a replay of the log does.
 *  3. ::msid_can_session_upload: the parameter set as CFG frames with flow
 *     control (after every block of frames a QUERY, and the next block only
 *     once the device has answered: a device with a small receive FIFO is
 *     never overrun), then the device's confirmation and CRC are checked.
 *  4. ::msid_can_session_run per experiment: START, then every received frame
 *     through the decoder until the device's DONE closes the experiment. A
 *     DONE frame lost while the host stalled is recovered: after query_ms
 *     without a new frame the session sends QUERY, and the device's STATE
 *     answer (DONE, samples sent) closes the experiment like the lost frame
 *     would have. Only when nothing but replies to queries arrives for
 *     silence_ms does the run fail as a silent device.
 *
 * On-device estimation (extension estimate/1, msid_can_est.h) is a readout of
 * the same session: after the upload, ::msid_can_session_est_setup switches
 * the device's estimator on (estimate only: no decoder is attached and no
 * sample frame is expected, the experiments are closed by the device's DONE
 * and their progress is the sample count of its STATE answers; or estimate and
 * stream, with a decoder as above); after the experiments,
 * ::msid_can_session_est_solve collects the result block bit for bit.
 *
 * Every frame sent (flagged MSID_CANF_TX) and received passes, in order,
 * through the optional frame hook (a candump log). Errors follow the daq
 * error space (msid_daq.h): 0 or a negative code; device errors are decoded
 * here (-MSID_DAQ_E_DEVICE, the device's error name and, for a refused design,
 * the core's reason in s->err), a decoder refusal carries the core status
 * (::msid_daq_core). No allocation: the caller owns the session, the decoder
 * and the transport. Waits are bounded by the configured timeouts.
 */
#ifndef MSID_CAN_SESSION_H
#define MSID_CAN_SESSION_H

#include <stddef.h>
#include <stdint.h>
#include "msid_can_decoder.h"
#include "msid_can_est.h"
#include "msid_can_proto.h"
#include "msid_can_transport.h"
#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Most SOLVE requests of one ::msid_can_session_est_solve (values lost on the way are asked for again). */
#define MSID_CAN_EST_SOLVES 32u

/** Frames kept from before ::msid_can_session_attach (more are counted in early_dropped, not decoded). */
#define MSID_CAN_SESSION_EARLY 256u

/**
 * Frame hook: called with every frame sent (flags has MSID_CANF_TX) and received.
 * Returns 0 to go on; any other value stops the session with -MSID_DAQ_E_HOOK.
 */
typedef int (*msid_can_frame_hook)(void *user, const msid_can_frame *f);

/** Configuration. Times in milliseconds; 0 selects the default. */
typedef struct msid_can_session_cfg {
    msid_can_transport *tr;      /**< an open transport */
    uint32_t base;               /**< device base identifier, a multiple of 0x80 up to 0x780 */
    uint32_t send_timeout_ms;    /**< a full send queue is retried this long (default 2000) */
    uint32_t reply_timeout_ms;   /**< wait for an answer during the upload (default 5000) */
    uint32_t silence_ms;         /**< fail when only query replies arrive this long in an experiment (default 10000) */
    uint32_t query_ms;           /**< QUERY after this long without a new frame in an experiment (default silence_ms / 4) */
    uint32_t upload_block;       /**< CFG frames between flow-control QUERYs (default 16) */
    msid_can_frame_hook on_frame;/**< NULL: none */
    void *user;                  /**< passed to on_frame */
    /** ::msid_can_session_run calls it after every receive batch or wait (at most 100 ms apart; NULL: none),
        e.g. to draw progress; a non-zero return stops the experiment: see ::msid_can_session_run. */
    int (*on_poll)(void *poll_user);
    void *poll_user;             /**< passed to on_poll */
} msid_can_session_cfg;

/** Counters of the session (cumulative). */
typedef struct msid_can_session_counters {
    uint64_t frames_sent;        /**< CTRL and CFG frames sent */
    uint64_t queries;            /**< QUERY commands sent (identification, flow control, recovery) */
    uint64_t recovery_queries;   /**< QUERYs sent because an experiment went quiet */
    uint64_t done_recovered;     /**< experiments closed by the answer to such a QUERY (their DONE frame was lost) */
    uint64_t early_dropped;      /**< frames before attach beyond MSID_CAN_SESSION_EARLY (not decoded) */
    uint64_t est_solves;         /**< SOLVE requests sent (more than one: values of the block were lost and asked again) */
    uint64_t est_frames;         /**< EST frames received */
    uint64_t error_frames;       /**< error frames received */
} msid_can_session_counters;

/** The session (caller-owned). */
typedef struct msid_can_session {
    msid_can_session_cfg cfg;
    msid_can_device dev;         /**< last device status the session received */
    msid_can_decoder *dec;       /**< attached decoder (NULL before ::msid_can_session_attach) */
    uint32_t crc;                /**< CRC-32 of the uploaded parameter set (the COMMIT value) */
    msid_can_session_counters cnt;
    msid_can_est_view est;       /**< the device's estimator, as its EST frames last said */
    double *est_vals;            /**< result block being collected (::msid_can_session_est_solve) */
    uint8_t *est_got;
    uint32_t est_n;
    uint64_t dones;              /**< STATE DONE frames received (without a decoder: what closes an experiment) */
    uint32_t done_exp;           /**< experiment of the last of them */
    uint64_t progress;           /**< without a decoder: new sample counts in STATE RUNNING, and non-status frames */
    uint32_t last_count;
    msid_can_bus_state bus;      /**< bus state from the error frames received (the decoder's too when attached) */
    uint32_t n_early;
    msid_can_frame early[MSID_CAN_SESSION_EARLY];
    msid_can_frame rx[64];       /**< receive batch */
    char err[320];               /**< message of the last failure */
} msid_can_session;

/** @brief Set a session up on an open transport. @return 0 or -MSID_DAQ_E_ARG (NULL or a base that is not a multiple of 0x80). */
int msid_can_session_init(msid_can_session *s, const msid_can_session_cfg *cfg);

/**
 * @brief QUERY the device and wait up to timeout_ms for its INFO frame.
 * @return 0 (s->dev: version, inputs, outputs), -MSID_DAQ_E_TIMEOUT (no device answered),
 *         -MSID_DAQ_E_PROTOCOL (another protocol version) or a transport error; s->err says which.
 */
int msid_can_session_identify(msid_can_session *s, uint32_t timeout_ms);

/**
 * @brief Attach the decoder that feeds the measurement; frames received so far go through it first.
 * @return 0, -MSID_DAQ_E_ARG (NULL) or the core status the decoder returned (::msid_daq_core).
 */
int msid_can_session_attach(msid_can_session *s, msid_can_decoder *dec);

/**
 * @brief Upload a parameter set (CFG records of ::msid_params_frames, BEGIN..COMMIT) with flow control.
 * @return 0 once the device confirmed it with the same CRC (s->crc); -MSID_DAQ_E_DEVICE (refused: the
 *         device's error name, and the core's reason for a refused design, in s->err), -MSID_DAQ_E_PROTOCOL
 *         (another CRC or version), -MSID_DAQ_E_TIMEOUT (no answer) or a transport/hook/core error.
 */
int msid_can_session_upload(msid_can_session *s, const uint8_t (*rec)[8], size_t n);

/**
 * @brief Run experiment e (K = periods): START, then decode until the experiment is closed by the
 *        device's DONE (or by the answer to a recovery QUERY). Without an attached decoder (on-device
 *        estimation, estimate only) the device's STATE DONE of experiment e closes it, and a recovery
 *        QUERY whose answer reports a new sample count is progress.
 *        When the configured on_poll returns non-zero the experiment is closed in the decoder where it
 *        stands (::msid_can_decoder_abort: every complete period is kept, the partial last one is discarded
 *        and counted) and the device is sent STOP (best effort).
 * @return 0; -MSID_DAQ_E_STOPPED (on_poll asked), -MSID_DAQ_E_DEVICE (the device reported an error), -MSID_DAQ_E_TIMEOUT (silent for
 *         silence_ms), the core status of a decoder refusal (e.g. ::msid_daq_core(MSID_E_CAPACITY): more
 *         periods than the measurement holds), or a transport/hook error. s->err says what.
 */
int msid_can_session_run(msid_can_session *s, uint32_t e, uint32_t periods);

/**
 * @brief Switch the device's estimator on (after the upload, before the first START): ALPHA (two
 *        words) and SETUP, then the device's answer STATE, NEED, HAVE, PERIODS (s->est).
 * @param mode 1 estimate only (no sample frames), 2 estimate and stream
 * @param transient 0 off, 1 flag, 2 drop (msid_transient_mode)
 * @param skip periods skipped at the start of every experiment (at most 65535)
 * @param alpha level of the transient test, in [0, 1)
 * @return 0 (the estimator is accumulating); -MSID_DAQ_E_PROTOCOL (no EST answer within
 *         reply_timeout_ms: a device without the extension, or another extension version);
 *         -MSID_DAQ_E_DEVICE (the device refused: s->est.status holds the msid_status, s->est.need
 *         and s->est.have the byte counts of MSID_E_MEM_SIZE); -MSID_DAQ_E_ARG; or a transport/hook error.
 *         s->err says what.
 */
int msid_can_session_est_setup(msid_can_session *s, uint32_t mode, uint32_t transient, uint32_t skip, double alpha);

/**
 * @brief SOLVE, then collect the result block of n doubles (layout msid_mb_est.h) into vals, bit for bit.
 *        Values lost on the way (a host reading slower than a virtual bus delivers) are asked for again:
 *        SOLVE once more (a ready device resends its block) as long as every answer brings values that
 *        were missing, MSID_CAN_EST_SOLVES times at most.
 * @param got n bytes of scratch (bit 0 low, bit 1 high word seen)
 * @return 0; -MSID_DAQ_E_DEVICE (the estimate failed: s->est.status, s->est.bad1); -MSID_DAQ_E_PROTOCOL
 *         (a block of another size than n, or values still missing after an answer that brought none);
 *         -MSID_DAQ_E_TIMEOUT; or a
 *         transport/hook/core error. s->err says what.
 */
int msid_can_session_est_solve(msid_can_session *s, double *vals, uint8_t *got, uint32_t n);

#ifdef __cplusplus
}
#endif
#endif
