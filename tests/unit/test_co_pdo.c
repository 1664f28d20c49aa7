/* CANopen PDO configuration by SDO (daq/src/msid_co_pdo.c) against the test node of co_test_node.h: the
   writes in CiA 301's order and the node's own dictionary holding the mapping afterwards; what the node
   held saved and put back; a node that refuses a mapping, put back as it was; every refusal made before
   anything is written; the communication cycle period. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "msid_daq/msid_co_pdo.h"
#include "co_test_node.h"

#define NODE 5u

/* a CiA 402 drive's objects that a PDO maps, and its PDO records as they come from the factory */
static void drive(test_node *t)
{
    memset(t, 0, sizeof *t);
    t->id = NODE;
    tn_add(t, 0x1006, 0, 4, TN_RW, 0, 0);
    tn_add(t, 0x6040, 0, 2, TN_RW, 1, 0);     /* controlword */
    tn_add(t, 0x6041, 0, 2, TN_RO, 1, 0x0250); /* statusword */
    tn_add(t, 0x6071, 0, 2, TN_RW, 1, 0);     /* target torque */
    tn_add(t, 0x6074, 0, 2, TN_RO, 1, 0);     /* torque demand */
    tn_add(t, 0x6077, 0, 2, TN_RO, 1, 0);     /* torque actual */
    tn_add(t, 0x606C, 0, 4, TN_RO, 1, 0);     /* velocity actual */
    tn_add(t, 0x6064, 0, 4, TN_RO, 1, 0);     /* position actual */
    tn_add(t, 0x6076, 0, 4, TN_RW, 0, 1000);  /* rated torque: not mappable */
    tn_add_pdo(t, 1, 1, 0x40000185u, 1);
    tn_add_pdo(t, 0, 1, 0x205u, 0);
    /* the factory's TPDO1: the statusword */
    t->od[tn_find(t, 0x1A00, 1) - t->od].value = 0x60410010u;
    t->od[tn_find(t, 0x1A00, 0) - t->od].value = 1;
}

/* a fresh drive and a client of it; with saved, TPDO1 as the drive holds it read first (writing nothing) */
static void fresh(test_node *t, msid_co_sdo *s, msid_co_pdo_cfg *saved)
{
    drive(t);
    const msid_co_io io = tn_io(t);
    assert_int_equal(msid_co_sdo_init(s, &io, NODE, 50), 0);
    if (!saved) return;
    assert_int_equal(msid_co_pdo_save(s, 1, 1, saved), 0);
    assert_int_equal(t->n_log, 0);
}

static msid_co_pdo_cfg tpdo_cst(void)
{
    msid_co_pdo_cfg c = {.tx = 1, .num = 1, .trans_type = MSID_CO_PDO_SYNC_EVERY, .inhibit_100us = 0, .n = 3};
    c.e[0] = (msid_co_pdo_entry){0x6074, 0, 16};
    c.e[1] = (msid_co_pdo_entry){0x6077, 0, 16};
    c.e[2] = (msid_co_pdo_entry){0x606C, 0, 32};
    return c;
}

static void expect_log(const test_node *t, const tn_write *want, int n)
{
    if (t->n_log != n) fail_msg("%d writes, expected %d", t->n_log, n);
    for (int i = 0; i < n; i++)
        if (t->log[i].index != want[i].index || t->log[i].sub != want[i].sub || t->log[i].value != want[i].value)
            fail_msg("write %d: 0x%04X:%02X = 0x%X, expected 0x%04X:%02X = 0x%X", i, (unsigned)t->log[i].index,
                     (unsigned)t->log[i].sub, (unsigned)t->log[i].value, (unsigned)want[i].index, (unsigned)want[i].sub,
                     (unsigned)want[i].value);
}

/* the node's records equal those of a fresh drive, entry by entry (a mapping's entries beyond its count
   carry nothing and are not compared) */
