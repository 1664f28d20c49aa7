/* Extension estimate/1 (daq/msid_mb_est, daq/msid_can_est): float64 registers bit for bit in the
   documented word order, the result block layout, the device-side encoder against the
   msid_meas + msid_frf it reads (decoded values identical to the core's, bit for bit), and the
   CAN double-word frames. */
#define _GNU_SOURCE
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "msid/msid.h"
#include "msid_daq/msid_can_est.h"
#include "msid_daq/msid_mb_est.h"

static void test_f64_registers(void **st)
{
    (void)st;
    uint16_t r[4];
    msid_mb_put_f64(r, 1.0);   /* 0x3FF0000000000000, most significant word first (Python struct ">d") */
    assert_int_equal(r[0], 0x3FF0);
    assert_int_equal(r[1] | r[2] | r[3], 0);
    msid_mb_put_f64(r, -2.5);  /* 0xC004000000000000 */
    assert_int_equal(r[0], 0xC004);
    const double v[] = {0.0, -0.0, INFINITY, -INFINITY, NAN, 4.9e-324, 1.7976931348623157e308, M_PI, -1e-300};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; ++i) {
        msid_mb_put_f64(r, v[i]);
        const double back = msid_mb_get_f64(r);
        assert_memory_equal(&back, &v[i], sizeof back);
    }
    uint64_t x = 0x9E3779B97F4A7C15ull;
    for (int i = 0; i < 1000; ++i) {   /* arbitrary bit patterns, NaN payloads included */
        x ^= x << 13, x ^= x >> 7, x ^= x << 17;
        double d;
        memcpy(&d, &x, sizeof d);
        msid_mb_put_f64(r, d);
        const double back = msid_mb_get_f64(r);
        assert_memory_equal(&back, &d, sizeof d);
    }
}

static void test_layout(void **st)
{
    (void)st;
    msid_mb_est_layout lo;
    assert_int_equal(msid_mb_est_layout_init(&lo, 2, 2, 2, 50), 0);
    const uint32_t g = 4, ny = 2, per_line = 2 * g + 4 * g * g + 2 + 2 * ny * ny + ny + 3;
    assert_int_equal(lo.line, per_line);
    assert_int_equal(lo.lines, 2 * MSID_MB_EST_X_COUNT + 2 * ny * ny);
    assert_int_equal(lo.doubles, lo.lines + 50 * per_line);
    assert_int_equal(msid_mb_est_regs(&lo), 4 * lo.doubles);
    /* fields in order, no overlap */
    const uint32_t off[] = {lo.G, lo.cov, lo.dof, lo.cov_ki, lo.dof_ki, lo.lnoise, lo.snr, lo.cond, lo.usnr, lo.status, lo.line};
    const uint32_t len[] = {2 * g, 2 * g * g, 1, 2 * g * g, 1, 2 * ny * ny, ny, 1, 1, 1};
    for (size_t i = 0; i + 1 < sizeof off / sizeof off[0]; ++i) assert_int_equal(off[i] + len[i], off[i + 1]);
    /* out of range */
    assert_int_equal(msid_mb_est_layout_init(&lo, 2, 2, 1, 5), -1);   /* m < nu */
    assert_int_equal(msid_mb_est_layout_init(&lo, 1, 1, 1, 0), -1);   /* no lines */
    assert_int_equal(msid_mb_est_layout_init(&lo, 0, 1, 1, 3), -1);
}

