/* The parameter set: CFG records out (host) and in (device, log replay). No OS, no heap. */
#include "msid_daq/msid_params.h"

#include <string.h>

void msid_params_reset(msid_params *c)
{
    c->open = 0;
    c->n_frames = 0;
    c->run_crc = 0;
    c->crc = 0;
    memset(c->got, 0, sizeof c->got);
}

/* Parameter class of a CFG id for the `got` counters. */
static int pclass(uint32_t p)
{
    switch (p) {
    case MSID_CAN_P_PERIOD: return 0;
    case MSID_CAN_P_LINES: return 1;
    case MSID_CAN_P_INPUTS: return 2;
    case MSID_CAN_P_EXPERIMENTS: return 3;
    case MSID_CAN_P_PATTERN: return 4;
    case MSID_CAN_P_PHASE_MODE: return 5;
    case MSID_CAN_P_SEED: return 6;
    case MSID_CAN_P_BIN: return 7;
    case MSID_CAN_P_AMP: return 8;
    case MSID_CAN_P_PHASE: return 9;
    case MSID_CAN_P_OMEGA: return 10;
    case MSID_CAN_P_SAMPLE_TIME: return 11;
    case MSID_CAN_P_ENCODING: return 12;
    case MSID_CAN_P_SCALE: return 13;
    case MSID_CAN_P_FD: return 14;
    case MSID_CAN_P_RATE: case MSID_CAN_P_PERIODS: return 15;
    default: return -1;
    }
}

static void put_frame(uint8_t (*out)[8], size_t cap, size_t *n, uint32_t p, uint32_t idx, uint32_t v)
{
    if (out && *n < cap) {
        uint8_t *d = out[*n];
        d[0] = (uint8_t)p; d[1] = (uint8_t)idx; d[2] = (uint8_t)(idx >> 8); d[3] = (uint8_t)(idx >> 16);
        msid_can_put_u32(d + 4, v);
    }
    ++*n;
}

static void put_double(uint8_t (*out)[8], size_t cap, size_t *n, uint32_t p, uint32_t idx, double x)
{
    uint64_t w;
    memcpy(&w, &x, 8);
    put_frame(out, cap, n, p, 2 * idx, (uint32_t)w);
    put_frame(out, cap, n, p, 2 * idx + 1, (uint32_t)(w >> 32));
}

size_t msid_params_frames(const msid_params *c, uint8_t (*out)[8], size_t cap)
{
    if (c->n_lines == 0 || c->n_lines > MSID_PARAMS_MAX_LINES || c->n_inputs == 0 || c->n_inputs > MSID_MAX_INPUTS)
        return 0;
    size_t n = 0;
    const uint32_t L = c->n_lines, nu = c->n_inputs;
    put_frame(out, cap, &n, MSID_CAN_P_BEGIN, MSID_CAN_PROTO_VERSION, 0);
    put_frame(out, cap, &n, MSID_CAN_P_PERIOD, 0, c->period);
    put_frame(out, cap, &n, MSID_CAN_P_LINES, 0, L);
    put_frame(out, cap, &n, MSID_CAN_P_INPUTS, 0, nu);
    put_frame(out, cap, &n, MSID_CAN_P_EXPERIMENTS, 0, c->n_experiments);
    put_frame(out, cap, &n, MSID_CAN_P_PATTERN, 0, c->pattern);
    put_frame(out, cap, &n, MSID_CAN_P_PHASE_MODE, 0, c->phase_mode);
    put_frame(out, cap, &n, MSID_CAN_P_SEED, 0, (uint32_t)c->seed);
    put_frame(out, cap, &n, MSID_CAN_P_SEED, 1, (uint32_t)(c->seed >> 32));
    if (c->is_ct) {
        for (uint32_t l = 0; l < L; ++l) put_double(out, cap, &n, MSID_CAN_P_OMEGA, l, c->omega[l]);
        put_double(out, cap, &n, MSID_CAN_P_SAMPLE_TIME, 0, c->sample_time);
    } else {
        for (uint32_t l = 0; l < L; ++l) put_frame(out, cap, &n, MSID_CAN_P_BIN, l, c->bins[l]);
    }
    if (c->have_amp)
        for (uint32_t k = 0; k < nu * L; ++k) put_double(out, cap, &n, MSID_CAN_P_AMP, k, c->amp[k]);
    if (c->have_phase)
        for (uint32_t k = 0; k < nu * L; ++k) put_double(out, cap, &n, MSID_CAN_P_PHASE, k, c->phase[k]);
    uint32_t sc;
    memcpy(&sc, &c->scale, 4);
    put_frame(out, cap, &n, MSID_CAN_P_ENCODING, 0, c->encoding);
    put_frame(out, cap, &n, MSID_CAN_P_SCALE, 0, sc);
    put_frame(out, cap, &n, MSID_CAN_P_FD, 0, c->fd);
    put_frame(out, cap, &n, MSID_CAN_P_RATE, 0, c->rate_hz);
    put_frame(out, cap, &n, MSID_CAN_P_PERIODS, 0, c->periods);
    if (out && n <= cap) {
        uint32_t crc = 0;
        for (size_t i = 0; i < n; ++i) crc = msid_can_crc32(crc, out[i], 8);
        put_frame(out, cap, &n, MSID_CAN_P_COMMIT, 0, crc);
    } else {
        ++n;
    }
    return n;
}