static void expect_factory(test_node *t)
{
    test_node fresh;
    drive(&fresh);
    for (int i = 0; i < fresh.n; i++) {
        const tn_entry *e = &fresh.od[i];
        const int is_map = (e->index >= 0x1600u && e->index <= 0x17FFu) || (e->index >= 0x1A00u && e->index <= 0x1BFFu);
        if (is_map && e->sub > tn_value(&fresh, e->index, 0)) continue;
        if (t->od[i].value != e->value)
            fail_msg("0x%04X:%02X holds 0x%X, the factory's 0x%X", (unsigned)t->od[i].index, (unsigned)t->od[i].sub,
                     (unsigned)t->od[i].value, (unsigned)e->value);
    }
}

static void test_tpdo_order(void **state)
{
    (void)state;
    test_node t;
    msid_co_sdo s;
    msid_co_pdo_cfg saved;
    fresh(&t, &s, &saved);
    assert_int_equal(saved.cob_id, 0x40000185u);
    assert_int_equal(saved.trans_type, 255);
    assert_int_equal(saved.n, 1);
    assert_int_equal(msid_co_pdo_map_value(&saved.e[0]), 0x60410010u);
    const msid_co_pdo_cfg c = tpdo_cst();
    assert_int_equal(msid_co_pdo_configure(&s, &c, &saved), 0);
    const tn_write want[] = {
        {0x1800, 1, 0xC0000185u}, {0x1800, 2, 1},           {0x1800, 3, 0},           {0x1A00, 0, 0},
        {0x1A00, 1, 0x60740010u}, {0x1A00, 2, 0x60770010u}, {0x1A00, 3, 0x606C0020u}, {0x1A00, 0, 3},
        {0x1800, 1, 0x40000185u},
    };
    expect_log(&t, want, (int)(sizeof want / sizeof want[0]));
    /* the node's own dictionary holds the mapping */
    assert_int_equal(tn_value(&t, 0x1A00, 0), 3);
    assert_int_equal(tn_value(&t, 0x1A00, 3), 0x606C0020u);
    assert_int_equal(tn_value(&t, 0x1800, 1), 0x40000185u);
    msid_co_pdo_cfg back;
    assert_int_equal(msid_co_pdo_save(&s, 1, 1, &back), 0);
    assert_int_equal(back.n, 3);
    assert_memory_equal(back.e, c.e, sizeof c.e[0] * 3);
    /* and put back */
    assert_int_equal(msid_co_pdo_restore(&s, &saved), 0);
    expect_factory(&t);
}

static void test_rpdo(void **state)
{
    (void)state;
    test_node t;
    msid_co_sdo s;
    fresh(&t, &s, NULL);
    msid_co_pdo_cfg c = {.tx = 0, .num = 1, .trans_type = 1, .n = 2};
    c.e[0] = (msid_co_pdo_entry){0x6040, 0, 16};
    c.e[1] = (msid_co_pdo_entry){0x6071, 0, 16};
    assert_int_equal(msid_co_pdo_configure(&s, &c, NULL), 0);
    const tn_write want[] = {
        {0x1400, 1, 0x80000205u}, {0x1400, 2, 1}, {0x1600, 0, 0}, {0x1600, 1, 0x60400010u},
        {0x1600, 2, 0x60710010u}, {0x1600, 0, 2}, {0x1400, 1, 0x205u},
    };
    expect_log(&t, want, (int)(sizeof want / sizeof want[0]));  /* no inhibit time on an RPDO */
}

/* a node that refuses a mapping: named, and the PDO put back as it was */
static void test_refused_by_node(void **state)
{
    (void)state;
    test_node t;
    msid_co_sdo s;
    msid_co_pdo_cfg saved;
    fresh(&t, &s, &saved);
    msid_co_pdo_cfg c = tpdo_cst();
    c.n = 2;
    c.e[1] = (msid_co_pdo_entry){0x6076, 0, 32};  /* rated torque: not mappable */
    assert_int_equal(msid_co_pdo_configure(&s, &c, &saved), -MSID_DAQ_E_DEVICE);
    assert_int_equal(s.abort_code, 0x06040041u);
    if (!strstr(s.err, "TPDO1 of node 5") || !strstr(s.err, "0x1A00:02") || !strstr(s.err, "object cannot be mapped to the PDO"))
        fail_msg("err: %s", s.err);
    expect_factory(&t);
    /* an object the node does not have */
    c.e[1] = (msid_co_pdo_entry){0x2345, 0, 16};
    assert_int_equal(msid_co_pdo_configure(&s, &c, &saved), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(s.err, "object does not exist in the object dictionary"));
    expect_factory(&t);
}

