/**
 * @file sim_mbmap.h
 * @brief msid-devsim's Modbus front end for a described device (msid-device/1): the description's registers
 *        over libmodbus TCP or RTU, the device's cycle behind them (sim_mapdev.h), fault injection.
 */
#ifndef MSID_SIM_MBMAP_H
#define MSID_SIM_MBMAP_H

#include "sim_device.h"
#include "sim_mapdev.h"

/** @brief Serve until a signal (or --idle-exit). The plant is d->pd. @return the exit status. */
int sim_mbmap_main(sim_device *d, const msid_devdesc *desc, const sim_mapdev_opts *mo);

#endif
