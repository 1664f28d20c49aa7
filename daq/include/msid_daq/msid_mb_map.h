/**
 * @file msid_mb_map.h
 * @brief A Modbus device described by msid-device/1 (its register map) as an
 *        ::msid_devio backend: the drive channels written, the measure
 *        channels read, once per tick, over any Modbus transport.
 *
 * The channels are grouped into spans of contiguous registers: one write
 * (FC 16) per span of drive channels, one read (FC 04 input, FC 03 holding)
 * per span of measure channels; registers between channels are never written
 * nor read (a device may refuse an address it does not map). With function 23
 * (read/write multiple registers: the write first, then the read, in one
 * transaction) and all drive channels in one span, the write and the first
 * span of holding registers to read share one transaction. Requests are not
 * retried within a tick: a tick whose read fails is a missing sample, and the
 * tick loop goes on with the next. When the description has a counter
 * channel that the write's own transaction does not read, the counter is
 * also read just before the write: only a counter that did not move between
 * the two reads says which device cycle took the write. No allocation after
 * init: the spans and the register buffers live in the object.
 */
#ifndef MSID_MB_MAP_H
#define MSID_MB_MAP_H

#include "msid_devdesc.h"
#include "msid_devio.h"
#include "msid_mb_transport.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MSID_MB_MAP_MAX_SPANS (MSID_DEV_MAX_DRIVE + MSID_DEV_MAX_MEASURE)

/** Registers [addr, addr + n) of one table, read or written in one request. */
typedef struct msid_mb_span {
    uint32_t table, addr, n;
} msid_mb_span;

/** Counters (cumulative). */
typedef struct msid_mb_map_counters {
    uint64_t exchanges, requests, failures, timeouts, exceptions, bad_replies, io_errors, recoveries;
    uint32_t last_exception;      /**< code of the last exception response */
    uint32_t last_function;       /**< function code of the request that failed last */
} msid_mb_map_counters;

/** The mapped device (caller-owned). */
typedef struct msid_mb_map {
    msid_devio io;                /**< the backend to hand to the tick loop */
    const msid_devdesc *desc;
    msid_mb_transport *tr;
    int use_fc23;                 /**< write and first holding read in one FC 23 transaction */
    uint32_t n_wspan, n_rspan;
    msid_mb_span wspan[MSID_MB_MAP_MAX_SPANS], rspan[MSID_MB_MAP_MAX_SPANS];
    uint16_t wbuf[MSID_MB_MAP_MAX_SPANS][125], rbuf[MSID_MB_MAP_MAX_SPANS][125];
    int32_t counter;              /**< measure channel of the device's cycle counter (-1: none) */
    uint16_t cbuf[4];             /**< the counter's registers, read before the write (msid_devio_times) */
    uint32_t wspan_of[MSID_DEV_MAX_DRIVE], rspan_of[MSID_DEV_MAX_MEASURE];   /**< each channel's span */
    msid_mb_map_counters cnt;
    int lost;                     /**< the last failure lost the link: recover reconnects */
    char how[128];
    char err[400];
} msid_mb_map;

/**
 * @brief Plan the spans of a Modbus description over transport tr.
 * @param fc23  1: one FC 23 transaction where the plan allows it (all drive channels in one span of at most 121
 *              registers and a holding span to read); 0: FC 16 then the reads
 * @return 0, or -MSID_DAQ_E_ARG when the description is not a Modbus one (err)
 */
int msid_mb_map_init(msid_mb_map *m, const msid_devdesc *d, msid_mb_transport *tr, int fc23);

/** @brief Whether FC 23 can carry the write and a read for this description. */
int msid_mb_map_fc23_possible(const msid_mb_map *m);

/**
 * @brief Read span s of the measure channels alone and decode its channels into measure[] (the others are left
 *        as they are): one refused address names only its own channels (msid device check).
 * @return 0 or -msid_daq_status (err names the registers, the function and the channels)
 */
int msid_mb_map_read_span(msid_mb_map *m, uint32_t s, double *measure);

/** @brief Requests per exchange (1 with FC 23 and a single holding span to read). */
uint32_t msid_mb_map_requests(const msid_mb_map *m);

#ifdef __cplusplus
}
#endif
#endif
