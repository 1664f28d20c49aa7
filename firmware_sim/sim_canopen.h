/**
 * @file sim_canopen.h
 * @brief msid-devsim's CANopen front end: the CiA 402 drive node of sim_co_node.h on a SocketCAN interface.
 */
#ifndef MSID_SIM_CANOPEN_H
#define MSID_SIM_CANOPEN_H

#include "sim_co_node.h"
#include "sim_device.h"

/** What the front end serves. */
typedef struct sim_canopen_opts {
    unsigned node;           /**< 1..127 */
    const char *eds;         /**< the EDS of the object dictionary */
    sim_co_faults f;
} sim_canopen_opts;

/** @brief Serve until a signal (or --idle-exit seconds without a frame). @return the exit status. */
int sim_canopen_main(sim_device *d, const sim_canopen_opts *o);

#endif
