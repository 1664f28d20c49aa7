/* msid-device/1: the register value codec against hand-computed registers, its range checks, and the TOML
 * reader's messages (msid_devdesc.h, msid_devdesc_file.h). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "msid_daq/msid_devdesc.h"
#include "msid_daq/msid_devdesc_file.h"
#include "msid_daq/msid_mb_proto.h"

static msid_dev_chan chan(uint32_t type, uint32_t wo, double scale, double offset)
{
    msid_dev_chan c;
    msid_dev_chan_defaults(&c);
    c.type = type;
    c.word_order = wo;
    c.scale = scale;
    c.offset = offset;
    return c;
}

static void expect_regs(uint32_t type, uint32_t wo, double v, const uint16_t *want)
{
    const msid_dev_chan c = chan(type, wo, 1.0, 0.0);
    uint16_t r[4] = {0xAAAA, 0xAAAA, 0xAAAA, 0xAAAA};
    assert_int_equal(msid_dev_encode(&c, v, r), 0);
    for (uint32_t i = 0; i < msid_dev_type_regs(type); ++i) assert_int_equal(r[i], want[i]);
    assert_true(msid_dev_decode(&c, r) == v);
}

/* The four word orders of 16-, 32- and 64-bit values, written out by hand. */
static void test_word_orders(void **state)
{
    (void)state;
    expect_regs(MSID_DEV_FLOAT32, MSID_MB_ABCD, 1.0, (const uint16_t[]){0x3F80, 0x0000});
    expect_regs(MSID_DEV_FLOAT32, MSID_MB_CDAB, 1.0, (const uint16_t[]){0x0000, 0x3F80});
    expect_regs(MSID_DEV_FLOAT32, MSID_MB_BADC, 1.0, (const uint16_t[]){0x803F, 0x0000});
    expect_regs(MSID_DEV_FLOAT32, MSID_MB_DCBA, 1.0, (const uint16_t[]){0x0000, 0x803F});
    expect_regs(MSID_DEV_UINT32, MSID_MB_ABCD, 305419896.0, (const uint16_t[]){0x1234, 0x5678});
    expect_regs(MSID_DEV_UINT32, MSID_MB_CDAB, 305419896.0, (const uint16_t[]){0x5678, 0x1234});
    expect_regs(MSID_DEV_UINT32, MSID_MB_BADC, 305419896.0, (const uint16_t[]){0x3412, 0x7856});
    expect_regs(MSID_DEV_UINT32, MSID_MB_DCBA, 305419896.0, (const uint16_t[]){0x7856, 0x3412});
    expect_regs(MSID_DEV_INT32, MSID_MB_ABCD, -2.0, (const uint16_t[]){0xFFFF, 0xFFFE});
    expect_regs(MSID_DEV_INT16, MSID_MB_ABCD, -1.0, (const uint16_t[]){0xFFFF});
    expect_regs(MSID_DEV_INT16, MSID_MB_BADC, 4660.0, (const uint16_t[]){0x3412});
    expect_regs(MSID_DEV_UINT16, MSID_MB_CDAB, 65535.0, (const uint16_t[]){0xFFFF});
    /* 1.0 = 0x3FF0000000000000; -2.5 = 0xC004000000000000 */
    expect_regs(MSID_DEV_FLOAT64, MSID_MB_ABCD, 1.0, (const uint16_t[]){0x3FF0, 0, 0, 0});
    expect_regs(MSID_DEV_FLOAT64, MSID_MB_CDAB, 1.0, (const uint16_t[]){0, 0, 0, 0x3FF0});
    expect_regs(MSID_DEV_FLOAT64, MSID_MB_BADC, -2.5, (const uint16_t[]){0x04C0, 0, 0, 0});
    expect_regs(MSID_DEV_FLOAT64, MSID_MB_DCBA, -2.5, (const uint16_t[]){0, 0, 0, 0x04C0});
}

