/* Instruction counts per sample on the target, for `msid bench target`.
 *
 * Runs under qemu-system-arm with -icount shift=0: every guest instruction
 * advances the virtual clock by exactly 1 ns, and the SysTick counter runs
 * at 25 MHz of that clock, so one tick is 40 instructions. Each case times
 * SAMPLES samples of the firmware's per-sample work (the sampling interrupt
 * body) and prints the mean instructions per sample; the per-sample maximum
 * (period ends included) is read with the 40-instruction resolution.
 *
 * Per sample (block=1, the sampling interrupt) or per block of 16 samples
 * (block=16, a DMA half-buffer; the cost printed is still per sample): msid_gen_next (waveform-table mode, O(1), or on-the-fly mode,
 * O(L)) writes u; y is copied from u (stands for the ADC read); msid_meas_push
 * of that one row runs the streaming line DFT and, at each period end, the
 * period statistics (Welford update, Pintelon 2002 eqs. 12-13); with spread=1
 * (msid_meas_cfg.spread) that period-end work is done one line per sample
 * during the next period instead, and max_insn shows the bounded maximum.
 * The msid_*_mem_size() of every object of each configuration is printed too.
 * Output: one "case ..." line per case, key=value fields, parsed by msid bench target. */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "board.h"
#include "msid/msid.h"

#define P 256u
#define SAMPLES (8u * P)
#define ARENA (512u * 1024u)
static unsigned char arena[ARENA] __attribute__((aligned(64)));
static size_t used;
static void *take(size_t n)
{
    n = (n + 63u) & ~(size_t)63u;
    if (n > ARENA - used) { printf("error: arena too small\n"); return NULL; }
    void *p = arena + used;
    used += n;
    return p;
}

static uint32_t insn(uint64_t ticks) { return (uint32_t)(ticks * (1000000000u / BOARD_TICK_HZ)); }

typedef struct { uint32_t nu, ny, L, m; int table; const char *name; uint32_t block; int f32; int spread; int f32in; } bcase;

static int run(const bcase *c, int what)   /* what: 0 gen+push, 1 gen only, 2 push only */
{
    used = 0;
    uint32_t bins[64];
    for (uint32_t l = 0; l < c->L; ++l) bins[l] = 1u + 2u * l;
    msid_twiddle tw;
    const size_t ntw = msid_twiddle_mem_size(P);
    if (msid_twiddle_init(&tw, P, take(ntw), ntw) != MSID_OK) return 1;
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = P; dc.n_lines = c->L; dc.bins = bins; dc.n_inputs = c->nu; dc.n_experiments = c->m;
    dc.twiddle = &tw;
    msid_design d;
    const size_t nd = msid_design_mem_size(&dc);
    if (msid_design_init(&d, &dc, take(nd), nd) != MSID_OK) return 1;
    msid_gen_cfg gc = {&d, &tw, 0u, c->table};
    msid_gen g;
    const size_t ng = msid_gen_mem_size(&gc);
    if (msid_gen_init(&g, &gc, take(ng), ng) != MSID_OK) return 1;
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = c->nu; mc.n_outputs = c->ny; mc.n_experiments = c->m;
    mc.n_lines = c->L; mc.bins = bins; mc.twiddle = &tw; mc.path = c->f32 ? MSID_DFT_STREAM_F32 : MSID_DFT_STREAM;
    mc.spread = c->spread;
    msid_meas ms;
    const size_t nm = msid_meas_mem_size(&mc);
    if (msid_meas_init(&ms, &mc, take(nm), nm) != MSID_OK) return 1;
    msid_frf_cfg fc = {P, c->nu, c->ny, c->m, c->L, 0u, NULL};
    const size_t nf = msid_frf_mem_size(&fc);
    msid_meas_begin(&ms, 0u);

    const uint32_t C = c->nu + c->ny, B = c->block ? c->block : 1u;
    static double rows[16 * 8];
    static float rowsf[16 * 8];   /* f32in: float samples, as an ADC driver would store them */
    double *row = rows;
    uint64_t worst = 0;
    board_ticks_start();
    const uint64_t t0 = board_ticks();
    if (!c->f32in) {
        for (uint32_t s = 0; s < SAMPLES; s += B) {
            /* B samples per call: as a DMA half-buffer would deliver them */
            for (uint32_t k = 0; k < B; ++k) {
                double *r = rows + k * C;
                if (what != 2) msid_gen_next(&g, r);
                for (uint32_t i = 0; i < c->ny; ++i) r[c->nu + i] = r[i % c->nu];   /* "ADC" */
            }
            if (what != 1) msid_meas_push(&ms, rows, B);
        }
    } else {   /* float samples, as an ADC driver would store them */
        for (uint32_t s = 0; s < SAMPLES; s += B) {
            for (uint32_t k = 0; k < B; ++k) {
                float *rf = rowsf + k * C;
                if (what != 2) {
                    msid_gen_next(&g, rows);
                    rf[0] = (float)rows[0];   /* the excitation, once (a DAC takes an integer anyway) */
                }
                for (uint32_t i = 0; i < c->ny; ++i) rf[c->nu + i] = rf[i % c->nu];   /* "ADC" */
            }
            if (what != 1) msid_meas_push_f32(&ms, rowsf, B);
        }
    }
    const uint64_t total = board_ticks() - t0;
    /* per-sample maximum (period ends included), 40-instruction resolution */
    for (uint32_t s = 0; s < 2u * P; ++s) {
        const uint64_t a = board_ticks();
        if (what != 2) msid_gen_next(&g, row);
        if (c->f32in) {
            if (what != 2) rowsf[0] = (float)row[0];
            for (uint32_t i = 0; i < c->ny; ++i) rowsf[c->nu + i] = rowsf[i % c->nu];
            if (what != 1) msid_meas_push_f32(&ms, rowsf, 1u);
        } else {
            for (uint32_t i = 0; i < c->ny; ++i) row[c->nu + i] = row[i % c->nu];
            if (what != 1) msid_meas_push(&ms, row, 1u);
        }
        const uint64_t b = board_ticks() - a;
        if (b > worst) worst = b;
    }
    const double mean = (double)insn(total) / SAMPLES;
    static const char *const what_s[3] = {"gen+push", "gen", "push"};
    printf("case name=%s spread=%d block=%u work=%s nu=%u ny=%u m=%u lines=%u channels=%u gen=%s insn_per_sample=%.1f max_insn=%u "
           "mem_twiddle=%u mem_design=%u mem_gen=%u mem_meas=%u mem_frf=%u struct_bytes=%u\n",
           c->name, c->spread, (unsigned)B, what_s[what], (unsigned)c->nu, (unsigned)c->ny, (unsigned)c->m, (unsigned)c->L, (unsigned)C,
           c->table ? "table" : "onthefly", mean, (unsigned)insn(worst), (unsigned)ntw, (unsigned)nd, (unsigned)ng,
           (unsigned)nm, (unsigned)nf,
           (unsigned)(sizeof(msid_twiddle) + sizeof(msid_design) + sizeof(msid_gen) + sizeof(msid_meas) +
                      sizeof(msid_frf)));
    return 0;
}

