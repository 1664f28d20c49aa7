/**
 * @file msid_candump.h
 * @brief candump .log files: a writer, and a replay transport.
 *
 * One frame per line, as `candump -l` writes and can-utils' canplayer and
 * python-can's CanutilsLogReader read:
 *   (1700000000.123456) vcan0 212#0102030405060708 R     classic, received
 *   (1700000000.123456) vcan0 201#0100000001000000 T     classic, sent by the logging host
 *   (1700000000.123456) vcan0 248##1<128 hex digits> R   CAN FD (flags digit)
 *   (1700000000.123456) vcan0 20000040#0000000000000000  error frame (8 hex digits, no direction)
 *   (1700000000.123456) vcan0 1ABCDEF0#... R             29-bit identifier
 * The direction (T: the frame has MSID_CANF_TX, R: received) is written as python-can's
 * CanutilsLogWriter and `candump -x` write it; the reader accepts lines with and without it
 * (without: received) and sets MSID_CANF_TX for T.
 * The replay backend returns the frames in file order with their timestamps;
 * a malformed line stops the replay with -MSID_DAQ_E_FORMAT and its line number
 * (after the frames before it have been returned).
 */
#ifndef MSID_CANDUMP_H
#define MSID_CANDUMP_H

#include <stdio.h>
#include "msid_can_transport.h"

#ifdef __cplusplus
extern "C" {
#endif

/** @brief Format one frame as a candump log line (with '\n'); returns its length. buf: >= 200 bytes. */
int msid_candump_format(char *buf, size_t cap, const msid_can_frame *f, const char *iface);

/**
 * @brief Parse one candump log line.
 * @return 0, 1 for a blank line, or -MSID_DAQ_E_FORMAT.
 */
int msid_candump_parse(const char *line, msid_can_frame *f, char *iface, size_t iface_cap);

/** Replay state (caller-owned). */
typedef struct msid_candump_reader {
    msid_can_transport tr;
    FILE *fp;
    uint64_t line;         /**< lines read */
    int pending;           /**< error to return on the next call (after the frames before it) */
    msid_can_link_stats st;
    char err[256];
    char iface[32];        /**< interface of the last frame */
} msid_candump_reader;

/** @brief Open a log for replay. @return 0 or -MSID_DAQ_E_IO (detail in r->err). */
int msid_candump_open(msid_candump_reader *r, const char *path);

/** @brief Rewind to the first line (for a second pass). */
void msid_candump_rewind(msid_candump_reader *r);

#ifdef __cplusplus
}
#endif
#endif
