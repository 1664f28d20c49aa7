/**
 * @file sim_modbus.h
 * @brief msid-devsim's Modbus front end: msid-modbus/1 over libmodbus TCP or
 *        RTU (docs/modbus-registers.md), with fault injection.
 */
#ifndef MSID_SIM_MODBUS_H
#define MSID_SIM_MODBUS_H

#include "sim_device.h"

/** @brief Serve msid-modbus/1 (d->o.mb_tcp or d->o.mb_rtu) until *d->stop (or --idle-exit); process exit status. */
int sim_modbus_main(sim_device *d);

#endif
