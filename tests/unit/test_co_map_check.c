/* The checks a CANopen run passes before anything is sent (msid_co_map_check.c): the bus budget of the SYNC
 * cycle against frame lengths worked out here from the frame layout (not from msid_co_bus.c), and every
 * entry the run uses against the in-VM tests' drive402.eds: the presets pass it; an entry the file lacks, a
 * read-only target, a channel type other than the entry's, an object that is not mappable, a PDO parameter
 * the node keeps constant, the heartbeat time and the rated torque only when the run uses them. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "msid_daq/msid_co_map.h"
#include "msid_daq/msid_devdesc_file.h"

static const char PRESET[] =
    "format = \"msid-device/1\"\n"
    "transport = \"canopen\"\n"
    "preset = \"cst\"\n"
    "eds = \"data/drive402.eds\"\n"
    "[[drive]]\n"
    "min = -0.3\n"
    "max = 0.3\n"
    "safe = 0.0\n";

static const char EXPLICIT[] =
    "format = \"msid-device/1\"\n"
    "transport = \"canopen\"\n"
    "mode = \"cst\"\n"
    "rated_torque = 1.0\n"
    "heartbeat_ms = 300\n"
    "[[drive]]\n"
    "name = \"T\"\n"
    "object = \"%s\"\n"
    "type = \"%s\"\n"
    "scale = 0.001\n"
    "safe = 0.0\n"
    "[[measure]]\n"
    "name = \"w\"\n"
    "role = \"output\"\n"
    "object = \"%s\"\n"
    "type = \"int32\"\n";

static msid_co_od_entry MEM[256];
static msid_co_eds EDS;
static msid_devdesc D;
static msid_co_map M;
static msid_can_transport T;

static void load_eds(void)
{
    const int rc = msid_co_eds_load(MSID_SOURCE_DIR "/tests/vcan/in_vm/data/drive402.eds", &EDS, MEM, 256);
    if (rc) fail_msg("%d: %s", rc, EDS.err);
}

static void map_of(const char *text)
{
    char err[512];
    if (msid_devdesc_parse(text, strlen(text), MSID_SOURCE_DIR "/tests/vcan/in_vm/d.toml", &D, err, sizeof err))
        fail_msg("%s", err);
    if (msid_co_map_init(&M, &D, 5, D.heartbeat_ms, &T)) fail_msg("%s", M.err);
}

static void map_explicit(const char *drive, const char *type, const char *output)
{
    char t[1024];
    snprintf(t, sizeof t, EXPLICIT, drive, type, output);
    map_of(t);
}

static msid_co_od_entry *entry(uint16_t index, uint8_t sub)
{
    msid_co_od_entry *e = (msid_co_od_entry *)msid_co_eds_find(&EDS, index, sub);
    if (!e) fail_msg("0x%04X:%02X is not in drive402.eds", index, sub);
    return e;
}

/* drop an entry from the dictionary (kept sorted) */
static void remove_entry(uint16_t index, uint8_t sub)
{
    msid_co_od_entry *e = entry(index, sub);
    const size_t at = (size_t)(e - EDS.e);
    memmove(e, e + 1, (EDS.n - at - 1) * sizeof *e);
    EDS.n--;
}

static void expect_refused(const char *needle)
{
    char err[1024] = "";
    assert_int_equal(msid_co_map_check_eds(&M, &EDS, err, sizeof err), -MSID_DAQ_E_ARG);
    if (!strstr(err, needle)) fail_msg("'%s' does not say '%s'", err, needle);
    if (!strstr(err, "drive402.eds")) fail_msg("'%s' does not name the file", err);
}

static void expect_passed(void)
{
    char err[1024] = "";
    if (msid_co_map_check_eds(&M, &EDS, err, sizeof err)) fail_msg("refused: %s", err);
}

static void test_presets_pass(void **state)
{
    (void)state;
    load_eds();
    map_of(PRESET);
    /* eds relative to the description's folder */
    assert_string_equal(D.co_eds, MSID_SOURCE_DIR "/tests/vcan/in_vm/data/drive402.eds");
    expect_passed();
    static const char *const modes[] = {"csv", "csp"};
    for (int k = 0; k < 2; ++k) {
        char t[1024];
        snprintf(t, sizeof t, "%s", PRESET);
        memcpy(strstr(t, "cst"), modes[k], 3);
        map_of(t);
        expect_passed();
    }
    map_explicit("0x6071:00", "int16", "0x606C:00");
    expect_passed();
}

static void test_channels(void **state)
{
    (void)state;
    load_eds();
    map_explicit("0x6071:00", "int16", "0x2100:00");
    expect_refused("measure channel 'w' (object = \"0x2100:00\"): 0x2100:00 is not in");
    map_explicit("0x6077:00", "int16", "0x606C:00");
    expect_refused("drive channel 'T' (object = \"0x6077:00\"): 0x6077:00 (Torque actual value) is read only");
    map_explicit("0x6071:00", "uint16", "0x606C:00");
    expect_refused("0x6071:00 (Target torque) is INTEGER16 in");
    expect_refused("but type = \"uint16\" reads it as UNSIGNED16");
    map_explicit("0x6076:00", "uint32", "0x606C:00");
    expect_refused("0x6076:00 (Motor rated torque) is not PDO-mappable: a target goes in RPDO1");
    map_explicit("0x6071:00", "int16", "0x6076:00");
    expect_refused("is not PDO-mappable: a measured value goes in a TPDO");
    entry(0x606C, 0)->access = MSID_CO_WO;
    map_explicit("0x6071:00", "int16", "0x606C:00");
    expect_refused("0x606C:00 (Velocity actual value) is write only: the node cannot send it");
}

