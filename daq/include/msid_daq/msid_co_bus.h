/**
 * @file msid_co_bus.h
 * @brief What a classic CAN bus carries per SYNC cycle: the worst-case length of each frame (bit stuffing
 *        included) and the highest SYNC rate at which the SYNC and the mapped PDOs fit in a share of the
 *        bit rate. A rate the bus cannot carry is refused before anything is written, with the rate it can.
 */
#ifndef MSID_CO_BUS_H
#define MSID_CO_BUS_H

#include <stddef.h>
#include <stdint.h>
#include "msid_daq.h"

#ifdef __cplusplus
extern "C" {
#endif

/**
 * @brief Bits on the bus of a classic frame with an 11-bit identifier and `bytes` (0..8) of data, at worst:
 *        47 + 8 bytes fixed and data bits, and one stuff bit per 4 of the 34 + 8 bytes stuffed ones after
 *        the first: 55 + 10 bytes (55 bits for 0 bytes, 135 for 8; Davis et al., CAN schedulability analysis).
 *        0 for more than 8 bytes.
 */
unsigned msid_co_frame_bits(unsigned bytes);

/**
 * @brief Check that a SYNC (of sync_bytes, 0 or 1) and PDOs of pdo_bytes[0..n) every cycle fit at rate_hz in
 *        max_share (0 < share <= 1) of bitrate bit/s.
 * @param max_rate receives the highest rate that fits (may be NULL)
 * @return 0, or -MSID_DAQ_E_ARG with err saying what the cycle takes and the rate the bus carries
 */
int msid_co_bus_check(uint32_t bitrate, double rate_hz, unsigned sync_bytes, const uint8_t *pdo_bytes, unsigned n,
                      double max_share, double *max_rate, char *err, size_t len);

#ifdef __cplusplus
}
#endif
#endif