/* Scale, offset, rounding to nearest, and values the type cannot hold refused (nothing written). */
static void test_scale_and_range(void **state)
{
    (void)state;
    msid_dev_chan c = chan(MSID_DEV_INT16, MSID_MB_ABCD, 0.001, 0.0);
    uint16_t r[2] = {0x5555, 0x5555};
    assert_int_equal(msid_dev_encode(&c, 1.2346, r), 0);
    assert_int_equal(r[0], 1235);
    assert_int_equal(msid_dev_encode(&c, -1.2346, r), 0);
    assert_int_equal((int16_t)r[0], -1235);
    assert_true(fabs(msid_dev_decode(&c, r) - (-1.235)) < 1e-12);
    r[0] = 0x5555;
    assert_int_equal(msid_dev_encode(&c, 40.0, r), -1);   /* 40000 > 32767 */
    assert_int_equal(r[0], 0x5555);
    assert_int_equal(msid_dev_encode(&c, NAN, r), -1);
    c = chan(MSID_DEV_UINT16, MSID_MB_ABCD, 0.5, 10.0);   /* physical = raw / 2 + 10 */
    assert_int_equal(msid_dev_encode(&c, 9.0, r), -1);   /* raw -2 */
    assert_int_equal(msid_dev_encode(&c, 20.0, r), 0);
    assert_int_equal(r[0], 20);
    assert_true(msid_dev_decode(&c, r) == 20.0);
    c = chan(MSID_DEV_FLOAT32, MSID_MB_ABCD, 1.0, 0.0);
    assert_int_equal(msid_dev_encode(&c, 1e39, r), -1);
    c = chan(MSID_DEV_UINT32, MSID_MB_ABCD, 1.0, 0.0);
    assert_int_equal(msid_dev_encode(&c, 4294967295.0, r), 0);
    assert_int_equal(msid_dev_encode(&c, 4294967296.0, r), -1);
}

/* Random round trips: decode(encode(v)) within half a step for integers, float32 rounding, float64 exact. */
static void test_round_trips(void **state)
{
    (void)state;
    uint64_t s = 12345;
    for (int k = 0; k < 20000; ++k) {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        const uint32_t type = 1 + (uint32_t)((s >> 33) % 6), wo = (uint32_t)((s >> 40) % 4);
        const double scale = (s >> 20) % 2 ? 0.01 : 1.0;
        const msid_dev_chan c = chan(type, wo, scale, (s >> 50) % 2 ? 3.0 : 0.0);
        const double u = (double)((s >> 11) & 0xFFFFF) / (double)0xFFFFF;   /* [0, 1] */
        const double v = c.offset + scale * (u * 60000.0 - (type == MSID_DEV_UINT16 || type == MSID_DEV_UINT32 ? 0 : 30000));
        uint16_t r[4];
        assert_int_equal(msid_dev_encode(&c, v, r), 0);
        const double back = msid_dev_decode(&c, r);
        const double tol = type == MSID_DEV_FLOAT64 ? 0 : type == MSID_DEV_FLOAT32 ? fabs(v - c.offset) * 1.2e-7 + 1e-12 : 0.5 * scale * (1 + 1e-9);
        assert_true(fabs(back - v) <= tol);
    }
}

static const char *ISSUE_EXAMPLE =
    "format = \"msid-device/1\"\n"
    "transport = \"modbus\"\n"
    "unit = 1\n"
    "\n"
    "[[drive]]\n"
    "name = \"Torque command\"\n"
    "unit = \"N m\"\n"
    "register = \"holding:100\"\n"
    "type = \"float32\"\n"
    "word_order = \"ABCD\"\n"
    "min = -2.0\n"
    "max = 2.0\n"
    "safe = 0.0\n"
    "\n"
    "[[measure]]\n"
    "name = \"Torque\"\n"
    "unit = \"N m\"\n"
    "role = \"input\"\n"
    "register = \"input:0\"\n"
    "type = \"float32\"\n"
    "word_order = \"ABCD\"\n"
    "\n"
    "[[measure]]\n"
    "name = \"Speed\"\n"
    "unit = \"rad/s\"\n"
    "role = \"output\"\n"
    "register = \"input:2\"\n"
    "type = \"int16\"\n"
    "scale = 0.001\n";

