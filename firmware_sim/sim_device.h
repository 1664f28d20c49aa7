/**
 * @file sim_device.h
 * @brief msid-devsim's shared device core, written as firmware would be: the
 *        uploaded parameter set, the design and generator rebuilt from it with
 *        lib/, the simulated plant and the noise, and the production of sample
 *        rows. All state lives in one ::sim_device; fixed memory only (an
 *        arena the caller owns, no malloc). The CAN (sim_can.c) and Modbus
 *        (sim_modbus.c) front ends call into it; it calls neither.
 */
#ifndef MSID_SIM_DEVICE_H
#define MSID_SIM_DEVICE_H

#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <time.h>
#include "msid/msid.h"
#include "msid_daq/msid_params.h"
#include "sim_plant.h"

/** Fault injection and device options (command line). */
typedef struct sim_opts {
    const char *iface;
    uint32_t base;
    uint32_t version;                /**< protocol version the device speaks */
    uint64_t seed;
    double sigma_y, sigma_u, color;  /**< output noise std, input noise std, AR(1) pole of the output noise */
    uint64_t drop_every, dup_every, reorder_every, malformed_every, error_every;
    double drop_frac;
    int busoff_exp; uint64_t busoff_at, busoff_len;      /**< -1: none */
    int restart_exp; uint64_t restart_at;                /**< -1: none */
    const char *truth, *report;
    double idle_exit;                /**< seconds without host frames before exiting (0: never) */
    int rcvbuf;
    /* Modbus front end (sim_modbus.c) */
    const char *mb_tcp, *mb_rtu;     /**< "HOST:PORT", or a serial device */
    uint32_t baud, unit, ring;       /**< RTU baud, unit id, ring capacity cap in samples (0: the whole map) */
    int emulate_baud;                /**< RTU: reply after the frames' wire time at `baud` */
    uint64_t delay_every, delay_ms;  /**< every K-th request answered MS ms late */
    uint64_t exc_every, exc_code;    /**< every K-th request answered with an exception */
    uint64_t corrupt_every;          /**< RTU: every K-th reply with a bad CRC */
    int drop_exp; uint64_t drop_at;  /**< drop the connection at sample N of experiment E (-1: none) */
    int stall_exp; uint64_t stall_at, stall_samples, stall_ms;   /**< stall: no replies, D samples regardless */
    /* adversarial device (tests of the host's range checks) */
    int never_done;                  /**< Modbus: keep writing past K P samples and never report DONE */
    int answer_twice;                /**< Modbus: send every reply twice */
    int back_exp; uint64_t back_at;  /**< Modbus: from sample N of experiment E report a write index 16 samples back */
    int bad_result;                  /**< Modbus: publish a NaN in the on-device result block (line 1, G[0][0]) */
    uint64_t garbage_tid_every;      /**< Modbus TCP: every K-th reply carries a transaction id the host never sent */
    uint64_t drip_every, drip_ms;    /**< Modbus: every K-th read reply sent one byte at a time, MS ms apart */
    uint64_t truncate_every;         /**< Modbus: every K-th read reply cut to half its bytes (the rest never comes) */
    uint64_t oversize_every;         /**< Modbus: every K-th read reply 16 bytes longer than asked (byte count and all) */
    int absurd_exp; uint64_t absurd_at;   /**< Modbus: from sample N of experiment E the header's TOTAL is 0xFFFFFFF0 */
    int done_twice;                  /**< CAN: send every DONE frame twice */
    int replay_exp; uint64_t replay_at;   /**< CAN: at sample N of experiment E send the last DONE frame again */
    int lose_done_exp;               /**< CAN: the DONE frame of experiment E is not sent (lost); QUERY recovers it (-1: none) */
    /* a described device (--map, sim_mbmap.c) */
    int no_fc23;                     /**< refuse function 23 (illegal function) */
    uint64_t drop_after;             /**< close the connection instead of answering request N + 1 (0: never) */
    uint64_t die_after;              /**< exit at once instead of answering request N + 1 (0: never) */
    /* on-device estimation (sim_estimate.c) */
    uint64_t est_mem;                /**< bytes the device gives the estimator (0: the default) */
} sim_opts;

/** The device: options, plant, uploaded configuration, design and run state. */
typedef struct sim_device {
    sim_opts o;
    sim_plant_def pd;
    msid_params cfg;             /**< the uploaded configuration (msid-can/1 parameter records) */
    volatile sig_atomic_t *stop;     /**< set by the signal handler (main.c) */
    /* fixed memory */
    uint8_t *arena;
    size_t arena_size, arena_used, arena_mark;   /**< mark: end of the design's memory */
    /* design state (rebuilt at every commit) */
    int configured;
    msid_twiddle tw;
    msid_design des;
    msid_gen gen;
    void *gen_mem;
    size_t gen_len;
    msid_plant pl;
    msid_cplx *gl;                   /**< [L * ny*nu] true response at each line (what the truth file holds) */
    msid_cplx *ph;                   /**< [L * ny] output phasors of the running experiment (CT plant) */
    double ar_state[MSID_MAX_OUTPUTS];
    msid_rng rng;
    /* run state */
    uint64_t n_sample, n_total;      /**< sample index in the segment, samples per segment */
    struct timespec t_start;
} sim_device;

/** @brief Reset a device over a caller-owned arena (64-byte aligned); options default. */
void sim_device_init(sim_device *d, uint8_t *arena, size_t arena_size);
/** @brief n bytes (rounded to 64) from the arena, or NULL when it is exhausted. */
void *sim_take(sim_device *d, size_t n);
/** @brief Seconds on the monotonic clock. */
double sim_now_s(void);
/** @brief Write path atomically (temporary file, rename) with body(f, ctx); no-op for NULL path. */
void sim_write_atomic(const char *path, void (*body)(FILE *, const void *), const void *ctx);
/** @brief Rebuild the design from d->cfg (writes --truth); 0 or an MSID_CAN_ERR_* code, *mstatus the msid_status. */
uint32_t sim_configure(sim_device *d, uint32_t *mstatus);
/** @brief Start experiment e (K periods, 0: configured) at sample 0; 0 or an MSID_CAN_ERR_* code. */
int sim_start(sim_device *d, uint32_t e, uint32_t periods);
/** @brief The row [u; y] (nu + ny doubles) of sample d->n_sample (the caller advances n_sample). */
void sim_row(sim_device *d, double *row);
/** @brief Device restart: the segment starts again at sample 0. */
void sim_restart_segment(sim_device *d);

#endif
