/* Twiddle table: entries vs exp(-j 2 pi n / P) in long double, exact points, errors. */
#include "unit_util.h"
#include <float.h>

static void check_table(uint32_t P)
{
    const size_t need = msid_twiddle_mem_size(P);
    UT_CHECK(need == ut_round64((size_t)16u * P), "P=%u need=%zu", P, need);
    void *mem = tsim_alloc(need);
    msid_twiddle tw;
    UT_STATUS(msid_twiddle_init(&tw, P, mem, need), MSID_OK);
    UT_CHECK(tw.period == P && tw.w == mem, "P=%u", P);
    double worst = 0.0;
    uint32_t wn = 0;
    for (uint32_t n = 0; n < P; ++n) {
        const long double a = 2.0L * UT_PI_L * (long double)n / (long double)P;
        const double e = (double)fmaxl(fabsl(tw.w[n].re - cosl(a)), fabsl(tw.w[n].im + sinl(a)));
        if (e > worst) { worst = e; wn = n; }
    }
    UT_CHECK(worst <= 4e-16, "P=%u: max error %.3g at n=%u", P, worst, wn);
    /* exact points */
    UT_CHECK(tw.w[0].re == 1.0 && tw.w[0].im == 0.0, "P=%u w[0]", P);
    if (P % 2u == 0u) UT_CHECK(tw.w[P / 2].re == -1.0 && tw.w[P / 2].im == 0.0, "P=%u w[P/2]=(%.17g,%.17g)", P, tw.w[P / 2].re, tw.w[P / 2].im);
    if (P % 4u == 0u) {
        UT_CHECK(tw.w[P / 4].re == 0.0 && tw.w[P / 4].im == -1.0, "P=%u w[P/4]=(%.17g,%.17g)", P, tw.w[P / 4].re, tw.w[P / 4].im);
        UT_CHECK(tw.w[3 * (P / 4)].re == 0.0 && tw.w[3 * (P / 4)].im == 1.0, "P=%u w[3P/4]", P);
    }
    if (P % 8u == 0u)
        for (uint32_t k = 1; k < 8; k += 2) {
            const msid_cplx w = tw.w[k * (P / 8)];
            UT_CHECK(fabs(w.re) == UT_SQRT1_2 && fabs(w.im) == UT_SQRT1_2, "P=%u w[%u P/8]=(%.17g,%.17g)", P, k, w.re, w.im);
        }
    /* real DFT symmetry: w[P-n] = conj(w[n]) */
    for (uint32_t n = 1; n < P; ++n)
        UT_CHECK(tw.w[P - n].re == tw.w[n].re && tw.w[P - n].im == -tw.w[n].im, "P=%u n=%u", P, n);
    tsim_free(mem);
}

static void test_entries(void **state)
{
    (void)state;
#if LDBL_MANT_DIG <= DBL_MANT_DIG
    /* The reference needs a wider long double: where it is double (32-bit ARM) the rounding of 2 pi n / P
     * alone exceeds the tolerance (armhf under qemu-arm: 6.11e-16 at P = 3, n = 2). target_linux_bits
     * requires the table's bits to equal the x86-64 build's there, so its accuracy is the host's. */
    skip();
#endif
    const uint32_t Ps[] = {2, 3, 4, 5, 6, 7, 8, 12, 16, 24, 100, 1000, 1023, 1024, 4096, 65536, 99991, 999983, 1u << 20};
    for (size_t k = 0; k < sizeof Ps / sizeof Ps[0]; ++k) check_table(Ps[k]);
}

static void test_errors(void **state)
{
    (void)state;
    msid_twiddle tw;
    assert_int_equal(msid_twiddle_mem_size(0), 0);
    assert_int_equal(msid_twiddle_mem_size(1), 0);
    assert_int_equal(msid_twiddle_mem_size(MSID_MAX_PERIOD + 1u), 0);
    assert_int_equal(msid_twiddle_mem_size(MSID_MAX_PERIOD), (size_t)16u * MSID_MAX_PERIOD);
    assert_int_equal(msid_twiddle_mem_size(2), 64);
    assert_int_equal(msid_twiddle_mem_size(5), 128);
    const uint32_t P = 64;
    const size_t need = msid_twiddle_mem_size(P);
    unsigned char *mem = (unsigned char *)tsim_alloc(need + 64);
    UT_STATUS(msid_twiddle_init(NULL, P, mem, need), MSID_E_NULL);
    UT_STATUS(msid_twiddle_init(&tw, P, NULL, need), MSID_E_NULL);
    UT_STATUS(msid_twiddle_init(&tw, 0, mem, need), MSID_E_PERIOD);
    UT_STATUS(msid_twiddle_init(&tw, 1, mem, need), MSID_E_PERIOD);
    UT_STATUS(msid_twiddle_init(&tw, MSID_MAX_PERIOD + 1u, mem, need), MSID_E_PERIOD);
    UT_STATUS(msid_twiddle_init(&tw, P, ut_misalign(mem), need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_twiddle_init(&tw, P, mem + 32, need), MSID_E_MEM_ALIGN);
    UT_STATUS(msid_twiddle_init(&tw, P, mem, need - 1), MSID_E_MEM_SIZE);
    UT_STATUS(msid_twiddle_init(&tw, P, mem, 0), MSID_E_MEM_SIZE);
    UT_STATUS(msid_twiddle_init(&tw, P, mem + 64, need), MSID_OK);
    UT_STATUS(msid_twiddle_init(&tw, 2, mem, msid_twiddle_mem_size(2)), MSID_OK);
    UT_CHECK(tw.w[0].re == 1.0 && tw.w[1].re == -1.0 && tw.w[1].im == 0.0, "P=2 (%g,%g)", tw.w[1].re, tw.w[1].im);
    tsim_free(mem);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_entries),
        cmocka_unit_test(test_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