/* every refusal before anything is written */
static void test_refused_before_writing(void **state)
{
    (void)state;
    static const struct { int what; const char *msg; } cases[] = {
        {0, "TPDO1 maps 72 bits (9 bytes): a PDO carries at most 8 bytes"},
        {1, "TPDO1 maps 9 entries: at most 8 fit in a PDO of 8 bytes"},
        {2, "TPDO1 entry 1 (0x6074:00) is 0 bits long (1..64)"},
        {3, "TPDO1: COB-ID 0x705 is not an 11-bit identifier a PDO may use"},
        {4, "TPDO1: COB-ID 0x1000 is not an 11-bit identifier a PDO may use"},
        {5, "RPDO1: transmission type 252 is not one an RPDO takes (0..240, 254, 255)"},
        {6, "TPDO5 has no COB-ID of the predefined connection set (PDOs 1..4): give one"},
        {7, "TPDO number 0 is out of range (1..512)"},
        {8, "TPDO1: transmission type 241 is not one a TPDO takes (0..240, 252, 253, 254, 255)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        test_node t;
        msid_co_sdo s;
        fresh(&t, &s, NULL);
        msid_co_pdo_cfg c = tpdo_cst();
        switch (cases[i].what) {
        case 0: c.e[2].bits = 40; break;
        case 1: c.n = 9; break;
        case 2: c.e[0].bits = 0; break;
        case 3: c.cob_id = 0x705; break;
        case 4: c.cob_id = 0x1000; break;
        case 5: c.tx = 0, c.trans_type = 252; break;
        case 6: c.num = 5; break;
        case 7: c.num = 0; break;
        case 8: c.trans_type = 241; break;
        }
        assert_int_equal(msid_co_pdo_configure(&s, &c, NULL), -MSID_DAQ_E_ARG);
        if (strncmp(s.err, cases[i].msg, strlen(cases[i].msg))) fail_msg("err '%s', expected '%s'", s.err, cases[i].msg);
        assert_int_equal(t.n_log, 0);
    }
    char err[200];
    msid_co_pdo_cfg c = tpdo_cst();
    assert_int_equal(msid_co_pdo_check(&c, 0, err, sizeof err), -MSID_DAQ_E_ARG);
    assert_string_equal(err, "node id 0 is out of range (1..127)");
    assert_int_equal(msid_co_pdo_check(&c, 127, err, sizeof err), 0);
    c.cob_id = 0x281;  /* another node's default identifier is a PDO's to use */
    assert_int_equal(msid_co_pdo_check(&c, 5, err, sizeof err), 0);
}

static void test_cycle_period(void **state)
{
    (void)state;
    test_node t;
    msid_co_sdo s;
    fresh(&t, &s, NULL);
    uint32_t us = 1;
    assert_int_equal(msid_co_cycle_write(&s, 1000), 0);
    assert_int_equal(msid_co_cycle_read(&s, &us), 0);
    assert_int_equal(us, 1000);
    assert_int_equal(tn_value(&t, 0x1006, 0), 1000);
    /* a node that never answers */
    t.silent = 1;
    assert_int_equal(msid_co_cycle_read(&s, &us), -MSID_DAQ_E_TIMEOUT);
    assert_non_null(strstr(s.err, "no response within 50 ms"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tpdo_order),
        cmocka_unit_test(test_rpdo),
        cmocka_unit_test(test_refused_by_node),
        cmocka_unit_test(test_refused_before_writing),
        cmocka_unit_test(test_cycle_period),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
