/* msid-devsim's device core: design from the uploaded parameters, excitation
 * from lib/, the simulated plant and the noise, one sample row at a time.
 * Shared by the CAN and Modbus front ends; all state in the sim_device. */
#define _GNU_SOURCE
#include "sim_device.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

void sim_device_init(sim_device *d, uint8_t *arena, size_t arena_size)
{
    memset(d, 0, sizeof *d);
    d->arena = arena;
    d->arena_size = arena_size;
    d->o.base = MSID_CAN_DEFAULT_BASE;
    d->o.version = MSID_CAN_PROTO_VERSION;
    d->o.seed = 1;
    d->o.sigma_y = 0.05;
    d->o.sigma_u = 0.002;
    d->o.busoff_exp = d->o.restart_exp = d->o.drop_exp = d->o.stall_exp = d->o.back_exp = -1;
    d->o.absurd_exp = d->o.replay_exp = d->o.lose_done_exp = -1;
    d->o.baud = 115200;
    d->o.unit = 1;
    d->o.emulate_baud = 1;
}

void *sim_take(sim_device *d, size_t n)
{
    n = (n + 63u) / 64u * 64u;
    if (n == 0 || n > d->arena_size - d->arena_used) return NULL;
    void *p = d->arena + d->arena_used;
    d->arena_used += n;
    return p;
}

double sim_now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

void sim_write_atomic(const char *path, void (*body)(FILE *, const void *), const void *ctx)
{
    if (!path) return;
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp.%d", path, (int)getpid());
    FILE *f = fopen(tmp, "w");
    if (!f) { fprintf(stderr, "msid-devsim: error: cannot write '%s': %s\n", path, strerror(errno)); exit(1); }
    body(f, ctx);
    if (fclose(f) != 0 || rename(tmp, path) != 0) {
        fprintf(stderr, "msid-devsim: error: cannot write '%s'\n", path);
        exit(1);
    }
}

static void truth_body(FILE *f, const void *ctx)
{
    const sim_device *d = ctx;
    const uint32_t L = d->des.n_lines, nu = d->pd.nu, ny = d->pd.ny;
    fprintf(f, "{\"format\": \"msid-devsim-truth/1\", \"period_samples\": %u, \"n_inputs\": %u, \"n_outputs\": %u,\n",
            d->des.period, nu, ny);
    fprintf(f, " \"plant\": \"%s\", \"sigma_y\": %.17g, \"sigma_u\": %.17g, \"color\": %.17g, \"config_crc\": %u,\n \"lines\": [",
            d->pd.ct ? "ct" : "dt", d->o.sigma_y, d->o.sigma_u, d->o.color, d->cfg.crc);
    for (uint32_t l = 0; l < L; ++l) {
        fprintf(f, "%s\n  {\"bin\": %u, \"G\": {\"re\": [", l ? "," : "", d->des.bins[l]);
        for (int part = 0; part < 2; ++part) {
            if (part) fprintf(f, "], \"im\": [");
            for (uint32_t i = 0; i < ny; ++i) {
                fprintf(f, "%s[", i ? ", " : "");
                for (uint32_t j = 0; j < nu; ++j) {
                    const msid_cplx g = d->gl[(size_t)l * ny * nu + i * nu + j];
                    fprintf(f, "%s%.17g", j ? ", " : "", part ? g.im : g.re);
                }
                fprintf(f, "]");
            }
        }
        fprintf(f, "]}}");
    }
    fprintf(f, "\n ]}\n");
}

/* ---- configuration ------------------------------------------------------ */
uint32_t sim_configure(sim_device *d, uint32_t *mstatus)
{
    const sim_plant_def *pd = &d->pd;
    d->configured = 0;
    d->arena_used = d->arena_mark = 0;
    d->gen_mem = NULL;
    d->gen_len = 0;
    *mstatus = 0;
    if (d->cfg.n_inputs != pd->nu) return MSID_CAN_ERR_DIMS;
    const uint32_t P = d->cfg.period;
    if (P < MSID_MIN_PERIOD || P > MSID_MAX_PERIOD) { *mstatus = MSID_E_PERIOD; return MSID_CAN_ERR_DESIGN; }
    size_t n = msid_twiddle_mem_size(P);
    void *m = sim_take(d, n);
    if (!m) { *mstatus = MSID_E_MEM_SIZE; return MSID_CAN_ERR_DESIGN; }
    msid_status st = msid_twiddle_init(&d->tw, P, m, n);
    if (st) { *mstatus = st; return MSID_CAN_ERR_DESIGN; }
    msid_design_cfg dc;
    msid_params_design_cfg(&d->cfg, &dc, &d->tw);
    n = msid_design_mem_size(&dc);
    m = n ? sim_take(d, n) : NULL;
    if (!m) { *mstatus = n ? MSID_E_MEM_SIZE : MSID_E_DIMS; return MSID_CAN_ERR_DESIGN; }
    st = msid_design_init(&d->des, &dc, m, n);
    if (st) { *mstatus = st; return MSID_CAN_ERR_DESIGN; }
    const msid_design *des = &d->des;
    const uint32_t L = des->n_lines, nu = pd->nu, ny = pd->ny;
    d->gl = sim_take(d, sizeof(msid_cplx) * L * nu * ny);
    d->ph = sim_take(d, sizeof(msid_cplx) * L * ny);
    if (!d->gl || !d->ph) { *mstatus = MSID_E_MEM_SIZE; return MSID_CAN_ERR_DESIGN; }
    if (pd->ct && !des->is_ct && !(pd->h > 0)) { *mstatus = MSID_E_SAMPLE_TIME; return MSID_CAN_ERR_DESIGN; }
    for (uint32_t l = 0; l < L; ++l) {
        /* CT plant: rad/s; DT plant: rad/sample (a folded CT line keeps its unfolded frequency) */
        double w;
        if (pd->ct) w = des->is_ct ? des->omega[l] : 2 * M_PI * des->bins[l] / ((double)P * pd->h);
        else w = des->is_ct ? des->omega[l] * des->sample_time : 2 * M_PI * des->bins[l] / (double)P;
        if (sim_plant_response(pd, w, d->gl + (size_t)l * nu * ny) != 0) { *mstatus = MSID_E_SINGULAR; return MSID_CAN_ERR_DESIGN; }
    }
    if (!pd->ct) {
        msid_plant_cfg pc = {pd->n, nu, ny, pd->A, pd->B, pd->C, pd->D};
        n = msid_plant_mem_size(&pc);
        m = sim_take(d, n);
        if (!m || msid_plant_init(&d->pl, &pc, m, n) != MSID_OK) { *mstatus = MSID_E_DIMS; return MSID_CAN_ERR_DESIGN; }
    }
    /* the generator's memory: the largest over the experiments */
    for (uint32_t e = 0; e < des->n_experiments; ++e) {
        msid_gen_cfg gc = {des, &d->tw, e, 0};
        n = msid_gen_mem_size(&gc);
        if (n > d->gen_len) d->gen_len = n;
    }
    d->gen_mem = d->gen_len ? sim_take(d, d->gen_len) : NULL;
    if (!d->gen_mem) { *mstatus = MSID_E_MEM_SIZE; return MSID_CAN_ERR_DESIGN; }
    d->arena_mark = d->arena_used;
    d->configured = 1;
    sim_write_atomic(d->o.truth, truth_body, d);
    return MSID_CAN_ERR_NONE;
}