/* SISO, P = 32, lines {1, 3, 5}, y = 0.5 u(n-1) + noise, 6 periods: encode, decode, compare with the core. */
static void test_encode_matches_core(void **st)
{
    (void)st;
    enum { P = 32, L = 3, K = 6 };
    const uint32_t bins[L] = {1, 3, 5};
    void *mtw = aligned_alloc(64, (msid_twiddle_mem_size(P) + 63) / 64 * 64);
    msid_twiddle tw;
    assert_int_equal(msid_twiddle_init(&tw, P, mtw, msid_twiddle_mem_size(P)), MSID_OK);
    msid_meas_cfg mc = {0};
    mc.period = P; mc.n_inputs = 1; mc.n_outputs = 1; mc.n_experiments = 1; mc.n_lines = L; mc.bins = bins;
    mc.twiddle = &tw; mc.path = MSID_DFT_STREAM; mc.skip_periods = 1;
    mc.transient = MSID_TRANSIENT_FLAG; mc.max_periods = 4 * K + 8; mc.alpha = 0.01;
    const size_t nm = msid_meas_mem_size(&mc);
    void *mm = aligned_alloc(64, (nm + 63) / 64 * 64);
    msid_meas ms;
    assert_int_equal(msid_meas_init(&ms, &mc, mm, nm), MSID_OK);
    msid_rng rng;
    msid_rng_seed(&rng, 7);
    assert_int_equal(msid_meas_begin(&ms, 0), MSID_OK);
    double prev = 0;
    for (uint32_t n = 0; n < K * P; ++n) {
        double u = 0;
        for (int l = 0; l < L; ++l) u += cos(2 * M_PI * bins[l] * (n % P) / P + l);
        const double row[2] = {u, 0.5 * prev + 0.01 * msid_rng_normal(&rng)};
        prev = u;
        assert_int_equal(msid_meas_push(&ms, row, 1), MSID_OK);
    }
    assert_int_equal(msid_meas_end(&ms, NULL), MSID_OK);
    msid_frf_cfg fc = {P, 1, 1, 1, L, 0, NULL};
    const size_t nf = msid_frf_mem_size(&fc);
    void *mf = aligned_alloc(64, (nf + 63) / 64 * 64);
    msid_frf f;
    assert_int_equal(msid_frf_init(&f, &fc, mf, nf), MSID_OK);
    const msid_pstats *ps[1] = {msid_meas_stats(&ms, 0)};
    assert_int_equal(msid_frf_compute(&f, ps), MSID_OK);

    msid_mb_est_layout lo;
    assert_int_equal(msid_mb_est_layout_init(&lo, 1, 1, 1, L), 0);
    uint16_t *regs = calloc(msid_mb_est_regs(&lo), sizeof *regs);
    msid_mb_est_encode(regs, &lo, &ms, &f);
    assert_true(msid_mb_est_value(regs, MSID_MB_EST_X_USED) == K - 1);
    assert_true(msid_mb_est_value(regs, MSID_MB_EST_X_SKIPPED) == 1);
    assert_true(msid_mb_est_value(regs, MSID_MB_EST_X_SAMPLES) == K * P);
    for (uint32_t l = 0; l < L; ++l) {
        const uint32_t b = lo.lines + l * lo.line;
        const msid_cplx G = msid_frf_G(&f, l)[0], C = msid_frf_cov(&f, l)[0];
        const double got[] = {msid_mb_est_value(regs, b + lo.G), msid_mb_est_value(regs, b + lo.G + 1),
                              msid_mb_est_value(regs, b + lo.cov), msid_mb_est_value(regs, b + lo.dof),
                              msid_mb_est_value(regs, b + lo.dof_ki), msid_mb_est_value(regs, b + lo.status)};
        const double want[] = {G.re, G.im, C.re, msid_frf_dof(&f, l), msid_frf_dof_known_input(&f, l), MSID_LINE_OK};
        assert_memory_equal(got, want, sizeof got);
        /* and the estimate is the plant's: 0.5 e^{-j w} within a few standard deviations */
        const double w = 2 * M_PI * bins[l] / P;
        assert_true(hypot(G.re - 0.5 * cos(w), G.im + 0.5 * sin(w)) < 6 * sqrt(C.re));
    }
    /* negative control: a block for other data differs */
    uint16_t *other = calloc(msid_mb_est_regs(&lo), sizeof *other);
    msid_mb_est_encode(other, &lo, &ms, NULL);   /* counts only: the lines stay NaN */
    assert_true(isnan(msid_mb_est_value(other, lo.lines + lo.G)));
    free(other);
    free(regs);
    free(mf);
    free(mm);
    free(mtw);
}

/* msid-can/1 extension: a double as two EST frames (any order), collected bit for bit; other frames ignored. */
static void test_can_value_frames(void **st)
{
    (void)st;
    enum { N = 5 };
    const double v[N] = {M_PI, -0.0, NAN, 1e-310, -7.25};
    double got[N];
    uint8_t have[N] = {0};
    memset(got, 0, sizeof got);
    for (uint32_t k = 0; k < N; ++k) {
        uint8_t lo[8], hi[8];
        msid_can_est_encode_value(lo, hi, k, v[k]);
        assert_int_equal(lo[0], MSID_CAN_EST_MUX_LO);
        assert_int_equal(hi[0], MSID_CAN_EST_MUX_HI);
        assert_int_equal(lo[1] | lo[2] << 8 | lo[3] << 16, k);
        /* high word first for odd k: the order of the pair does not matter */
        assert_int_equal(msid_can_est_collect(k % 2 ? hi : lo, got, have, N), 1);
        assert_int_equal(msid_can_est_collect(k % 2 ? lo : hi, got, have, N), 1);
    }
    assert_memory_equal(got, v, sizeof v);
    for (uint32_t k = 0; k < N; ++k) assert_int_equal(have[k], 3);
    uint8_t f[8], g[8];
    msid_can_est_encode_value(f, g, N, 1.0);                 /* index beyond the block */
    assert_int_equal(msid_can_est_collect(f, got, have, N), 0);
    msid_can_est_encode_state(f, MSID_CAN_EST_STATE_ERROR, 1, MSID_E_MEM_SIZE, 0);   /* not a value */
    assert_int_equal(msid_can_est_collect(f, got, have, N), 0);
    assert_int_equal(f[4] | f[5] << 8, MSID_E_MEM_SIZE);
    assert_int_equal(f[3], MSID_CAN_EST_VERSION);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_f64_registers),
        cmocka_unit_test(test_layout),
        cmocka_unit_test(test_encode_matches_core),
        cmocka_unit_test(test_can_value_frames),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
