/* msid-devsim: a CAN device simulator written as firmware would be.
 * Fixed memory only (static arenas, no malloc), links lib/ for the design,
 * the generator and the plant, and daq/'s protocol codec and SocketCAN
 * transport as its "CAN peripheral". See docs/can-protocol.md. */
#ifndef MSID_DEVSIM_H
#define MSID_DEVSIM_H

#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <time.h>
#include "msid/msid.h"
#include "msid_daq/msid_params.h"
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
    /* Modbus front end (devsim_mb.c) */
    const char *mb_tcp, *mb_rtu;     /* "HOST:PORT", or a serial device */
    uint32_t baud, unit, ring;       /* RTU baud, unit id, ring capacity cap in samples (0: the whole map) */
    int emulate_baud;                /* RTU: reply after the frames' wire time at `baud` */
    uint64_t delay_every, delay_ms;  /* every K-th request answered MS ms late */
    uint64_t exc_every, exc_code;    /* every K-th request answered with an exception */
    uint64_t corrupt_every;          /* RTU: every K-th reply with a bad CRC */
    int drop_exp; uint64_t drop_at;  /* drop the connection at sample N of experiment E (-1: none) */
    int stall_exp; uint64_t stall_at, stall_samples, stall_ms;   /* stall: no replies, D samples regardless */
    /* adversarial device (tests of the host's range checks) */
    int never_done;                  /* Modbus: keep writing past K P samples and never report DONE */
    int answer_twice;                /* Modbus: send every reply twice */
    int back_exp; uint64_t back_at;  /* Modbus: from sample N of experiment E report a write index 16 samples back */
} sim_opts;

/* Counters of what the simulator did (written to the report). */
typedef struct sim_counts {
    uint64_t frames_sent, sample_frames, samples;
    uint64_t dropped, duplicated, reordered, malformed, error_frames, bus_off, restarts, tx_busy;
    uint64_t busoff_samples;         /* samples not sent while bus-off */
    uint64_t paced_waits, late_samples;  /* --rate: samples that waited for their deadline / found it passed */
    uint64_t early_samples;              /* --rate: samples sent before their deadline (never, if paced) */
    uint32_t experiments_done;
} sim_counts;

/* Shared by the CAN (devsim.c) and Modbus (devsim_mb.c) front ends. */
extern sim_opts O;
extern sim_plant_def PD;
extern msid_params CFG;           /* the uploaded configuration (msid-can/1 parameter records) */
extern msid_design DES;
extern int configured;
extern uint64_t n_sample, n_total;    /* sample index in the segment, samples per segment */
extern struct timespec t_start;
extern volatile sig_atomic_t stop_flag;
double now_s(void);
void sim_write_atomic(const char *path, void (*body)(FILE *));
/* Rebuild the design from CFG (writes --truth); 0 or an MSID_CAN_ERR_* code, *mstatus the msid_status. */
uint32_t sim_configure(uint32_t *mstatus);
/* Start experiment e (K periods, 0: configured) at sample 0; 0 or an MSID_CAN_ERR_* code. */
int sim_start(uint32_t e, uint32_t periods);
/* The row [u; y] of sample n_sample (the caller advances n_sample). */
void sim_row(double *row);
/* Device restart: the segment starts again at sample 0. */
void sim_restart_segment(void);
/* The Modbus front end: serve msid-modbus/1 over TCP or RTU until SIGTERM. */
int sim_modbus_main(void);

int sim_parse_plant(const char *path, sim_plant_def *p, char *err, size_t errlen);
void sim_builtin_plant(sim_plant_def *p);
/* G at line frequency: DT z = e^{j w}, w in rad/sample; CT s = j w, w in rad/s. G is ny x nu. */
int sim_plant_response(const sim_plant_def *p, double w, msid_cplx *G);

#endif
