/* CANopen basics: node ids and the io's clock. */
#define _POSIX_C_SOURCE 200809L
#include "msid_daq/msid_co.h"

#include <time.h>

int msid_co_node_valid(unsigned node)
{
    return node >= MSID_CO_NODE_MIN && node <= MSID_CO_NODE_MAX;
}

uint64_t msid_co_now_ms(const msid_co_io *io)
{
    if (io && io->now_ms) return io->now_ms(io->ctx);
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000u + (uint64_t)t.tv_nsec / 1000000u;
}
