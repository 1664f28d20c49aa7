/**
 * @file sim_mapdev.h
 * @brief msid-devsim as a device that does not run msid's firmware: a plant
 *        behind a register map or DBC signals described by msid-device/1,
 *        written as a drive's or PLC's firmware would be. The host writes
 *        setpoints and reads measured values whenever it likes; the device
 *        runs its own cycle on its own clock.
 *
 * Cycle k runs at device time k / cycle_hz; the device's clock runs
 * (1 + ppm 1e-6) times the host's (a crystal's offset). At each cycle the
 * device takes the latest setpoint of every drive channel (the input it
 * applies for this cycle), computes the outputs y = C x + D u (+ noise),
 * publishes the applied input (+ noise) for the channels that read it back,
 * the outputs, its cycle counter and the setpoint of reference channels, and
 * steps the plant x <- A x + B u. A setpoint written between two cycles is
 * applied from the next cycle on; a read returns what the last cycle
 * published. The cycles are run when a request arrives, up to its arrival
 * time (the same result as a timer, without one). All state in one
 * ::sim_mapdev; no allocation.
 */
#ifndef MSID_SIM_MAPDEV_H
#define MSID_SIM_MAPDEV_H

#include <stdint.h>
#include "msid/msid.h"
#include "msid_daq/msid_devdesc.h"
#include "sim_plant.h"

/** Options of a described device. */
typedef struct sim_mapdev_opts {
    double cycle_hz;              /**< the device's cycle rate on its own clock */
    double ppm;                   /**< its clock against the host's, parts per million */
    double sigma_y, sigma_u;      /**< output and read-back noise (std, physical units) */
    uint64_t seed;
} sim_mapdev_opts;

/** The device. */
typedef struct sim_mapdev {
    const msid_devdesc *desc;
    sim_plant_def pd;             /**< discrete-time, at the cycle rate: nu = drive channels, ny = output channels */
    sim_mapdev_opts o;
    msid_rng rng;
    double t0;                    /**< host time of cycle 0 (s, CLOCK_MONOTONIC) */
    uint64_t cycles;              /**< cycles run */
    double x[SIM_MAX_STATES];
    double setpoint[MSID_DEV_MAX_DRIVE];   /**< latest setpoints (physical) */
    double value[MSID_DEV_MAX_MEASURE];    /**< what the last cycle published (physical) */
    uint32_t out_of[MSID_DEV_MAX_MEASURE]; /**< per output channel the plant output it publishes; per input channel
                                                the drive channel it reads back */
} sim_mapdev;

/**
 * @brief Set up over a description and a discrete-time plant whose inputs are the drive channels and outputs the
 *        output channels (in the description's order). The setpoints start at the safe values.
 * @return 0, or -1 with a message in err
 */
int sim_mapdev_init(sim_mapdev *s, const msid_devdesc *d, const sim_plant_def *pd, const sim_mapdev_opts *o,
                    char *err, size_t cap);

/** @brief Run the cycles due by host time now_s (each takes the setpoints as they are now). */
void sim_mapdev_advance(sim_mapdev *s, double now_s);

#endif
