/* Instruction counts per sample on Linux targets (scripts/insn_count.sh, docs/target.md "Linux bench
 * controller"): the firmware's per-sample work of tests/target/bench_target.c (msid_gen_next of one row,
 * y copied from u as the "ADC", msid_meas_push of the row or of blocks of 16) for N samples, nothing
 * else. Run under qemu-user with one instruction per translation block and every block's execution
 * logged, the count of two runs with N1 and N2 samples differs by the instructions of N2 - N1 samples,
 * period ends included (N1, N2 multiples of the period): start-up and set-up cancel.
 *   usage: msid_insn_probe CASE SAMPLES    (CASE: siso1 | siso50 | mimo2x2_50, optionally with _b16) */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "msid/msid.h"

#define P 256u

static unsigned char arena[1u << 20] __attribute__((aligned(64)));
static size_t used;
static void *take(size_t n)
{
    n = (n + 63u) & ~(size_t)63u;
    if (n > sizeof arena - used) { fprintf(stderr, "insn_linux: arena too small\n"); exit(1); }
    void *p = arena + used;
    used += n;
    return p;
}

int main(int argc, char **argv)
{
    if (argc != 3) { fprintf(stderr, "usage: %s siso1|siso50|mimo2x2_50[_b16] SAMPLES\n", argv[0]); return 2; }
    uint32_t nu = 1, ny = 1, L = 1, m = 1, B = strstr(argv[1], "_b16") ? 16u : 1u;
    if (!strncmp(argv[1], "siso50", 6)) L = 50;
    else if (!strncmp(argv[1], "mimo2x2_50", 10)) { nu = ny = m = 2; L = 50; }
    else if (strncmp(argv[1], "siso1", 5)) { fprintf(stderr, "insn_linux: unknown case %s\n", argv[1]); return 2; }
    const uint32_t N = (uint32_t)strtoul(argv[2], NULL, 10);
    uint32_t bins[64];
    for (uint32_t l = 0; l < L; ++l) bins[l] = 1u + 2u * l;
    msid_twiddle tw;
    const size_t ntw = msid_twiddle_mem_size(P);
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = P; dc.n_lines = L; dc.bins = bins; dc.n_inputs = nu; dc.n_experiments = m; dc.twiddle = &tw;
    msid_design d;
    if (msid_twiddle_init(&tw, P, take(ntw), ntw) != MSID_OK) return 1;
    const size_t nd = msid_design_mem_size(&dc);
    if (msid_design_init(&d, &dc, take(nd), nd) != MSID_OK) return 1;
    msid_gen_cfg gc = {&d, &tw, 0u, 1};
    msid_gen g;
    const size_t ng = msid_gen_mem_size(&gc);
    if (msid_gen_init(&g, &gc, take(ng), ng) != MSID_OK) return 1;
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = P; mc.n_inputs = nu; mc.n_outputs = ny; mc.n_experiments = m;
    mc.n_lines = L; mc.bins = bins; mc.twiddle = &tw; mc.path = MSID_DFT_STREAM;
    msid_meas ms;
    const size_t nm = msid_meas_mem_size(&mc);
    if (msid_meas_init(&ms, &mc, take(nm), nm) != MSID_OK) return 1;
    msid_meas_begin(&ms, 0u);
    const uint32_t C = nu + ny;
    static double rows[16 * 8];
    for (uint32_t s = 0; s < N; s += B) {
        for (uint32_t k = 0; k < B; ++k) {
            double *r = rows + k * C;
            msid_gen_next(&g, r);
            for (uint32_t i = 0; i < ny; ++i) r[nu + i] = r[i % nu];   /* "ADC" */
        }
        if (msid_meas_push(&ms, rows, B) != MSID_OK) return 1;
    }
    printf("case=%s lines=%u channels=%u samples=%u mem_twiddle=%zu mem_design=%zu mem_gen=%zu mem_meas=%zu\n",
           argv[1], (unsigned)L, (unsigned)C, (unsigned)N, ntw, nd, ng, nm);
    return 0;
}
