/**
 * @file sim_candbc.h
 * @brief msid-devsim's CAN front end for a described device (msid-device/1 with a DBC): a node on SocketCAN
 *        that takes the command messages the host sends and sends its status messages once per cycle of its
 *        own clock (sim_mapdev.h), as an ECU or a drive does; fault injection (clock offset, dropped and late
 *        status frames, a node that dies).
 */
#ifndef MSID_SIM_CANDBC_H
#define MSID_SIM_CANDBC_H

#include "sim_device.h"
#include "sim_mapdev.h"

/** Faults of the CAN node. */
typedef struct sim_candbc_faults {
    uint64_t drop_every;     /**< k: the k-th, 2k-th, .. status cycle sends nothing (0: none) */
    uint64_t late_every;     /**< k: every k-th status cycle's frames are sent late_us late (0: none) */
    uint64_t late_us;
    uint64_t die_after;      /**< exit at once after this many status cycles (0: never) */
} sim_candbc_faults;

/**
 * @brief Serve until a signal (or --idle-exit after the last command frame). The plant is d->pd; the DBC is the
 *        description's. @return the exit status.
 */
int sim_candbc_main(sim_device *d, const msid_devdesc *desc, const sim_mapdev_opts *mo, const sim_candbc_faults *f);

#endif
