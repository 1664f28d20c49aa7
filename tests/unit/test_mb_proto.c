/* msid-modbus/1 codec: word orders against libmodbus's own float functions, scaled integers,
   invalid codes, header and record round trips, the RTU line rate. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>
#if MSID_TEST_LIBMODBUS
#include <modbus/modbus.h>
#endif

#include "msid_daq/msid_mb_proto.h"

/* ABCD is the IEEE-754 bytes most significant first (as Python's struct ">f" and pymodbus
   write them, tests/modbus). libmodbus 3.1.6's modbus_set_float_abcd() writes the bytes of
   each register swapped on little-endian hosts: ours(ABCD) == its "badc", ours(CDAB) == its
   "dcba" -- checked here when the build has libmodbus, so an upgrade that fixes it shows up; the
   expected bytes (want) are checked either way. */
static void test_float_word_orders(void **st)
{
    (void)st;
    const float v[4] = {1.5f, -123.456f, 3.0e-7f, 6.02e23f};
    for (int i = 0; i < 4; ++i) {
        uint32_t u;
        memcpy(&u, &v[i], 4);
        const uint16_t A = (uint16_t)(u >> 24), B = (uint16_t)(u >> 16 & 0xFF), C = (uint16_t)(u >> 8 & 0xFF),
                       D = (uint16_t)(u & 0xFF);
        const uint16_t want[4][2] = {{A << 8 | B, C << 8 | D}, {C << 8 | D, A << 8 | B},
                                     {B << 8 | A, D << 8 | C}, {D << 8 | C, B << 8 | A}};
        for (uint32_t w = 0; w < 4; ++w) {
            uint16_t ours[2];
            msid_mb_encode_value(ours, v[i], MSID_MB_ENC_F32, w, 1);
            assert_memory_equal(ours, want[w], 4);
            assert_true(msid_mb_decode_value(ours, MSID_MB_ENC_F32, w, 1) == (double)v[i]);
        }
#if MSID_TEST_LIBMODBUS
        uint16_t ours[2], lm[2];
        msid_mb_encode_value(ours, v[i], MSID_MB_ENC_F32, MSID_MB_ABCD, 1);
        modbus_set_float_badc(v[i], lm);
        assert_memory_equal(ours, lm, 4);
        msid_mb_encode_value(ours, v[i], MSID_MB_ENC_F32, MSID_MB_CDAB, 1);
        modbus_set_float_dcba(v[i], lm);
        assert_memory_equal(ours, lm, 4);
#endif
    }
}

static void test_scaled_integers_and_invalid_codes(void **st)
{
    (void)st;
    uint16_t r[2];
    for (uint32_t w = 0; w < 4; ++w) {
        msid_mb_encode_value(r, -1.234, MSID_MB_ENC_S16, w, 0.001);
        assert_true(fabs(msid_mb_decode_value(r, MSID_MB_ENC_S16, w, 0.001) + 1.234) < 1e-12);
        msid_mb_encode_value(r, 40.0, MSID_MB_ENC_S16, w, 0.001);           /* out of range */
        assert_true(isnan(msid_mb_decode_value(r, MSID_MB_ENC_S16, w, 0.001)));
        msid_mb_encode_value(r, 1234.567891, MSID_MB_ENC_S32, w, 1e-6);
        assert_true(fabs(msid_mb_decode_value(r, MSID_MB_ENC_S32, w, 1e-6) - 1234.567891) < 1e-9);
        msid_mb_encode_value(r, NAN, MSID_MB_ENC_S32, w, 1e-6);
        assert_true(isnan(msid_mb_decode_value(r, MSID_MB_ENC_S32, w, 1e-6)));
    }
    msid_mb_encode_value(r, 0.258, MSID_MB_ENC_S16, MSID_MB_BADC, 0.001);   /* 258 = 0x0102, byte-swapped */
    assert_int_equal(r[0], 0x0201);
    assert_int_equal(msid_mb_sample_regs(MSID_MB_ENC_S16, 4), 5);
    assert_int_equal(msid_mb_sample_regs(MSID_MB_ENC_F32, 4), 9);
    assert_int_equal(msid_mb_ring_samples(5), (65536 - 64) / 5);
}

static void test_header_and_records_round_trip(void **st)
{
    (void)st;
    msid_mb_header h, g;
    memset(&h, 0, sizeof h);
    h.magic = MSID_MB_MAGIC; h.version = 1; h.state = 3; h.write_index = 0x12345678u; h.seg_start = 70000;
    h.overruns = 99; h.crc = 0xDEADBEEFu; h.period = 256; h.cmd_done = 7; h.periods = 100000;
    uint16_t r[MSID_MB_IR_HEADER];
    msid_mb_header_encode(r, &h);
    assert_int_equal(r[MSID_MB_IR_WRITE_INDEX], 0x1234);
    assert_int_equal(r[MSID_MB_IR_WRITE_INDEX + 1], 0x5678);
    msid_mb_header_decode(&g, r);
    assert_memory_equal(&g, &h, sizeof h);
    uint8_t rec[2][8] = {{1, 2, 3, 4, 5, 6, 7, 8}, {0x7F, 0, 0, 0, 0xEF, 0xBE, 0xAD, 0xDE}}, back[2][8];
    uint16_t rr[8];
    msid_mb_pack_records(rr, (const uint8_t(*)[8])rec, 2);
    assert_int_equal(rr[0], 0x0102);
    msid_mb_unpack_records(back, rr, 2);
    assert_memory_equal(back, rec, sizeof rec);
}

static void test_rtu_line_rate(void **st)
{
    (void)st;
    /* 125 registers at 115200 8N1: (8 + 255) * 10 / 115200 + 2 * 1.75 ms */
    const double t = 263 * 10.0 / 115200 + 3.5e-3;
    assert_true(fabs(msid_mb_rtu_reg_rate(115200, 10, 125) - 125 / t) < 1e-9);
    /* 9600 baud: t3.5 is 3.5 characters */
    const double t2 = 263 * 11.0 / 9600 + 2 * 3.5 * 11 / 9600;
    assert_true(fabs(msid_mb_rtu_reg_rate(9600, 11, 125) - 125 / t2) < 1e-9);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(test_float_word_orders),
        cmocka_unit_test(test_scaled_integers_and_invalid_codes),
        cmocka_unit_test(test_header_and_records_round_trip),
        cmocka_unit_test(test_rtu_line_rate),
    };
    return cmocka_run_group_tests(t, NULL, NULL);
}
