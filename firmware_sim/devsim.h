/* msid-devsim: a CAN device simulator written as firmware would be.
 * Fixed memory only (static arenas, no malloc), links lib/ for the design,
 * the generator and the plant, and daq/'s protocol codec and SocketCAN
 * transport as its "CAN peripheral". See docs/can-protocol.md. */
#ifndef MSID_DEVSIM_H
#define MSID_DEVSIM_H

#include <stdint.h>
#include "msid/msid.h"
#include "msid_daq/msid_can_proto.h"
#include "msid_daq/msid_socketcan.h"

#define SIM_MAX_STATES 16u

/* The simulated plant: discrete-time state space stepped sample by sample,
 * or a continuous-time system whose exact steady-state response to the
 * multisine is evaluated at t = n h (valid for any h, also below Nyquist). */
typedef struct sim_plant_def {
    int ct;                          /* 0: x(n+1) = A x + B u; 1: dx/dt = A x + B u */
    uint32_t n, nu, ny;
    double A[SIM_MAX_STATES * SIM_MAX_STATES], B[SIM_MAX_STATES * MSID_MAX_INPUTS];
    double C[MSID_MAX_OUTPUTS * SIM_MAX_STATES], D[MSID_MAX_OUTPUTS * MSID_MAX_INPUTS];
    double h;                        /* CT plant with a DT design: sample time (s) */
} sim_plant_def;

/* Fault injection and device options (command line). */
typedef struct sim_opts {
    const char *iface;
    uint32_t base;
    uint32_t version;                /* protocol version the device speaks */
    uint64_t seed;
    double sigma_y, sigma_u, color;  /* output noise std, input noise std, AR(1) pole of the output noise */
    uint64_t drop_every, dup_every, reorder_every, malformed_every, error_every;
    double drop_frac;
    int busoff_exp; uint64_t busoff_at, busoff_len;      /* -1: none */
    int restart_exp; uint64_t restart_at;                /* -1: none */
    const char *truth, *report;
    double idle_exit;                /* seconds without host frames before exiting (0: never) */
    int rcvbuf;
} sim_opts;

/* Counters of what the simulator did (written to the report). */
typedef struct sim_counts {
    uint64_t frames_sent, sample_frames, samples;
    uint64_t dropped, duplicated, reordered, malformed, error_frames, bus_off, restarts, tx_busy;
    uint64_t busoff_samples;         /* samples not sent while bus-off */
    uint32_t experiments_done;
} sim_counts;

int sim_parse_plant(const char *path, sim_plant_def *p, char *err, size_t errlen);
void sim_builtin_plant(sim_plant_def *p);
/* G at line frequency: DT z = e^{j w}, w in rad/sample; CT s = j w, w in rad/s. G is ny x nu. */
int sim_plant_response(const sim_plant_def *p, double w, msid_cplx *G);

#endif
