/* The bus budget of a SYNC cycle (msid_co_bus.h). */
#include "msid_daq/msid_co_bus.h"

#include <stdio.h>

unsigned msid_co_frame_bits(unsigned bytes)
{
    if (bytes > 8) return 0;
    /* SOF, identifier, RTR, IDE, r0, DLC, data and CRC are stuffed: 34 + 8 bytes bits, a stuff bit at worst
       after every 4 following the first; CRC delimiter, ACK, EOF and intermission are 13 more */
    const unsigned stuffed = 34u + 8u * bytes;
    return stuffed + (stuffed - 1u) / 4u + 13u;
}

int msid_co_bus_check(uint32_t bitrate, double rate_hz, unsigned sync_bytes, const uint8_t *pdo_bytes, unsigned n,
                      double max_share, double *max_rate, char *err, size_t len)
{
    if (bitrate == 0 || !(rate_hz > 0) || sync_bytes > 1 || (n && !pdo_bytes) || !(max_share > 0 && max_share <= 1)) {
        snprintf(err, len, "bus check: bit rate, rate, SYNC length or share out of range");
        return -MSID_DAQ_E_ARG;
    }
    unsigned bits = msid_co_frame_bits(sync_bytes);
    for (unsigned i = 0; i < n; i++) {
        if (pdo_bytes[i] > 8) {
            snprintf(err, len, "PDO %u of %u bytes: a classic CAN frame carries at most 8", i + 1, (unsigned)pdo_bytes[i]);
            return -MSID_DAQ_E_ARG;
        }
        bits += msid_co_frame_bits(pdo_bytes[i]);
    }
    const double fits = max_share * (double)bitrate / (double)bits;
    if (max_rate) *max_rate = fits;
    if (rate_hz <= fits) return 0;
    snprintf(err, len,
             "at %g Hz the SYNC and %u PDO%s take %u bits a cycle (%.0f kbit/s at worst), above %.0f%% of the %.0f kbit/s "
             "bus: it carries them at up to %.0f Hz",
             rate_hz, n, n == 1 ? "" : "s", bits, bits * rate_hz / 1000.0, 100.0 * max_share, bitrate / 1000.0, fits);
    return -MSID_DAQ_E_ARG;
}
