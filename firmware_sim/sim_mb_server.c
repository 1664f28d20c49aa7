/* msid-devsim's Modbus server plumbing (sim_mb_server.h): listener, clients, one poll round. */
#define _GNU_SOURCE
#include "sim_mb_server.h"

#include <arpa/inet.h>
#include <errno.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

void sim_die(const char *what, const char *detail)
{
    fprintf(stderr, "msid-devsim: error: %s%s%s\n", what, detail ? ": " : "", detail ? detail : "");
    exit(1);
}

void sim_sleep_s(volatile sig_atomic_t *stop, double s)
{
    if (s <= 0) return;
    struct timespec t = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    while (nanosleep(&t, &t) != 0 && errno == EINTR && !*stop) {}
}

void sim_mb_server_open(sim_mb_server *s, const sim_opts *o, uint32_t unit)
{
    memset(s, 0, sizeof *s);
    s->listen_fd = -1;
    if (o->mb_rtu) {
        s->rtu = 1;
        s->mb = modbus_new_rtu(o->mb_rtu, (int)o->baud, 'N', 8, 1);
        if (!s->mb) sim_die("libmodbus", modbus_strerror(errno));
        if (unit < 1 || unit > 247) sim_die("--unit must be 1..247", NULL);
        modbus_set_slave(s->mb, (int)unit);
        if (modbus_connect(s->mb) != 0) sim_die(o->mb_rtu, modbus_strerror(errno));
        return;
    }
    snprintf(s->host, sizeof s->host, "%s", o->mb_tcp);
    char *colon = strrchr(s->host, ':');
    if (!colon) sim_die("--modbus-tcp wants HOST:PORT", o->mb_tcp);
    *colon = 0;
    s->mb = modbus_new_tcp(s->host, atoi(colon + 1));
    if (!s->mb) sim_die("libmodbus", modbus_strerror(errno));
    s->listen_fd = modbus_tcp_listen(s->mb, SIM_MB_MAX_CLIENTS);
    if (s->listen_fd < 0) sim_die(o->mb_tcp, modbus_strerror(errno));
    struct sockaddr_in sa;
    socklen_t sl = sizeof sa;
    getsockname(s->listen_fd, (struct sockaddr *)&sa, &sl);
    s->port = ntohs(sa.sin_port);
}

void sim_mb_server_poll(sim_mb_server *s, int timeout_ms, void (*serve)(void *ctx, const uint8_t *q, int len), void *ctx)
{
    struct pollfd pf[SIM_MB_MAX_CLIENTS + 1];
    int np = 0;
    if (s->rtu) pf[np++] = (struct pollfd){modbus_get_socket(s->mb), POLLIN, 0};
    else {
        pf[np++] = (struct pollfd){s->listen_fd, POLLIN, 0};
        for (int i = 0; i < s->n_clients; ++i) pf[np++] = (struct pollfd){s->clients[i], POLLIN, 0};
    }
    if (poll(pf, (nfds_t)np, timeout_ms) < 0) return;
    uint8_t q[MODBUS_MAX_ADU_LENGTH];
    for (int i = 0; i < np; ++i) {
        if (!(pf[i].revents & (POLLIN | POLLHUP | POLLERR))) continue;
        if (!s->rtu && pf[i].fd == s->listen_fd) {
            const int c = accept(s->listen_fd, NULL, NULL);
            if (c < 0) continue;
            /* replies go out at once, as a device's do: Nagle's algorithm would hold a reply until the host
               acknowledged the last one */
            const int one = 1;
            setsockopt(c, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
            if (s->n_clients == SIM_MB_MAX_CLIENTS) {
                close(s->clients[0]);
                memmove(s->clients, s->clients + 1, sizeof(int) * (size_t)--s->n_clients);
            }
            s->clients[s->n_clients++] = c;
            continue;
        }
        modbus_set_socket(s->mb, pf[i].fd);
        const int n = modbus_receive(s->mb, q);
        if (n > 0) serve(ctx, q, n);
        else if (n < 0 && s->rtu) modbus_flush(s->mb);
        else if (n < 0) {
            close(pf[i].fd);
            for (int j = 0; j < s->n_clients; ++j)
                if (s->clients[j] == pf[i].fd) {
                    s->clients[j] = s->clients[--s->n_clients];
                    break;
                }
        }
    }
}

void sim_mb_server_drop(sim_mb_server *s)
{
    for (int i = 0; i < s->n_clients; ++i) close(s->clients[i]);
    s->n_clients = 0;
}

void sim_mb_server_close(sim_mb_server *s)
{
    sim_mb_server_drop(s);
    if (s->listen_fd >= 0) close(s->listen_fd);
    s->listen_fd = -1;
    if (s->mb) {
        if (s->rtu) modbus_close(s->mb);
        modbus_free(s->mb);
    }
    s->mb = NULL;
}