static void test_reads_the_example(void **state)
{
    (void)state;
    msid_devdesc d;
    char err[512];
    const int rc = msid_devdesc_parse(ISSUE_EXAMPLE, strlen(ISSUE_EXAMPLE), "dev.toml", &d, err, sizeof err);
    if (rc) fail_msg("%s", err);
    assert_int_equal(d.transport, MSID_DEV_MODBUS);
    assert_int_equal(d.unit, 1);
    assert_int_equal(d.n_drive, 1);
    assert_int_equal(d.n_measure, 2);
    assert_string_equal(d.drive[0].name, "Torque command");
    assert_string_equal(d.drive[0].unit, "N m");
    assert_int_equal(d.drive[0].table, MSID_DEV_HOLDING);
    assert_int_equal(d.drive[0].addr, 100);
    assert_int_equal(d.drive[0].type, MSID_DEV_FLOAT32);
    assert_true(d.drive[0].min == -2.0 && d.drive[0].max == 2.0 && d.drive[0].safe == 0.0);
    assert_true(isnan(d.drive[0].max_step) && isnan(d.drive[0].op) && isnan(d.drive[0].amplitude));
    assert_int_equal(d.measure[0].role, MSID_DEV_ROLE_INPUT);
    assert_int_equal(d.measure[1].role, MSID_DEV_ROLE_OUTPUT);
    assert_int_equal(d.measure[1].type, MSID_DEV_INT16);
    assert_true(d.measure[1].scale == 0.001);
    assert_int_equal(d.measure[1].addr, 2);
    assert_int_equal(d.measure[1].line, 23);
    assert_int_equal(msid_devdesc_readback(&d, 0), 0);
    assert_int_equal(d.fade_periods, 1);
    assert_int_equal(d.fc23, -1);
}

/* The example with one edit: replace `from` by `to` and expect a message containing `want`. */
static void expect_refused(const char *from, const char *to, const char *want)
{
    char text[4096];
    const char *at = strstr(ISSUE_EXAMPLE, from);
    assert_non_null(at);
    const size_t pre = (size_t)(at - ISSUE_EXAMPLE);
    snprintf(text, sizeof text, "%.*s%s%s", (int)pre, ISSUE_EXAMPLE, to, at + strlen(from));
    msid_devdesc d;
    char err[512] = "";
    assert_int_equal(msid_devdesc_parse(text, strlen(text), "dev.toml", &d, err, sizeof err), -1);
    if (!strstr(err, want)) fail_msg("message '%s' does not say '%s'", err, want);
}

static void test_refusals(void **state)
{
    (void)state;
    expect_refused("safe = 0.0", "safe = 0.0\nmax_stp = 0.1", "dev.toml line 14: unknown key 'max_stp'");
    expect_refused("safe = 0.0", "", "no safe value");
    expect_refused("safe = 0.0", "safe = 3.0", "the safe value 3 is above max 2");
    expect_refused("min = -2.0", "min = 2.5", "min 2.5 is not below max 2");
    expect_refused("register = \"holding:100\"", "register = \"40101\"", "1-based Modicon number: holding:100");
    expect_refused("register = \"holding:100\"", "register = \"input:100\"", "input registers, which are read-only");
    expect_refused("register = \"holding:100\"", "register = \"holding:70000\"", "0..65535");
    expect_refused("type = \"int16\"", "type = \"int12\"", "type = \"int12\"");
    expect_refused("role = \"output\"", "role = \"outptu\"", "role = \"outptu\"");
    expect_refused("role = \"output\"", "role = \"reference\"", "no [[measure]] channel with role = \"output\"");
    expect_refused("name = \"Speed\"", "name = \"Torque\"", "a second channel named 'Torque'");
    expect_refused("register = \"input:2\"", "register = \"input:1\"", "overlaps the registers of 'Torque'");
    expect_refused("format = \"msid-device/1\"", "format = \"msid-device/2\"", "msid reads msid-device/1");
    expect_refused("unit = 1\n", "unit = 300\n", "unit must be 0..247");
    expect_refused("max = 2.0", "max = \"2\"", "max must be a number");
    expect_refused("max = 2.0", "max = 2.0 2", "dev.toml line 12");   /* a TOML syntax error names its line */
    expect_refused("role = \"input\"", "role = \"input\"\nreads_back = \"Torque cmd\"", "names no drive channel");
    expect_refused("scale = 0.001", "scale = 0", "scale must be finite and non-zero");
    expect_refused("transport = \"modbus\"", "transport = \"profibus\"", "must be \"modbus\", \"can\" or \"canopen\"");
}

static void test_missing_file(void **state)
{
    (void)state;
    msid_devdesc d;
    char err[512];
    assert_int_equal(msid_devdesc_load("/nonexistent/dev.toml", &d, err, sizeof err), -1);
    assert_non_null(strstr(err, "cannot read the device description '/nonexistent/dev.toml'"));
    assert_int_equal(msid_devdesc_load("/", &d, err, sizeof err), -1);
    if (!strstr(err, "'/'")) fail_msg("%s", err);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_word_orders),   cmocka_unit_test(test_scale_and_range),
        cmocka_unit_test(test_round_trips),   cmocka_unit_test(test_reads_the_example),
        cmocka_unit_test(test_refusals),      cmocka_unit_test(test_missing_file),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
