/* The bus budget of a SYNC cycle (daq/src/msid_co_bus.c): worst-case frame lengths worked out by hand, the
   rate a 1 Mbit/s bus carries for a drive's PDOs, and the refusal that says it. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "msid_daq/msid_co_bus.h"

static void test_frame_bits(void **state)
{
    (void)state;
    /* 0 bytes: 34 stuffed bits + 8 stuff bits + 13 = 55; 8 bytes: 98 + 24 + 13 = 135; 2 bytes: 50 + 12 + 13 = 75; 4 bytes: 66 + 16 + 13 = 95 */
    assert_int_equal(msid_co_frame_bits(0), 55);
    assert_int_equal(msid_co_frame_bits(2), 75);
    assert_int_equal(msid_co_frame_bits(4), 95);
    assert_int_equal(msid_co_frame_bits(8), 135);
    assert_int_equal(msid_co_frame_bits(9), 0);
    for (unsigned b = 1; b <= 8; b++) assert_true(msid_co_frame_bits(b) > msid_co_frame_bits(b - 1));
}

static void test_budget(void **state)
{
    (void)state;
    /* CST: an RPDO of controlword + target torque (4 bytes), a TPDO of demand, actual torque and velocity (8) */
    const uint8_t pdos[2] = {4, 8};
    char err[240];
    double fits = 0;
    /* SYNC 55 + (66 + 16 + 13 = 95) + 135 = 285 bits a cycle; 70% of 1 Mbit/s carries 2456.1 of them a second */
    assert_int_equal(msid_co_bus_check(1000000, 1000, 0, pdos, 2, 0.7, &fits, err, sizeof err), 0);
    assert_true(fits > 2456.0 && fits < 2456.2);
    assert_int_equal(msid_co_bus_check(250000, 1000, 0, pdos, 2, 0.7, &fits, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_string_equal(err, "at 1000 Hz the SYNC and 2 PDOs take 285 bits a cycle (285 kbit/s at worst), above 70% of "
                             "the 250 kbit/s bus: it carries them at up to 614 Hz");
    const uint8_t nine = 9;
    assert_int_equal(msid_co_bus_check(1000000, 100, 0, &nine, 1, 0.7, NULL, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_co_bus_check(0, 100, 0, pdos, 2, 0.7, NULL, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_co_bus_check(1000000, 100, 2, pdos, 2, 0.7, NULL, err, sizeof err), -MSID_DAQ_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_frame_bits), cmocka_unit_test(test_budget)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