int main(void)
{
    static const bcase cases[] = {
        {1, 1, 1, 1, 1, "siso1"},  {1, 1, 2, 1, 1, "siso2"},     {1, 1, 50, 1, 1, "siso50"},
        {2, 2, 50, 2, 1, "mimo2x2_50"}, {1, 1, 1, 1, 0, "siso1_otf"}, {1, 1, 50, 1, 0, "siso50_otf"},
        {1, 1, 1, 1, 1, "siso1", 16}, {1, 1, 50, 1, 1, "siso50", 16}, {2, 2, 50, 2, 1, "mimo2x2_50", 16},
        {1, 1, 1, 1, 1, "siso1_f32", 1, 1}, {1, 1, 50, 1, 1, "siso50_f32", 1, 1},
        {1, 1, 1, 1, 1, "siso1_f32", 16, 1}, {1, 1, 50, 1, 1, "siso50_f32", 16, 1},
        {2, 2, 50, 2, 1, "mimo2x2_50_f32", 16, 1},
        /* period end spread over the next period (msid_meas_cfg.spread): bounded per-sample maximum */
        {1, 1, 1, 1, 1, "siso1", 1, 0, 1}, {1, 1, 50, 1, 1, "siso50", 1, 0, 1}, {2, 2, 50, 2, 1, "mimo2x2_50", 1, 0, 1},
        {1, 1, 50, 1, 1, "siso50", 16, 0, 1}, {1, 1, 50, 1, 1, "siso50_f32", 1, 1, 1},
        /* float samples in (msid_meas_push_f32), float path: no double-to-float conversion per sample */
        {1, 1, 1, 1, 1, "siso1_f32in", 1, 1, 0, 1}, {1, 1, 50, 1, 1, "siso50_f32in", 1, 1, 0, 1},
        {1, 1, 1, 1, 1, "siso1_f32in", 16, 1, 0, 1}, {1, 1, 50, 1, 1, "siso50_f32in", 16, 1, 0, 1},
    };
    printf("# msid bench target: %s, P=%u, %u samples per case\n",
#if defined(__ARM_FP) && (__ARM_FP & 8)
           "Cortex-M7 FPv5-D16",
#else
           "Cortex-M4F FPv4-SP (double in software)",
#endif
           P, SAMPLES);
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; ++k)
        for (int w = 0; w < 3; ++w)
            if (run(&cases[k], w)) { printf("error: case %s failed to initialise\n", cases[k].name); return 1; }
    return 0;
}
