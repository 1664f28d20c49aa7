/* CANopen EDS/DCF files (daq/src/msid_co_eds_file.cpp, msid_co_eds.c): the in-VM tests' drive402.eds read
   entry by entry, records, a compact array, a DCF's ParameterValue; every refusal with its line; and the
   checks made before a write or a PDO mapping, one message each (an entry the file lacks, a read-only
   entry as a target, a size other than the type's, an object that is not mappable). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "msid_daq/msid_co_eds.h"

static msid_co_od_entry MEM[256];

static void load_drive(msid_co_eds *eds)
{
    const int rc = msid_co_eds_load(MSID_SOURCE_DIR "/tests/vcan/in_vm/data/drive402.eds", eds, MEM, 256);
    if (rc) fail_msg("%d: %s", rc, eds->err);
}

static const char *write_tmp(const char *text)
{
    static char path[64];
    snprintf(path, sizeof path, "/tmp/msid_test_co_eds_%d.eds", (int)getpid());
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    return path;
}

static int load_text(const char *text, msid_co_eds *eds)
{
    const char *p = write_tmp(text);
    const int rc = msid_co_eds_load(p, eds, MEM, 256);
    remove(p);
    return rc;
}

static void test_drive_file(void **state)
{
    (void)state;
    msid_co_eds eds;
    load_drive(&eds);
    /* 4 variables of 0x10xx, 0x1016 (2), 0x1018 (5), RPDOs 4 x (3 + 9), TPDOs 4 x (4 + 9), 2 test and 13 drive variables
     * (the torque offset 0x60B2 among them) */
    assert_int_equal(eds.n, 4 + 2 + 5 + 4 * 12 + 4 * 13 + 2 + 13);
    const msid_co_od_entry *e = msid_co_eds_find(&eds, 0x1018, 2);
    assert_non_null(e);
    assert_int_equal(e->type, 0x0007);
    assert_int_equal(e->access, MSID_CO_RO);
    assert_string_equal(e->name, "Product code");
    assert_string_equal(e->value, "0x402");
    e = msid_co_eds_find(&eds, 0x1800, 1);
    assert_string_equal(e->value, "$NODEID+0x40000180");
    e = msid_co_eds_find(&eds, 0x6041, 0);
    assert_true(e->pdo_mappable);
    assert_int_equal(e->access, MSID_CO_RO);
    assert_int_equal(msid_co_eds_find(&eds, 0x2000, 0)->type, 0x000F);
    assert_null(msid_co_eds_find(&eds, 0x1018, 5));
    assert_null(msid_co_eds_find(&eds, 0x3000, 0));
    for (uint32_t i = 1; i < eds.n; i++)  /* sorted for the binary search */
        assert_true(((uint32_t)eds.e[i - 1].index << 8 | eds.e[i - 1].sub) < ((uint32_t)eds.e[i].index << 8 | eds.e[i].sub));
}

