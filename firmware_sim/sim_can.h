/**
 * @file sim_can.h
 * @brief msid-devsim's CAN front end: msid-can/1 over SocketCAN
 *        (docs/can-protocol.md), with fault injection.
 */
#ifndef MSID_SIM_CAN_H
#define MSID_SIM_CAN_H

#include "sim_device.h"

/** @brief Serve msid-can/1 on d->o.iface until *d->stop (or --idle-exit); process exit status. */
int sim_can_main(sim_device *d);

#endif