int sim_start(sim_device *d, uint32_t e, uint32_t periods)
{
    if (!d->configured) return MSID_CAN_ERR_NOT_CONFIGURED;
    const msid_design *des = &d->des;
    if (e >= des->n_experiments) return MSID_CAN_ERR_EXPERIMENT;
    msid_gen_cfg gc = {des, &d->tw, e, 0};
    if (msid_gen_init(&d->gen, &gc, d->gen_mem, d->gen_len) != MSID_OK) return MSID_CAN_ERR_DESIGN;
    const uint32_t L = des->n_lines, nu = d->pd.nu, ny = d->pd.ny;
    if (d->pd.ct) {
        /* output phasor per line: G'(l) c_l, G' conjugated where the line folded */
        for (uint32_t l = 0; l < L; ++l)
            for (uint32_t i = 0; i < ny; ++i) {
                double re = 0, im = 0;
                for (uint32_t j = 0; j < nu; ++j) {
                    msid_cplx g = d->gl[(size_t)l * nu * ny + i * nu + j];
                    if (des->is_ct && des->folded[l]) g.im = -g.im;
                    const msid_cplx c = msid_design_coef(des, e, j, l);
                    re += g.re * c.re - g.im * c.im;
                    im += g.re * c.im + g.im * c.re;
                }
                d->ph[(size_t)l * ny + i].re = re;
                d->ph[(size_t)l * ny + i].im = im;
            }
    }
    msid_rng_seed(&d->rng, d->o.seed * 0x9E3779B97F4A7C15ull + e + 1);
    memset(d->ar_state, 0, sizeof d->ar_state);
    d->n_sample = 0;
    d->n_total = (uint64_t)(periods ? periods : d->cfg.periods) * des->period;
    clock_gettime(CLOCK_MONOTONIC, &d->t_start);
    return 0;
}

/* The device restarts (watchdog): it keeps its configuration (retained RAM) and the
   experiment starts again from sample 0; the plant keeps its state. */
void sim_restart_segment(sim_device *d)
{
    msid_gen_seek(&d->gen, 0);
    d->n_sample = 0;
}

/* The row [u; y] of sample n_sample: excitation from lib/, plant, noise. */
void sim_row(sim_device *d, double *row)
{
    const uint32_t nu = d->pd.nu, ny = d->pd.ny, P = d->des.period;
    double u[MSID_MAX_INPUTS];
    msid_gen_next(&d->gen, u);
    if (d->pd.ct) {
        const uint32_t L = d->des.n_lines;
        for (uint32_t i = 0; i < ny; ++i) row[nu + i] = 0;
        for (uint32_t l = 0; l < L; ++l) {
            const msid_cplx w = d->tw.w[(uint64_t)d->des.bins[l] * (d->n_sample % P) % P];   /* e^{-j 2 pi b n / P} */
            for (uint32_t i = 0; i < ny; ++i) {
                const msid_cplx c = d->ph[(size_t)l * ny + i];
                row[nu + i] += c.re * w.re + c.im * w.im;   /* Re{c e^{+j 2 pi b n / P}} */
            }
        }
    } else {
        msid_plant_step(&d->pl, u, row + nu);
    }
    for (uint32_t i = 0; i < ny; ++i) {
        d->ar_state[i] = d->o.color * d->ar_state[i] + d->o.sigma_y * msid_rng_normal(&d->rng);
        row[nu + i] += d->ar_state[i];
    }
    for (uint32_t j = 0; j < nu; ++j)
        row[j] = u[j] + (d->o.sigma_u > 0 ? d->o.sigma_u * msid_rng_normal(&d->rng) : 0.0);
}