static void test_checks(void **state)
{
    (void)state;
    msid_co_eds eds;
    load_drive(&eds);
    char err[240];
    assert_int_equal(msid_co_eds_check_write(&eds, 0x6040, 0, 2, err, sizeof err), 0);
    assert_int_equal(msid_co_eds_check_write(&eds, 0x2000, 0, 17, err, sizeof err), 0);  /* a domain takes any size */
    assert_int_equal(msid_co_eds_check_write(&eds, 0x3000, 0, 2, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(err, "0x3000:00 is not in "));
    assert_int_equal(msid_co_eds_check_write(&eds, 0x6041, 0, 2, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(err, "0x6041:00 (Statusword) is read only in "));
    assert_int_equal(msid_co_eds_check_write(&eds, 0x6040, 0, 4, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(err, "0x6040:00 (Controlword) is UNSIGNED16 (2 bytes) in "));
    assert_non_null(strstr(err, "not 4 bytes"));

    msid_co_pdo_cfg t = {.tx = 1, .num = 1, .trans_type = 1, .n = 3};
    t.e[0] = (msid_co_pdo_entry){0x6074, 0, 16};
    t.e[1] = (msid_co_pdo_entry){0x6077, 0, 16};
    t.e[2] = (msid_co_pdo_entry){0x606C, 0, 32};
    assert_int_equal(msid_co_eds_check_pdo(&eds, &t, err, sizeof err), 0);
    t.e[2].bits = 16;
    assert_int_equal(msid_co_eds_check_pdo(&eds, &t, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(err, "TPDO1 maps 0x606C:00 (Velocity actual value) with 16 bits: it is INTEGER32, 32 bits"));
    t.e[2] = (msid_co_pdo_entry){0x6076, 0, 32};
    assert_int_equal(msid_co_eds_check_pdo(&eds, &t, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(err, "TPDO1 maps 0x6076:00 (Motor rated torque), which is not PDO-mappable"));
    t.e[2] = (msid_co_pdo_entry){0x6099, 0, 32};
    assert_int_equal(msid_co_eds_check_pdo(&eds, &t, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(err, "TPDO1 maps 0x6099:00 is not in "));
    msid_co_pdo_cfg r = {.tx = 0, .num = 1, .trans_type = 1, .n = 2};
    r.e[0] = (msid_co_pdo_entry){0x6040, 0, 16};
    r.e[1] = (msid_co_pdo_entry){0x6071, 0, 16};
    assert_int_equal(msid_co_eds_check_pdo(&eds, &r, err, sizeof err), 0);
    r.e[1] = (msid_co_pdo_entry){0x6077, 0, 16};  /* torque actual as a target */
    assert_int_equal(msid_co_eds_check_pdo(&eds, &r, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_non_null(strstr(err, "RPDO1 maps 0x6077:00 (Torque actual value), which is read only: it cannot be a target msid writes"));
}

static void test_forms(void **state)
{
    (void)state;
    msid_co_eds eds;
    /* a compact array, a DCF's ParameterValue over the default, a variable without ObjectType, case */
    static const char text[] =
        "[DeviceInfo]\nVendorName=x\n"
        "[1003]\nParameterName=Errors\nObjectType=0x8\nDataType=0x0007\nAccessType=ro\nCompactSubObj=3\n"
        "[2100]\nParameterName=Gain\nDataType=0x0008\nAccessType=RW\nDefaultValue=1.5\nParameterValue=2.5\n"
        "[2101]\nParameterName=Rec\nObjectType=0x9\nSubNumber=2\n"
        "[2101Sub0]\nParameterName=n\nDataType=0x0005\nAccessType=const\nDefaultValue=1\n"
        "[2101sub1A]\nParameterName=x\nDataType=0x0004\nAccessType=rww\nPDOMapping=1\n";
    assert_int_equal(load_text(text, &eds), 0);
    assert_int_equal(eds.n, 4 + 1 + 2);
    assert_string_equal(msid_co_eds_find(&eds, 0x1003, 0)->value, "3");
    assert_int_equal(msid_co_eds_find(&eds, 0x1003, 3)->type, 0x0007);
    assert_string_equal(msid_co_eds_find(&eds, 0x2100, 0)->value, "2.5");
    assert_int_equal(msid_co_eds_find(&eds, 0x2100, 0)->access, MSID_CO_RW);
    assert_int_equal(msid_co_eds_find(&eds, 0x2101, 0)->access, MSID_CO_CONST);
    assert_int_equal(msid_co_eds_find(&eds, 0x2101, 0x1A)->access, MSID_CO_RWW);
    /* refusals, each with its line */
    static const struct { const char *text, *msg; int rc; } bad[] = {
        {"[2000]\nDataType=0x7\nAccessType=rx\n", "line 1: [2000] AccessType 'rx' is none of ro, wo, rw, rwr, rww, const", -MSID_DAQ_E_FORMAT},
        {"\n[2000]\nAccessType=ro\n", "line 2: [2000] has no datatype", -MSID_DAQ_E_FORMAT},
        {"[2000]\nObjectType=0x5\n", "line 1: [2000] ObjectType 0x5 is none of", -MSID_DAQ_E_FORMAT},
        {"[2000]\nDataType=0x7\nAccessType=ro\n[2000]\nDataType=0x7\nAccessType=ro\n", "line 4: 0x2000:00 is described twice (also line 1)", -MSID_DAQ_E_FORMAT},
        {"[2000\n", "line 1: unclosed section name", -MSID_DAQ_E_FORMAT},
        {"[2000]\nDataType=seven\nAccessType=ro\n", "line 1: [2000] datatype 'seven' is not a number", -MSID_DAQ_E_FORMAT},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const int rc = load_text(bad[i].text, &eds);
        if (rc != bad[i].rc || !strstr(eds.err, bad[i].msg)) fail_msg("case %zu: %d '%s', expected '%s'", i, rc, eds.err, bad[i].msg);
    }
    assert_int_equal(msid_co_eds_load("/nonexistent/x.eds", &eds, MEM, 256), -MSID_DAQ_E_IO);
    assert_non_null(strstr(eds.err, "/nonexistent/x.eds: cannot be read"));
    assert_int_equal(msid_co_eds_load(MSID_SOURCE_DIR "/tests/vcan/in_vm/data/drive402.eds", &eds, MEM, 10), -MSID_DAQ_E_RANGE);
    assert_non_null(strstr(eds.err, "entries: room for 10"));
    assert_int_equal(msid_co_type_bits(0x0004), 32);
    assert_int_equal(msid_co_type_bits(0x0009), 0);
    assert_string_equal(msid_co_type_name(0x001B), "UNSIGNED64");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_drive_file),
        cmocka_unit_test(test_checks),
        cmocka_unit_test(test_forms),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
