/**
 * @file msid_can_map.h
 * @brief A CAN device described by msid-device/1 and its DBC as an
 *        ::msid_devio backend: the drive channels packed into their command
 *        message(s) and sent once per tick, the measure channels decoded from
 *        the status frames the device sends back.
 *
 * Resolving (::msid_can_map_init) checks the description against the DBC and
 * refuses, with one message naming the channel, its line and the DBC signal:
 * a message or a signal the DBC does not have (the message's signals listed);
 * a `type` that does not match the signal (int16 is a 16-bit signed integer
 * signal, float32 a `SIG_VALTYPE_` 1 signal, ...); a drive channel whose safe
 * value, min, max or operating point does not fit its signal (its bits, or the
 * DBC's range); a drive channel in a message the device sends (a message that
 * carries a measure channel, or one whose DBC sender is the node that sends
 * the status messages); two drive channels on one signal, a drive channel on a
 * multiplexer switch, two drive channels of one message under different
 * multiplexer values; a counter that is not an integer signal.
 *
 * Values: description physical = DBC physical * scale + offset (the DBC's
 * factor and offset first). The signals of a command message that no drive
 * channel names are sent as raw 0 in every frame (the switch of a multiplexed
 * command message as the value of its drive channels).
 *
 * One exchange takes the status frames that arrived since the previous
 * exchange, waiting at most `wait_ns` for a fresh frame of every measure
 * channel, then sends every command message once: the sample is the newest
 * value of each channel, what the device published before this tick's command
 * (as a register read returns the cycle before a write). A channel with no
 * fresh frame makes the exchange fail (a missing sample, counted as a stale
 * tick; the command is sent all the same): a value is never held over a tick. Error
 * frames (bus errors), frames too short for their signals, frames of other
 * identifiers and the kernel's drops are counted. No allocation: the frames
 * and the resolved signals live in the object.
 */
#ifndef MSID_CAN_MAP_H
#define MSID_CAN_MAP_H

#include "msid_can_transport.h"
#include "msid_dbc.h"
#include "msid_devdesc.h"
#include "msid_devio.h"

#ifdef __cplusplus
extern "C" {
#endif

/** One DBC message as the map uses it: a command the host sends or a status it receives. */
typedef struct msid_can_map_msg {
    const msid_dbc_message *m;
    uint8_t data[MSID_DBC_MAX_DLC];   /**< command: the next frame's payload; status: the newest payload */
    uint64_t frames;                  /**< frames sent (command) or received (status) */
    int64_t last_ns;                  /**< status: arrival of the newest frame (CLOCK_MONOTONIC ns, 0: none) */
} msid_can_map_msg;

/** Counters (cumulative). */
typedef struct msid_can_map_counters {
    uint64_t exchanges;      /**< ticks exchanged */
    uint64_t frames_sent;    /**< command frames sent */
    uint64_t send_failures;  /**< command frames the transport refused (queue full for the whole timeout, link down) */
    uint64_t status_frames;  /**< frames of a status message received */
    uint64_t other_frames;   /**< frames of identifiers the map does not read */
    uint64_t bus_errors;     /**< error frames (CAN_ERR_*) */
    uint64_t short_frames;   /**< status frames too short for a signal of theirs (not decoded) */
    uint64_t stale;          /**< exchanges in which a measure channel had no fresh frame (missing samples) */
    uint64_t superseded;     /**< status frames overwritten by a newer frame of their message in the same tick */
} msid_can_map_counters;

/** The mapped device (caller-owned). */
typedef struct msid_can_map {
    msid_devio io;                 /**< the backend to hand to the tick loop */
    const msid_devdesc *desc;
    const msid_dbc *dbc;
    msid_can_transport *tr;        /**< NULL: codec only (::msid_can_map_pack, ::msid_can_map_take) */
    uint32_t n_cmd, n_st;
    msid_can_map_msg cmd[MSID_DEV_MAX_DRIVE], st[MSID_DEV_MAX_MEASURE];
    const msid_dbc_signal *dsig[MSID_DEV_MAX_DRIVE], *msig[MSID_DEV_MAX_MEASURE];
    uint32_t cmd_of[MSID_DEV_MAX_DRIVE], st_of[MSID_DEV_MAX_MEASURE];   /**< each channel's message */
    int32_t cmd_mux[MSID_DEV_MAX_DRIVE];   /**< per command message: the switch's raw value (-1: not multiplexed) */
    double value[MSID_DEV_MAX_MEASURE];    /**< newest value of each measure channel (NAN: none yet) */
    uint8_t fresh[MSID_DEV_MAX_MEASURE];   /**< decoded since the last exchange */
    int64_t newest_ns;             /**< arrival of the newest status frame taken (CLOCK_MONOTONIC ns) */
    int64_t wait_ns;               /**< how long an exchange waits for fresh status frames (default 1 ms) */
    int64_t read_wait_ns;          /**< how long a read alone waits (msid device check; default 1 s) */
    int send_timeout_ms;           /**< how long a full send queue is retried (default 1) */
    msid_can_map_counters cnt;
    char how[200];
    char err[400];
} msid_can_map;

/**
 * @brief Resolve a CAN description against its DBC.
 * @param tr  the bus (NULL: the codec only, for tests and for a simulator)
 * @return 0, or -MSID_DAQ_E_ARG with err naming the channel, its line and what does not match
 */
int msid_can_map_init(msid_can_map *m, const msid_devdesc *d, const msid_dbc *dbc, msid_can_transport *tr);

/**
 * @brief Pack drive values [n_drive] (description physical units) into the command messages' payloads.
 * @return 0, or -MSID_DAQ_E_RANGE with err when a value does not fit its signal (payloads unchanged)
 */
int msid_can_map_pack(msid_can_map *m, const double *drive);

/**
 * @brief Take one received frame: a status frame's channels decoded into value[] (marked fresh), error frames
 *        and frames of other identifiers counted.
 * @param now_ns  its arrival (CLOCK_MONOTONIC ns)
 * @return 1 a status frame, 0 anything else
 */
int msid_can_map_take(msid_can_map *m, const msid_can_frame *f, int64_t now_ns);

/**
 * @brief Decode a status payload of message index s into description physical values of every measure channel
 *        it carries (a multiplexed channel only when the frame carries it); measure[] of other channels untouched.
 * @param got  NULL, or [n_measure] flags set to 1 for the channels decoded
 * @return the channels decoded
 */
uint32_t msid_can_map_decode(const msid_can_map *m, uint32_t s, const uint8_t *data, size_t len, double *measure,
                             uint8_t *got);

/** @brief Index of the status message of identifier id (-1: none). */
int msid_can_map_status_index(const msid_can_map *m, uint32_t id);

/** @brief Counts after which measure channel i (a counter) wraps: 2^length of its signal. */
double msid_can_map_modulus(const msid_can_map *m, uint32_t i);

#ifdef __cplusplus
}
#endif
#endif