static void set_double_word(double *x, uint32_t w, uint32_t v)
{
    uint64_t b;
    memcpy(&b, x, 8);
    if (w) b = (b & 0xFFFFFFFFull) | (uint64_t)v << 32;
    else b = (b & 0xFFFFFFFF00000000ull) | v;
    memcpy(x, &b, 8);
}

/* Consistency of a complete configuration. */
static int config_complete(const msid_params *c)
{
    const uint32_t L = c->n_lines, nu = c->n_inputs;
    for (int k = 0; k <= 6; ++k)
        if (c->got[k] != (k == 6 ? 2u : 1u)) return 0;
    if (L == 0 || L > MSID_PARAMS_MAX_LINES || nu == 0 || nu > MSID_MAX_INPUTS) return 0;
    if (c->is_ct) { if (c->got[10] != 2 * L || c->got[11] != 2 || c->got[7] != 0) return 0; }
    else if (c->got[7] != L || c->got[10] != 0 || c->got[11] != 0) return 0;
    if (c->got[8] != 0 && c->got[8] != 2 * nu * L) return 0;
    if (c->got[9] != 0 && c->got[9] != 2 * nu * L) return 0;
    if (c->phase_mode == MSID_PHASE_USER && c->got[9] == 0) return 0;
    if (c->got[12] != 1 || c->got[13] != 1 || c->got[14] != 1 || c->got[15] != 2) return 0;
    if (c->encoding > 1 || c->fd > 1) return 0;
    /* every count that sizes memory or work on either end, against what a design allows */
    if (c->period < MSID_MIN_PERIOD || c->period > MSID_MAX_PERIOD || c->n_experiments == 0 ||
        c->n_experiments > MSID_MAX_EXPERIMENTS || c->periods < 2 || c->periods > MSID_PARAMS_MAX_PERIODS)
        return 0;
    if (c->encoding == MSID_CAN_ENC_S16 && !(c->scale > 0.0f && c->scale < 1e30f)) return 0;
    return 1;
}

