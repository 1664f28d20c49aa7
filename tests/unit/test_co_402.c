/* CiA 402 drive profile (daq/src/msid_co_402.c): every statusword against CiA 402's state table written
   here, the controlword of each step, and the way to "operation enabled" and back over SDO against the test
   node with a drive's state machine behind its controlword (quick stop option codes that end in "switch on
   disabled" and that stay in "quick stop active", a fault that clears and one that does not, a drive that
   never follows); modes of operation displayed and refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "msid_daq/msid_co_402.h"
#include "co_test_node.h"

#define NODE 7u

/* CiA 402's statusword table (mask, value, state) */
static const struct { uint16_t mask, value; msid_co402_state state; } TABLE[] = {
    {0x004F, 0x0000, MSID_CO402_NOT_READY},        {0x004F, 0x0040, MSID_CO402_SWITCH_ON_DISABLED},
    {0x006F, 0x0021, MSID_CO402_READY},            {0x006F, 0x0023, MSID_CO402_SWITCHED_ON},
    {0x006F, 0x0027, MSID_CO402_OPERATION_ENABLED}, {0x006F, 0x0007, MSID_CO402_QUICK_STOP_ACTIVE},
    {0x004F, 0x000F, MSID_CO402_FAULT_REACTION},   {0x004F, 0x0008, MSID_CO402_FAULT},
};
#define N_TABLE (sizeof TABLE / sizeof TABLE[0])

static void test_statusword_table(void **state)
{
    (void)state;
    unsigned seen[N_TABLE] = {0}, none = 0;
    for (uint32_t sw = 0; sw <= 0xFFFFu; sw++) {
        int match = -1;
        for (size_t i = 0; i < N_TABLE; i++)
            if ((sw & TABLE[i].mask) == TABLE[i].value) {
                if (match >= 0) fail_msg("statusword 0x%04X matches two rows", (unsigned)sw);
                match = (int)i;
            }
        const msid_co402_state got = msid_co402_decode((uint16_t)sw);
        if (match < 0) {
            none++;
            if (got != MSID_CO402_FAULT) fail_msg("0x%04X is no state but decodes to %s", (unsigned)sw, msid_co402_state_name(got));
            continue;
        }
        seen[match]++;
        if (got != TABLE[match].state)
            fail_msg("0x%04X: %s, CiA 402 says %s", (unsigned)sw, msid_co402_state_name(got), msid_co402_state_name(TABLE[match].state));
    }
    for (size_t i = 0; i < N_TABLE; i++) assert_int_equal(seen[i], 0x10000u >> (TABLE[i].mask == 0x4F ? 5 : 6));
    assert_int_not_equal(none, 0);
    assert_string_equal(msid_co402_state_name(MSID_CO402_SWITCH_ON_DISABLED), "switch on disabled");
    assert_string_equal(msid_co402_state_name(MSID_CO402_QUICK_STOP_ACTIVE), "quick stop active");
}

static void test_steps(void **state)
{
    (void)state;
    static const struct { msid_co402_state from; int up; uint16_t last; int reset; msid_co402_action a; uint16_t cw; } S[] = {
        {MSID_CO402_SWITCH_ON_DISABLED, 1, 0, 0, MSID_CO402_WRITE, 0x0006},
        {MSID_CO402_READY, 1, 0, 0, MSID_CO402_WRITE, 0x0007},
        {MSID_CO402_SWITCHED_ON, 1, 0, 0, MSID_CO402_WRITE, 0x000F},
        {MSID_CO402_OPERATION_ENABLED, 1, 0, 0, MSID_CO402_THERE, 0},
        {MSID_CO402_QUICK_STOP_ACTIVE, 1, 0, 0, MSID_CO402_WRITE, 0x0000},
        {MSID_CO402_FAULT, 1, 0, 0, MSID_CO402_STUCK, 0},
        {MSID_CO402_FAULT, 1, 0x0000, 1, MSID_CO402_WRITE, 0x0080},
        {MSID_CO402_FAULT, 1, 0x0080, 1, MSID_CO402_WRITE, 0x0000},
        {MSID_CO402_NOT_READY, 1, 0, 1, MSID_CO402_WAIT, 0},
        {MSID_CO402_FAULT_REACTION, 1, 0, 1, MSID_CO402_WAIT, 0},
        {MSID_CO402_OPERATION_ENABLED, 0, 0x000F, 0, MSID_CO402_WRITE, 0x0002},
        {MSID_CO402_QUICK_STOP_ACTIVE, 0, 0x0002, 0, MSID_CO402_WRITE, 0x0000},
        {MSID_CO402_SWITCHED_ON, 0, 0, 0, MSID_CO402_WRITE, 0x0000},
        {MSID_CO402_READY, 0, 0, 0, MSID_CO402_WRITE, 0x0000},
        {MSID_CO402_SWITCH_ON_DISABLED, 0, 0, 0, MSID_CO402_THERE, 0},
        {MSID_CO402_FAULT, 0, 0, 0, MSID_CO402_THERE, 0},
        {MSID_CO402_FAULT_REACTION, 0, 0, 0, MSID_CO402_WAIT, 0},
    };
    for (size_t i = 0; i < sizeof S / sizeof S[0]; i++) {
        uint16_t cw = 0xFFFF;
        const msid_co402_action a = msid_co402_step(S[i].from, S[i].up, S[i].last, S[i].reset, &cw);
        if (a != S[i].a || (a == MSID_CO402_WRITE && cw != S[i].cw))
            fail_msg("row %zu (%s, %s): action %d cw 0x%04X", i, msid_co402_state_name(S[i].from), S[i].up ? "up" : "out",
                     (int)a, (unsigned)cw);
    }
}

