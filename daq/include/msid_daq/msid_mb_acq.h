/**
 * @file msid_mb_acq.h
 * @brief The Modbus acquisition adapter: msid-modbus/1 device -> ::msid_stream -> ::msid_meas.
 *
 * Every request goes through ::msid_mb_call: at most 125 registers per read,
 * explicit timeouts (the transport's), retries with exponential backoff, a
 * flush after a bad CRC or a reply that does not match, and a reconnect of
 * its own (close, flush, connect) after a timeout or a lost connection;
 * exception responses 5 (acknowledge) and 6 (busy) are retried, every other
 * exception stops with its name. Nothing waits without a bound.
 *
 * Polling (::msid_mb_acq_poll): read the header, then the new ring samples
 * in batches of requests. Samples the device overwrote before they were read
 * (write index - ring capacity beyond the read position) are declared
 * missing: every period they touch is rejected and counted (overrun). Every
 * sample carries its index mod 65536 as a tag; a tag that does not match is
 * either an overwrite that raced the read (the header read after it says so:
 * missing) or a stale reply (flushed and read again), never data. A new
 * segment (device restart) closes the current one and opens another of the
 * same experiment at the device's segment start. No allocation: memory comes
 * from the caller.
 *
 * Errors: every function of the client and the poller returns 0 (or 1, see
 * ::msid_mb_acq_poll) or a negative code of the daq error space (msid_daq.h):
 * -msid_daq_status for the link, the device (-MSID_DAQ_E_DEVICE, its error
 * decoded by name) and the protocol (-MSID_DAQ_E_PROTOCOL, -MSID_DAQ_E_BADDATA),
 * or the core's status carried unchanged (::msid_daq_core) when the core
 * refused. The client's err says what and why.
 */
#ifndef MSID_MB_ACQ_H
#define MSID_MB_ACQ_H

#include "msid_mb_proto.h"
#include "msid_mb_transport.h"
#include "msid_stream.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Link counters of a client (cumulative). */
typedef struct msid_mb_link_counters {
    uint64_t requests, registers_read, registers_written;
    uint64_t retries, timeouts, crc_errors, exceptions, bad_replies, io_errors, reconnects;
    uint64_t skipped_replies;   /**< TCP: replies read past because their transaction or unit id was not the
                                     request's (a stale duplicate, a foreign reply); not a failure by itself */
    uint64_t malformed_frames;  /**< TCP: frames with a length or protocol id out of range (reconnected) */
} msid_mb_link_counters;

/** A client of one msid-modbus/1 device: retried requests, header, upload, commands (caller-owned). */
typedef struct msid_mb_client {
    msid_mb_transport *tr;
    uint32_t retries;           /**< attempts after the first */
    uint32_t backoff_ms;        /**< first backoff, doubled per attempt up to 1 s */
    msid_mb_header h;           /**< last header read */
    uint32_t cmd_seq, cfg_seq;
    msid_mb_link_counters cnt;
    char err[320];              /**< message of the last failure */
    int drain;                  /**< a reply did not match its request: the link is flushed before every request */
} msid_mb_client;

/** Configuration of the ring poller. */
typedef struct msid_mb_acq_cfg {
    msid_mb_client *client;
    uint32_t max_regs;          /**< registers per read, 1..125 (0: 125) */
    uint32_t batch;             /**< ring reads per poll (0: 8) */
    uint32_t n_inputs, n_outputs;
    uint32_t encoding, word_order;
    double scale;               /**< int16/int32 step */
    msid_meas *meas;            /**< the measurement to feed */
    uint32_t period;            /**< P of the design (0: unchecked). With it the header's P and TOTAL must be the
                                     design's P and K P, a segment ends after K P samples whether or not the
                                     device reports DONE, and a write index that steps back or a DONE before
                                     K P samples is a protocol error: the device's counts never size the work. */
    /** ::msid_mb_acq_run calls it after every poll (NULL: none), e.g. to draw progress; a non-zero return
        stops the experiment: see ::msid_mb_acq_run. */
    int (*on_poll)(void *user);
    void *user;                 /**< passed to on_poll */
} msid_mb_acq_cfg;

/** Counters of the poller (cumulative). */
typedef struct msid_mb_counters {
    uint64_t polls;
    uint64_t overrun_samples;   /**< samples overwritten before they were read (declared missing) */
    uint64_t overrun_events;    /**< runs of them */
    uint64_t stale_replies;     /**< ring replies whose tags did not match and were read again */
    uint64_t restarts;          /**< new segments seen (device restarts) */
    uint64_t experiments_done;
    uint64_t device_overruns;   /**< the device's own overrun count, summed over experiments */
    uint64_t done_missing;      /**< experiments closed after K P samples while the device still reported RUNNING */
    uint64_t stream_ns;         /**< ::msid_mb_acq_run: sum over experiments of the time from START to the last sample */
} msid_mb_counters;

/** Ring poller (caller-owned). */
typedef struct msid_mb_acq {
    msid_mb_acq_cfg cfg;
    msid_mb_client *cl;
    uint32_t C, W;              /**< channels, registers per sample */
    msid_stream st;
    uint16_t *buf;              /**< [max_regs] */
    double *row;                /**< [C] */
    int open;                   /**< experiment running */
    uint32_t exp;
    uint64_t r;                 /**< next sample index (of the run) to read */
    uint32_t seg;               /**< segment number */
    uint64_t seg_start;         /**< its first sample index */
    uint64_t total;             /**< K P: samples per segment (0: unchecked) */
    msid_mb_counters cnt;
} msid_mb_acq;

