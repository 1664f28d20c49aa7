/**
 * @file sim_mb_server.h
 * @brief msid-devsim's Modbus server plumbing, shared by its front ends (msid-modbus/1: sim_modbus.c; a
 *        described device: sim_mbmap.c): the libmodbus TCP listener and its clients, or an RTU port, and one
 *        poll round that hands every request to the front end. Fixed memory; failures to open end the process.
 */
#ifndef MSID_SIM_MB_SERVER_H
#define MSID_SIM_MB_SERVER_H

#include <stdint.h>
#include "sim_device.h"

#define SIM_MB_MAX_CLIENTS 8

typedef struct sim_mb_server {
    void *mb;                     /**< modbus_t */
    int rtu, listen_fd;
    int clients[SIM_MB_MAX_CLIENTS], n_clients;
    unsigned port;                /**< TCP: the port listened on (0 in --modbus-tcp HOST:0 picks one) */
    char host[128];
} sim_mb_server;

/** @brief Listen on o->mb_tcp (HOST:PORT) or open o->mb_rtu at o->baud with unit id `unit`; exits on failure. */
void sim_mb_server_open(sim_mb_server *s, const sim_opts *o, uint32_t unit);

/** @brief Wait up to timeout_ms, accept new clients, and pass each request (ADU of len bytes) to serve. */
void sim_mb_server_poll(sim_mb_server *s, int timeout_ms, void (*serve)(void *ctx, const uint8_t *q, int len),
                        void *ctx);

/** @brief Close every TCP client (the listener stays). */
void sim_mb_server_drop(sim_mb_server *s);

/** @brief Close everything. */
void sim_mb_server_close(sim_mb_server *s);

/** @brief Print "msid-devsim: error: what[: detail]" and exit 1. */
void sim_die(const char *what, const char *detail);

/** @brief Sleep s seconds unless *stop is set (a signal cuts it short). */
void sim_sleep_s(volatile sig_atomic_t *stop, double s);

#endif
