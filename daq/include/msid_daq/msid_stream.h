/**
 * @file msid_stream.h
 * @brief A sample-index stream into ::msid_meas, shared by every acquisition
 *        adapter (the CAN frame decoder, the Modbus ring poller).
 *
 * An adapter knows, for each sample index of an experiment segment, either
 * the row [u; y] or that the sample is missing. It hands them over in index
 * order: ::msid_stream_row for a row, ::msid_stream_lost for a run of missing
 * samples (declared to the core with ::msid_meas_push_gap, so every period
 * they touch is rejected and counted, never averaged in), ::msid_stream_mark
 * to discard the period being assembled. Rows are pushed in blocks.
 * ::msid_stream_begin opens a segment of an experiment (a device restart
 * opens a new segment of the same experiment: the skip periods apply again),
 * ::msid_stream_end closes it. Counters are cumulative. No allocation: memory
 * comes from the caller.
 */
#ifndef MSID_STREAM_H
#define MSID_STREAM_H

#include "msid/msid_meas.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Configuration. */
typedef struct msid_stream_cfg {
    uint32_t n_channels;    /**< nu + ny (the measurement's) */
    uint32_t block;         /**< rows per ::msid_meas_push (0: 256) */
    msid_meas *meas;        /**< the measurement to feed */
} msid_stream_cfg;

/** Counters (cumulative). */
typedef struct msid_stream_counters {
    uint64_t samples;         /**< rows pushed */
    uint64_t samples_lost;    /**< samples declared missing (pushed as gaps) */
    uint64_t gap_events;      /**< runs of missing samples */
    uint64_t periods_marked;  /**< periods discarded with ::msid_stream_mark */
    uint64_t segments;        /**< segments opened */
} msid_stream_counters;

/** Stream (caller-owned). */
typedef struct msid_stream {
    msid_stream_cfg cfg;
    double *rows;             /**< [block * C] pending rows */
    uint32_t nrows;
    uint64_t gap_run;         /**< pending missing samples */
    int open;                 /**< a segment is open */
    uint32_t exp;             /**< its experiment */
    int64_t next;             /**< index in the segment of the next sample */
    msid_stream_counters cnt;
    msid_status err;          /**< first core error (sticky) */
} msid_stream;

/** @brief Bytes of working memory; 0 if cfg is invalid. */
size_t msid_stream_mem_size(const msid_stream_cfg *cfg);

/** @brief Initialise. @return MSID_OK, MSID_E_NULL, MSID_E_DIMS, MSID_E_MEM_SIZE, MSID_E_MEM_ALIGN. */
msid_status msid_stream_init(msid_stream *s, const msid_stream_cfg *cfg, void *mem, size_t len);

/** @brief Open a segment of experiment e at sample 0 (an open segment is closed first). @return the first core error (sticky). */
msid_status msid_stream_begin(msid_stream *s, uint32_t e);

/** @brief The row of sample `next` (n_channels doubles); next advances. @return the first core error (sticky). */
msid_status msid_stream_row(msid_stream *s, const double *row);

/** @brief n missing samples from `next` on; next advances by n. @return the first core error (sticky). */
msid_status msid_stream_lost(msid_stream *s, uint64_t n);

/** @brief Discard the period being assembled (e.g. after a bus-off). @return the first core error (sticky). */
msid_status msid_stream_mark(msid_stream *s);

/**
 * @brief Close the open segment: pending rows and gaps go to the core, an
 *        incomplete last period is discarded (counted by ::msid_meas_leftover).
 * @return the first core error (sticky); MSID_OK if no segment was open.
 */
msid_status msid_stream_end(msid_stream *s);

#ifdef __cplusplus
}
#endif
#endif