static void test_communication_entries(void **state)
{
    (void)state;
    load_eds();
    map_explicit("0x6071:00", "int16", "0x606C:00");
    /* a node whose TPDO1 mapping is fixed */
    entry(0x1A00, 0)->access = MSID_CO_CONST;
    expect_refused("0x1A00:00 (TPDO1 number of mapped objects, which msid writes) is read only in");
    load_eds();
    remove_entry(0x1400, 2);
    expect_refused("0x1400:02 (RPDO1 transmission type, which msid writes) is not in");
    load_eds();
    remove_entry(0x1600, 1);
    expect_refused("0x1600:01 (RPDO1 mapped object 1, which msid writes) is not in");
    /* a TPDO without an inhibit time takes msid's 0 unwritten */
    load_eds();
    remove_entry(0x1800, 3);
    expect_passed();
    entry(0x6060, 0)->type = 0x0006;
    expect_refused("0x6060:00 (modes of operation) is UNSIGNED16 in");
    load_eds();
    remove_entry(0x6041, 0);
    expect_refused("0x6041:00 (statusword, which msid reads) is not in");
    load_eds();
    remove_entry(0x1006, 0);
    expect_refused("0x1006:00 (communication cycle period, which msid writes) is not in");
    /* the producer heartbeat time with heartbeat_ms only; the rated torque only when the description has none */
    load_eds();
    remove_entry(0x1017, 0);
    expect_refused("0x1017:00 (producer heartbeat time, which msid writes) is not in");
    load_eds();
    remove_entry(0x6076, 0);
    expect_passed();   /* rated_torque = 1.0 */
    map_of(PRESET);
    expect_refused("0x6076:00 (motor rated torque, which msid reads) is not in");
    load_eds();
    remove_entry(0x1017, 0);
    expect_passed();   /* no heartbeat_ms */
}

/* A classic frame with an 11-bit identifier: SOF 1, identifier 11, RTR 1, IDE 1, r0 1, DLC 4, data 8 n,
 * CRC 15 (all stuffed: 34 + 8 n bits, at worst a stuff bit after each 4 of them but the first), then CRC
 * delimiter 1, ACK 2, EOF 7 and intermission 3 unstuffed: 47 + 8 n bits and the stuff bits. */
static unsigned frame_bits(unsigned n)
{
    const unsigned stuffed = 1 + 11 + 1 + 1 + 1 + 4 + 8 * n + 15;
    return stuffed + (stuffed - 1) / 4 + 1 + 2 + 7 + 3;
}

static void test_bus_budget(void **state)
{
    (void)state;
    assert_int_equal(frame_bits(0), 55);
    assert_int_equal(frame_bits(8), 135);
    map_of(PRESET);
    /* cst: RPDO1 2 bytes (target torque), TPDO1 8 (demand, torque, velocity), TPDO2 4 (position), the SYNC empty */
    assert_int_equal(M.rpdo_len, 2);
    assert_int_equal(M.tpdo_len[0], 8);
    assert_int_equal(M.tpdo_len[1], 4);
    const unsigned bits = frame_bits(0) + frame_bits(2) + frame_bits(8) + frame_bits(4);
    assert_int_equal(bits, 55 + 75 + 135 + 95);
    char err[400];
    double fits = 0;
    static const uint32_t rates[] = {10000, 125000, 250000, 500000, 1000000};
    for (size_t k = 0; k < sizeof rates / sizeof rates[0]; ++k) {
        const double expect = MSID_CO_MAP_BUS_SHARE * rates[k] / bits;
        assert_int_equal(msid_co_map_check_bus(&M, rates[k], 0.999 * expect, &fits, err, sizeof err), 0);
        assert_true(fabs(fits - expect) < 1e-9 * expect);
        assert_int_equal(msid_co_map_check_bus(&M, rates[k], 1.001 * expect, &fits, err, sizeof err), -MSID_DAQ_E_ARG);
    }
    /* 0.7 x 10 kbit/s / 360 bits = 19.4 Hz */
    assert_int_equal(msid_co_map_check_bus(&M, 10000, 50, NULL, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_string_equal(err, "at 50 Hz the SYNC and 3 PDOs take 360 bits a cycle (18 kbit/s at worst), above 70% of "
                             "the 10 kbit/s bus: it carries them at up to 19 Hz");
    /* one TPDO: SYNC + RPDO1 (2 bytes) + TPDO1 (4 bytes) */
    map_explicit("0x6071:00", "int16", "0x606C:00");
    assert_int_equal(msid_co_map_check_bus(&M, 1000000, 1000, &fits, err, sizeof err), 0);
    const double one = MSID_CO_MAP_BUS_SHARE * 1e6 / (frame_bits(0) + frame_bits(2) + frame_bits(4));
    assert_true(fabs(fits - one) < 1e-9 * one);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_presets_pass), cmocka_unit_test(test_channels),
                                       cmocka_unit_test(test_communication_entries),
                                       cmocka_unit_test(test_bus_budget)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