/* ---- a drive behind the test node's controlword ---- */

typedef struct drive_sim {
    msid_co402_state st;
    int qs_stays;      /* quick stop option code 5..8: stays in quick stop active */
    int fault_clears;  /* a fault reset clears the fault */
    int frozen;        /* follows no command */
    uint16_t last_cw;
    msid_co402_state path[32];
    int n_path;
} drive_sim;

static const uint16_t SW_OF[] = {0x0000, 0x0040, 0x0021, 0x0023, 0x0027, 0x0007, 0x000F, 0x0008};

/* CiA 402 figure 11's transitions on a controlword write */
static msid_co402_state transition(const drive_sim *d, uint16_t cw)
{
    const int shutdown = (cw & 0x87u) == 0x06u, switch_on = (cw & 0x8Fu) == 0x07u, enable = (cw & 0x8Fu) == 0x0Fu;
    const int disable_voltage = (cw & 0x82u) == 0x00u, quick_stop = (cw & 0x86u) == 0x02u;
    switch (d->st) {
    case MSID_CO402_SWITCH_ON_DISABLED: return shutdown ? MSID_CO402_READY : d->st;
    case MSID_CO402_READY:
        return switch_on ? MSID_CO402_SWITCHED_ON : (disable_voltage || quick_stop) ? MSID_CO402_SWITCH_ON_DISABLED : d->st;
    case MSID_CO402_SWITCHED_ON:
        return enable ? MSID_CO402_OPERATION_ENABLED : shutdown ? MSID_CO402_READY
               : (disable_voltage || quick_stop) ? MSID_CO402_SWITCH_ON_DISABLED : d->st;
    case MSID_CO402_OPERATION_ENABLED:
        return quick_stop ? (d->qs_stays ? MSID_CO402_QUICK_STOP_ACTIVE : MSID_CO402_SWITCH_ON_DISABLED)
               : disable_voltage ? MSID_CO402_SWITCH_ON_DISABLED : switch_on ? MSID_CO402_SWITCHED_ON
               : shutdown ? MSID_CO402_READY : d->st;
    case MSID_CO402_QUICK_STOP_ACTIVE: return disable_voltage ? MSID_CO402_SWITCH_ON_DISABLED : d->st;
    case MSID_CO402_FAULT:
        return (cw & 0x80u) && !(d->last_cw & 0x80u) && d->fault_clears ? MSID_CO402_SWITCH_ON_DISABLED : d->st;
    default: return d->st;
    }
}

static void set_sw(test_node *t, const drive_sim *d)
{
    t->od[tn_find(t, 0x6041, 0) - t->od].value = SW_OF[d->st] | 0x0200u; /* bit 9: remote */
}

static void on_write(test_node *t, uint16_t index, uint8_t sub, uint32_t value)
{
    drive_sim *d = t->user;
    (void)sub;
    if (index == 0x6040 && !d->frozen) {
        d->st = transition(d, (uint16_t)value);
        d->last_cw = (uint16_t)value;
        if (d->n_path < 32) d->path[d->n_path++] = d->st;
        set_sw(t, d);
    }
    if (index == 0x6060 && !d->frozen) t->od[tn_find(t, 0x6061, 0) - t->od].value = value;
}

static void bench(test_node *t, drive_sim *d, msid_co_sdo *s, msid_co402_state start)
{
    memset(t, 0, sizeof *t);
    t->id = NODE;
    tn_add(t, 0x6040, 0, 2, TN_RW, 1, 0);
    tn_add(t, 0x6041, 0, 2, TN_RO, 1, 0);
    tn_add(t, 0x6060, 0, 1, TN_RW, 0, 0);
    tn_add(t, 0x6061, 0, 1, TN_RO, 0, 0);
    d->st = start;
    d->n_path = 0;
    d->last_cw = 0;
    t->user = d;
    t->on_write = on_write;
    set_sw(t, d);
    const msid_co_io io = tn_io(t);
    assert_int_equal(msid_co_sdo_init(s, &io, NODE, 50), 0);
}

