/* msid bare-metal example: the whole measurement on the microcontroller.
 *
 * Generates a SISO multisine with lib/ (msid_design, msid_gen), drives a
 * simulated plant (msid_plant, 2nd-order resonance, white output noise from
 * msid_rng), estimates the FRF in streaming form one sample at a time
 * (msid_meas: line DFT + period statistics) and solves it at the end
 * (msid_frf), then prints every line's G, variance and degrees of freedom.
 *
 * No heap: every object lives in one static arena sized by the
 * msid_*_mem_size() calls. On a real controller replace plant_and_adc() with
 * "write u to the DAC, read y from the ADC" inside the sampling interrupt;
 * everything else stays. Output goes through printf: semihosting on the
 * emulated MPS2 board (qemu-system-arm), stdout on the host. The same source
 * built for the host prints the same lines bit for bit (ctest -L target checks
 * it); lines starting with '#' describe the platform and are not compared.
 * See firmware_sim/baremetal/README.md. */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "msid/msid.h"

#define PERIOD 256u   /* samples per period */
#define N_LINES 16u   /* excited bins 2, 6, 10, ..., 62 */
#define SKIP 1u       /* leading periods dropped (plant transient) */
#define PERIODS 7u    /* periods measured, SKIP of them skipped */
#define NOISE 0.02    /* output noise standard deviation */

/* One static arena for every object; 64-byte aligned (MSID_MEM_ALIGN). */
#define ARENA_BYTES 32768u
static unsigned char arena[ARENA_BYTES] __attribute__((aligned(64)));
static size_t arena_used;

static void *take(size_t n)
{
    n = (n + MSID_MEM_ALIGN - 1u) & ~(size_t)(MSID_MEM_ALIGN - 1u);
    if (n > ARENA_BYTES - arena_used) return NULL;
    void *p = arena + arena_used;
    arena_used += n;
    return p;
}

static int check(const char *what, msid_status st)
{
    if (st == MSID_OK) return 0;
    printf("error: %s: %s\n", what, msid_strerror(st));
    return 1;
}

/* The plant: y(n) = C x(n) + noise, x(n+1) = A x(n) + B u(n); poles 0.8 +- 0.4j. */
static msid_plant plant;
static msid_rng rng;
static double plant_and_adc(double u)
{
    double y;
    msid_plant_step(&plant, &u, &y);
    return y + NOISE * msid_rng_normal(&rng);
}

static uint64_t fnv1a(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = (const unsigned char *)p;
    for (size_t i = 0; i < n; ++i) { h ^= b[i]; h *= 0x100000001b3ull; }
    return h;
}

int main(void)
{
    static const double A[4] = {1.6, -0.8, 1.0, 0.0}, B[2] = {1.0, 0.0}, C[2] = {0.1, 0.05};
    uint32_t bins[N_LINES];
    for (uint32_t l = 0; l < N_LINES; ++l) bins[l] = 2u + 4u * l;

    /* twiddle table and design: random phases from a fixed seed */
    msid_twiddle tw;
    size_t n = msid_twiddle_mem_size(PERIOD);
    if (check("twiddle", msid_twiddle_init(&tw, PERIOD, take(n), n))) return 1;
    msid_design_cfg dc;
    memset(&dc, 0, sizeof dc);
    dc.period = PERIOD; dc.n_lines = N_LINES; dc.bins = bins;
    dc.phase_mode = MSID_PHASE_RANDOM; dc.seed = 12u;
    dc.n_inputs = 1; dc.n_experiments = 1; dc.twiddle = &tw;
    msid_design design;
    n = msid_design_mem_size(&dc);
    if (check("design", msid_design_init(&design, &dc, take(n), n))) return 1;

    /* generator: on-the-fly mode (L*4 bytes of state instead of a P-sample table) */
    msid_gen_cfg gc = {&design, &tw, 0u, 0};
    msid_gen gen;
    n = msid_gen_mem_size(&gc);
    if (check("gen", msid_gen_init(&gen, &gc, take(n), n))) return 1;

    msid_plant_cfg pc = {2u, 1u, 1u, A, B, C, NULL};
    n = msid_plant_mem_size(&pc);
    if (check("plant", msid_plant_init(&plant, &pc, take(n), n))) return 1;
    msid_rng_seed(&rng, 2026u);

    /* streaming estimator: line DFT of [u, y] at the excited bins, period statistics */
    msid_meas_cfg mc;
    memset(&mc, 0, sizeof mc);
    mc.period = PERIOD; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = 1;
    mc.n_lines = N_LINES; mc.bins = bins; mc.twiddle = &tw; mc.path = MSID_DFT_STREAM;
    mc.skip_periods = SKIP;
    msid_meas meas;
    n = msid_meas_mem_size(&mc);
    if (check("meas", msid_meas_init(&meas, &mc, take(n), n))) return 1;

    msid_frf_cfg fc = {PERIOD, 1u, 1u, 1u, N_LINES, 0u, NULL};
    msid_frf frf;
    n = msid_frf_mem_size(&fc);
    if (check("frf", msid_frf_init(&frf, &fc, take(n), n))) return 1;

    /* the sampling loop: in firmware, the body of the sample interrupt */
    if (check("begin", msid_meas_begin(&meas, 0u))) return 1;
    for (uint32_t k = 0; k < PERIODS * PERIOD; ++k) {
        double row[2];
        msid_gen_next(&gen, &row[0]);       /* u(k) */
        row[1] = plant_and_adc(row[0]);     /* y(k) */
        if (check("push", msid_meas_push(&meas, row, 1u))) return 1;
    }
    if (check("end", msid_meas_end(&meas, NULL))) return 1;
    const msid_pstats *ps = msid_meas_stats(&meas, 0u);
    if (check("frf", msid_frf_compute(&frf, &ps))) return 1;

    printf("# msid bare-metal example on %s, %u bytes of arena used\n",
#if defined(__ARM_ARCH_7EM__) && defined(__ARM_FP) && (__ARM_FP & 8)
           "Cortex-M7 (double-precision FPU)",
#elif defined(__ARM_ARCH_7EM__)
           "Cortex-M4F (double precision in software)",
#else
           "the host",
#endif
           (unsigned)arena_used);
    printf("SISO P=%u lines=%u periods=%u skipped=%u noise=%g\n", PERIOD, N_LINES, PERIODS, SKIP, NOISE);
    printf("bin  G_re                    G_im                    var(G)                  dof  true_re                 true_im\n");
    uint64_t h = 0xcbf29ce484222325ull;
    for (uint32_t l = 0; l < N_LINES; ++l) {
        const msid_cplx G = msid_frf_G(&frf, l)[0];
        const double var = msid_frf_cov(&frf, l)[0].re, dof = msid_frf_dof(&frf, l);
        msid_cplx T;
        msid_plant_frf(&plant, (double)bins[l] / PERIOD, &T);
        printf("%3u  %-23.17g %-23.17g %-23.17g %3g  %-23.17g %-23.17g\n", (unsigned)bins[l], G.re, G.im, var, dof,
               T.re, T.im);
        h = fnv1a(h, &G, sizeof G);
        h = fnv1a(h, &var, sizeof var);
        h = fnv1a(h, &dof, sizeof dof);
    }
    printf("hash %08lx%08lx\n", (unsigned long)(h >> 32), (unsigned long)(h & 0xffffffffu));
    return 0;
}