int msid_params_feed(msid_params *c, const uint8_t *d, uint32_t len, uint32_t host_version)
{
    if (len != 8) return -MSID_CAN_ERR_CFG;
    const uint32_t p = d[0], idx = (uint32_t)d[1] | (uint32_t)d[2] << 8 | (uint32_t)d[3] << 16;
    const uint32_t v = msid_can_get_u32(d + 4);
    if (p == MSID_CAN_P_BEGIN) {
        msid_params_reset(c);
        if (idx != host_version) return -MSID_CAN_ERR_VERSION;
        c->open = 1;
        c->have_amp = c->have_phase = c->is_ct = 0;
        /* an upload that sends one index twice and another never (the counts still match) must not
         * inherit the previous upload's value there: every table starts at zero (found by
         * fuzz_can_config: a stale amplitude of 1e200 made a Schroeder phase NaN) */
        memset(c->bins, 0, sizeof c->bins);
        memset(c->amp, 0, sizeof c->amp);
        memset(c->phase, 0, sizeof c->phase);
        memset(c->omega, 0, sizeof c->omega);
        c->n_frames = 1;
        c->run_crc = msid_can_crc32(0, d, 8);
        return 0;
    }
    if (!c->open) return -MSID_CAN_ERR_CFG;
    if (p == MSID_CAN_P_COMMIT) {
        c->open = 0;
        if (v != c->run_crc) return -MSID_CAN_ERR_CRC;
        if (!config_complete(c)) return -MSID_CAN_ERR_CFG;
        c->crc = v;
        return 1;
    }
    const int k = pclass(p);
    if (k < 0) { c->open = 0; return -MSID_CAN_ERR_CFG; }
    c->run_crc = msid_can_crc32(c->run_crc, d, 8);
    c->n_frames++;
    c->got[k]++;
    const uint32_t L = c->n_lines, nu = c->n_inputs;
    switch (p) {
    case MSID_CAN_P_PERIOD: c->period = v; break;
    case MSID_CAN_P_LINES: c->n_lines = v; break;
    case MSID_CAN_P_INPUTS: c->n_inputs = v; break;
    case MSID_CAN_P_EXPERIMENTS: c->n_experiments = v; break;
    case MSID_CAN_P_PATTERN: c->pattern = v; break;
    case MSID_CAN_P_PHASE_MODE: c->phase_mode = v; break;
    case MSID_CAN_P_SEED:
        if (idx > 1) goto bad;
        c->seed = idx ? (c->seed & 0xFFFFFFFFull) | (uint64_t)v << 32 : (c->seed & ~0xFFFFFFFFull) | v;
        break;
    case MSID_CAN_P_BIN:
        if (idx >= L || L > MSID_PARAMS_MAX_LINES) goto bad;
        c->bins[idx] = v;
        break;
    case MSID_CAN_P_AMP:
    case MSID_CAN_P_PHASE:
        if (L > MSID_PARAMS_MAX_LINES || nu > MSID_MAX_INPUTS || idx >= 2 * nu * L) goto bad;
        set_double_word(p == MSID_CAN_P_AMP ? &c->amp[idx / 2] : &c->phase[idx / 2], idx & 1u, v);
        if (p == MSID_CAN_P_AMP) c->have_amp = 1; else c->have_phase = 1;
        break;
    case MSID_CAN_P_OMEGA:
        if (L > MSID_PARAMS_MAX_LINES || idx >= 2 * L) goto bad;
        set_double_word(&c->omega[idx / 2], idx & 1u, v);
        c->is_ct = 1;
        break;
    case MSID_CAN_P_SAMPLE_TIME:
        if (idx > 1) goto bad;
        set_double_word(&c->sample_time, idx, v);
        break;
    case MSID_CAN_P_ENCODING: c->encoding = v; break;
    case MSID_CAN_P_SCALE: memcpy(&c->scale, &v, 4); break;
    case MSID_CAN_P_FD: c->fd = v; break;
    case MSID_CAN_P_RATE: c->rate_hz = v; break;
    case MSID_CAN_P_PERIODS: c->periods = v; break;
    default: goto bad;
    }
    return 0;
bad:
    c->open = 0;
    return -MSID_CAN_ERR_CFG;
}

void msid_params_design_cfg(const msid_params *c, msid_design_cfg *dc, const msid_twiddle *tw)
{
    memset(dc, 0, sizeof *dc);
    dc->period = c->period;
    dc->n_lines = c->n_lines;
    dc->bins = c->is_ct ? NULL : c->bins;
    dc->omega = c->is_ct ? c->omega : NULL;
    dc->sample_time = c->is_ct ? c->sample_time : 0.0;
    dc->amplitudes = c->have_amp ? c->amp : NULL;
    dc->amp_per_input = c->have_amp && c->n_inputs > 1;
    dc->phase_mode = (msid_phase_mode)c->phase_mode;
    dc->phases = c->have_phase ? c->phase : NULL;
    dc->seed = c->seed;
    dc->n_inputs = c->n_inputs;
    dc->n_experiments = c->n_experiments;
    dc->pattern = (msid_pattern)c->pattern;
    dc->twiddle = tw;
    dc->crest = MSID_CREST_NONE;   /* a device never reports them: O(1), not O(m nu P L) */
}