static void test_goto(void **state)
{
    (void)state;
    test_node t;
    msid_co_sdo s;
    msid_co402_state fin;
    for (int qs_stays = 0; qs_stays < 2; qs_stays++) {
        drive_sim d = {.qs_stays = qs_stays};
        bench(&t, &d, &s, MSID_CO402_SWITCH_ON_DISABLED);
        assert_int_equal(msid_co402_goto(&s, 1, 0, 1000, &fin), 0);
        assert_int_equal(fin, MSID_CO402_OPERATION_ENABLED);
        assert_int_equal(d.n_path, 3);  /* ready, switched on, operation enabled */
        assert_int_equal(d.path[0], MSID_CO402_READY);
        assert_int_equal(d.path[1], MSID_CO402_SWITCHED_ON);
        /* and out: quick stop first, then (when the drive stays there) disable voltage */
        assert_int_equal(msid_co402_goto(&s, 0, 0, 1000, &fin), 0);
        assert_int_equal(fin, MSID_CO402_SWITCH_ON_DISABLED);
        assert_int_equal(t.log[3].index, 0x6040);
        assert_int_equal(t.log[3].value, 0x0002);
        assert_int_equal(t.n_log, qs_stays ? 5 : 4);
        if (qs_stays) assert_int_equal(t.log[4].value, 0x0000);
    }
    /* a fault that clears on the reset's rising edge */
    drive_sim d = {.fault_clears = 1};
    bench(&t, &d, &s, MSID_CO402_FAULT);
    d.last_cw = 0x0080;  /* bit 7 left high: the first write must lower it */
    assert_int_equal(msid_co402_goto(&s, 1, 1, 1000, &fin), 0);
    assert_int_equal(fin, MSID_CO402_OPERATION_ENABLED);
    /* a fault that is not to be reset, and one that stays */
    d = (drive_sim){.fault_clears = 0};
    bench(&t, &d, &s, MSID_CO402_FAULT);
    assert_int_equal(msid_co402_goto(&s, 1, 0, 1000, &fin), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(s.err, "in fault"));
    assert_int_equal(t.n_log, 0);
    assert_int_equal(msid_co402_goto(&s, 1, 1, 1000, &fin), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(s.err, "stays in \"fault\""));
    assert_int_equal(t.n_log, 16);
    /* a drive that follows nothing: the deadline */
    d = (drive_sim){.frozen = 1};
    bench(&t, &d, &s, MSID_CO402_NOT_READY);
    assert_int_equal(msid_co402_goto(&s, 1, 0, 200, &fin), -MSID_DAQ_E_DEVICE);
    assert_non_null(strstr(s.err, "stays in \"not ready to switch on\""));
    assert_true(t.now >= 200 && t.now < 210);
    /* a drive already out is left alone */
    d = (drive_sim){0};
    bench(&t, &d, &s, MSID_CO402_SWITCH_ON_DISABLED);
    assert_int_equal(msid_co402_goto(&s, 0, 0, 1000, &fin), 0);
    assert_int_equal(t.n_log, 0);
}

static void test_modes(void **state)
{
    (void)state;
    test_node t;
    msid_co_sdo s;
    drive_sim d = {0};
    bench(&t, &d, &s, MSID_CO402_SWITCH_ON_DISABLED);
    assert_int_equal(msid_co402_set_mode(&s, MSID_CO402_MODE_CST, 100), 0);
    assert_int_equal(tn_value(&t, 0x6060, 0), 10);
    assert_int_equal(msid_co402_set_mode(&s, MSID_CO402_MODE_CSV, 100), 0);
    assert_int_equal(tn_value(&t, 0x6061, 0), 9);
    d.frozen = 1;
    assert_int_equal(msid_co402_set_mode(&s, MSID_CO402_MODE_CSP, 100), -MSID_DAQ_E_DEVICE);
    assert_string_equal(s.err, "node 7 displays mode 9 (cyclic synchronous velocity (CSV)) in 0x6061 after cyclic "
                               "synchronous position (CSP) was written to 0x6060");
    assert_string_equal(msid_co402_mode_name(10), "cyclic synchronous torque (CST)");
    assert_string_equal(msid_co402_mode_name(-1), "unknown mode");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_statusword_table),
        cmocka_unit_test(test_steps),
        cmocka_unit_test(test_goto),
        cmocka_unit_test(test_modes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