/** Request kinds of ::msid_mb_call. */
enum { MSID_MB_READ_INPUT = 0, MSID_MB_READ_HOLDING = 1, MSID_MB_WRITE_HOLDING = 2 };

/** @brief Set a client up on a transport (retries 0: 5, backoff 0: 20 ms). */
void msid_mb_client_init(msid_mb_client *c, msid_mb_transport *tr, uint32_t retries, uint32_t backoff_ms);

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_mb_acq_mem_size(const msid_mb_acq_cfg *cfg);

/**
 * @brief Initialise on `len` bytes of caller memory at `mem` (MSID_MEM_ALIGN-aligned, ::msid_mb_acq_mem_size).
 * @return 0, or the core's reason as ::msid_daq_core(MSID_E_NULL / MSID_E_DIMS / MSID_E_ARG / MSID_E_MEM_SIZE /
 *         MSID_E_MEM_ALIGN).
 */
int msid_mb_acq_init(msid_mb_acq *a, const msid_mb_acq_cfg *cfg, void *mem, size_t len);

/**
 * @brief One request with retries, backoff, flush and reconnect.
 * @return 0, or -msid_daq_status after the last attempt (c->err says what and why).
 */
int msid_mb_call(msid_mb_client *c, int kind, uint32_t addr, uint32_t n, uint16_t *regs);

/**
 * @brief Read and check the header (magic) into c->h.
 * @return 0, -MSID_DAQ_E_BADDATA (not an msid-modbus device, c->err) or a transport error.
 */
int msid_mb_read_header(msid_mb_client *c);

/**
 * @brief Upload a configuration: the stream format registers, then the
 *        parameter records (msid-can/1 CFG frames, BEGIN..COMMIT) through the
 *        mailbox, MSID_MB_CFG_RECORDS per write, each block with a new
 *        sequence number (a retried write is applied once). Reads the header
 *        after: the caller checks state, error and CRC.
 */
int msid_mb_upload(msid_mb_client *c, uint32_t encoding, uint32_t word_order, const uint8_t (*rec)[8], size_t n);

/**
 * @brief Read the header and check the register map version.
 * @return 0, -MSID_DAQ_E_PROTOCOL (another version; c->err), -MSID_DAQ_E_BADDATA (not an msid-modbus
 *         device) or a transport error.
 */
int msid_mb_identify(msid_mb_client *c);

/**
 * @brief ::msid_mb_upload, then the device's verdict decoded: CONFIGURED with the CRC of the COMMIT record.
 * @return 0, -MSID_DAQ_E_DEVICE (refused: the device's error name and, for a refused design, the core's
 *         reason in c->err), -MSID_DAQ_E_PROTOCOL (not confirmed, or another CRC) or a transport error.
 */
int msid_mb_configure(msid_mb_client *c, uint32_t encoding, uint32_t word_order, const uint8_t (*rec)[8], size_t n);

/** @brief Execute a command (START, STOP, RESET) and wait (bounded) until the device reports it done. */
int msid_mb_command(msid_mb_client *c, uint32_t cmd, uint32_t experiment, uint32_t periods);

/**
 * @brief START experiment e (K periods, 0: configured) and open it in the stream.
 * @return 0, -MSID_DAQ_E_DEVICE (refused, decoded in the client's err), -MSID_DAQ_E_BADDATA (a ring or
 *         counts that do not match), a core status (::msid_daq_core) or a transport error.
 */
int msid_mb_acq_start(msid_mb_acq *a, uint32_t e, uint32_t periods);

/**
 * @brief One poll: the header, then up to `batch` ring reads.
 * @return 1 when the experiment is complete (closed in the measurement),
 *         0 to poll again, -msid_daq_status on a transport failure, a device
 *         error (-MSID_DAQ_E_DEVICE) or a protocol error (the client's err),
 *         or the core's status (::msid_daq_core, e.g. MSID_E_CAPACITY) when
 *         the measurement refused the samples.
 * @param progressed set to 1 if new samples were read or declared missing
 */
int msid_mb_acq_poll(msid_mb_acq *a, int *progressed);

/**
 * @brief Run experiment e (K = periods) to its end: START, then poll (sleeping idle_us between polls that
 *        brought nothing) until the experiment is complete; a device that keeps reporting RUNNING after
 *        the design's K P samples is sent STOP. After every poll the configured on_poll is called; when it
 *        returns non-zero the experiment is closed in the stream where it stands (every complete period is
 *        kept, the partial last one is discarded and counted), the device is sent STOP (best effort: it may
 *        be gone) and the call returns -MSID_DAQ_E_STOPPED (or the core's status if the close was refused).
 *        A request that failed while a stop was requested (a signal cut it short) counts as the stop.
 * @param silence_ms give up when no new sample arrived this long
 * @return 0; -MSID_DAQ_E_STOPPED (on_poll asked), -MSID_DAQ_E_TIMEOUT (no new sample), -MSID_DAQ_E_BADDATA
 *         (replies that did not match their requests, or a protocol error), -MSID_DAQ_E_DEVICE, a core status (::msid_daq_core, e.g.
 *         MSID_E_CAPACITY) or a transport error. The client's err says what.
 */
int msid_mb_acq_run(msid_mb_acq *a, uint32_t e, uint32_t periods, uint32_t silence_ms, uint32_t idle_us);

#ifdef __cplusplus
}
#endif
#endif
