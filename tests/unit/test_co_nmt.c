/* CANopen network management and emergencies (daq/src/msid_co_nmt.c, msid_co_emcy.c) on frames in memory:
   NMT command frames byte for byte, SYNC with and without a counter, the heartbeat consumer's start on the
   first heartbeat, its loss exactly one millisecond after the consumer time, its recovery and counts;
   EMCY decoding, the names of exact codes and of their classes, and the line a user reads. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "msid_daq/msid_co_emcy.h"
#include "msid_daq/msid_co_nmt.h"

typedef struct bus {
    msid_can_frame sent[8];
    int n;
} bus;

static int bus_send(void *ctx, const msid_can_frame *f)
{
    bus *b = ctx;
    if (b->n < 8) b->sent[b->n++] = *f;
    return 0;
}

static int bus_recv(void *ctx, msid_can_frame *f, int timeout_ms)
{
    (void)ctx, (void)f, (void)timeout_ms;
    return -MSID_DAQ_E_TIMEOUT;
}

static msid_can_frame frame(uint32_t id, unsigned len, const uint8_t *data)
{
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = id;
    f.len = (uint8_t)len;
    if (len) memcpy(f.data, data, len);
    return f;
}

static void test_nmt_frames(void **state)
{
    (void)state;
    bus b = {0};
    const msid_co_io io = {&b, bus_send, bus_recv, NULL, NULL};
    static const struct { msid_co_nmt_cmd cmd; uint8_t cs; const char *name; } cmds[] = {
        {MSID_CO_NMT_START, 0x01, "start"},
        {MSID_CO_NMT_STOP, 0x02, "stop"},
        {MSID_CO_NMT_PREOPERATIONAL, 0x80, "enter pre-operational"},
        {MSID_CO_NMT_RESET_NODE, 0x81, "reset node"},
        {MSID_CO_NMT_RESET_COMMUNICATION, 0x82, "reset communication"},
    };
    for (int i = 0; i < 5; i++) {
        b.n = 0;
        assert_int_equal(msid_co_nmt_send(&io, cmds[i].cmd, 42), 0);
        assert_int_equal(b.n, 1);
        assert_int_equal(b.sent[0].id, 0x000);
        assert_int_equal(b.sent[0].len, 2);
        assert_int_equal(b.sent[0].data[0], cmds[i].cs);
        assert_int_equal(b.sent[0].data[1], 42);
        assert_string_equal(msid_co_nmt_cmd_name(cmds[i].cs), cmds[i].name);
    }
    b.n = 0;
    assert_int_equal(msid_co_nmt_send(&io, MSID_CO_NMT_STOP, 0), 0);  /* every node */
    assert_int_equal(b.sent[0].data[1], 0);
    assert_int_equal(msid_co_nmt_send(&io, MSID_CO_NMT_STOP, 128), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_co_nmt_send(&io, (msid_co_nmt_cmd)0x03, 1), -MSID_DAQ_E_ARG);
    assert_int_equal(b.n, 1);  /* nothing sent for either */
    assert_string_equal(msid_co_nmt_cmd_name(0x03), "unknown command");
}

static void test_sync_frames(void **state)
{
    (void)state;
    msid_can_frame f;
    assert_int_equal(msid_co_sync_frame(&f, 0), 0);
    assert_int_equal(f.id, 0x080);
    assert_int_equal(f.len, 0);
    assert_int_equal(msid_co_sync_frame(&f, 240), 0);
    assert_int_equal(f.len, 1);
    assert_int_equal(f.data[0], 240);
    assert_int_equal(msid_co_sync_frame(&f, 241), -MSID_DAQ_E_ARG);
}

static void test_states(void **state)
{
    (void)state;
    assert_string_equal(msid_co_state_name(0x00), "boot-up");
    assert_string_equal(msid_co_state_name(0x04), "stopped");
    assert_string_equal(msid_co_state_name(0x05), "operational");
    assert_string_equal(msid_co_state_name(0x7F), "pre-operational");
    assert_string_equal(msid_co_state_name(0x85), "operational");  /* bit 7 (node guarding's toggle) ignored */
    assert_string_equal(msid_co_state_name(0x06), "unknown state");
    assert_string_equal(msid_co_state_name(MSID_CO_STATE_UNKNOWN), "no heartbeat yet");
}

static void test_heartbeat_consumer(void **state)
{
    (void)state;
    msid_co_hb hb;
    assert_int_equal(msid_co_hb_entry(5, 300), 0x0005012Cu);
    assert_int_equal(msid_co_hb_init(&hb, 0, 100), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_co_hb_init(&hb, 128, 100), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_co_hb_init(&hb, 5, 0), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_co_hb_init(&hb, 5, 65536), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_co_hb_init(&hb, 5, 100), 0);
    /* before the first heartbeat nothing is monitored, however long it takes */
    assert_int_equal(msid_co_hb_check(&hb, 0), MSID_CO_HB_WAITING);
    assert_int_equal(msid_co_hb_check(&hb, 100000), MSID_CO_HB_WAITING);
    assert_int_equal(hb.state, MSID_CO_STATE_UNKNOWN);
    const uint8_t boot = 0x00, pre = 0x7F, op = 0x05;
    msid_can_frame f = frame(0x706, 1, &op);  /* another node's */
    assert_int_equal(msid_co_hb_frame(&hb, &f, 1000), 0);
    f = frame(0x705, 1, &boot);
    assert_int_equal(msid_co_hb_frame(&hb, &f, 1000), 1);
    assert_int_equal(hb.bootups, 1);
    f = frame(0x705, 1, &pre);
    assert_int_equal(msid_co_hb_frame(&hb, &f, 1050), 1);
    assert_int_equal(hb.state, MSID_CO_STATE_PREOPERATIONAL);
    /* the consumer time is inclusive: lost one millisecond after it */
    assert_int_equal(msid_co_hb_check(&hb, 1150), MSID_CO_HB_ALIVE);
    assert_int_equal(msid_co_hb_check(&hb, 1151), MSID_CO_HB_LOST);
    assert_int_equal(msid_co_hb_check(&hb, 1300), MSID_CO_HB_LOST);
    assert_int_equal(hb.losses, 1);  /* counted once */
    f = frame(0x705, 1, &op);
    assert_int_equal(msid_co_hb_frame(&hb, &f, 1400), 1);
    assert_int_equal(msid_co_hb_check(&hb, 1401), MSID_CO_HB_ALIVE);
    assert_int_equal(hb.state, MSID_CO_STATE_OPERATIONAL);
    assert_int_equal(msid_co_hb_check(&hb, 1501), MSID_CO_HB_LOST);
    assert_int_equal(hb.losses, 2);
    /* a frame of its COB-ID that is no heartbeat is counted and changes nothing */
    const uint8_t two[2] = {5, 5};
    f = frame(0x705, 2, two);
    assert_int_equal(msid_co_hb_frame(&hb, &f, 1600), -MSID_DAQ_E_PROTOCOL);
    f = frame(0x705 | MSID_CAN_RTR_FLAG, 0, NULL);  /* node guarding's request */
    assert_int_equal(msid_co_hb_frame(&hb, &f, 1600), 0);
    assert_int_equal(hb.malformed, 1);
    assert_int_equal(hb.heartbeats, 3);
    assert_int_equal(msid_co_hb_check(&hb, 1600), MSID_CO_HB_LOST);
}

static void test_emcy(void **state)
{
    (void)state;
    const uint8_t d[8] = {0x30, 0x81, 0x11, 0x01, 0x02, 0x03, 0x04, 0x05};
    msid_co_emcy e;
    msid_can_frame f = frame(0x085, 8, d);
    assert_int_equal(msid_co_emcy_decode(&f, 5, &e), 1);
    assert_int_equal(e.node, 5);
    assert_int_equal(e.code, 0x8130);
    assert_int_equal(e.reg, 0x11);
    assert_memory_equal(e.mfr, "\x01\x02\x03\x04\x05", 5);
    char line[200];
    msid_co_emcy_describe(&e, line, sizeof line);
    assert_string_equal(line, "node 5 EMCY 0x8130 (life guard error or heartbeat error), error register 0x11 (generic, "
                              "communication), manufacturer bytes 01 02 03 04 05");
    assert_int_equal(msid_co_emcy_decode(&f, 6, &e), 0);
    f = frame(0x080, 0, NULL);  /* SYNC shares the function code */
    assert_int_equal(msid_co_emcy_decode(&f, 5, &e), 0);
    f = frame(0x085, 3, d);
    assert_int_equal(msid_co_emcy_decode(&f, 5, &e), -MSID_DAQ_E_PROTOCOL);
    e.reg = 0;
    msid_co_emcy_describe(&e, line, sizeof line);
    assert_non_null(strstr(line, "error register 0x00 (none)"));
    /* exact codes, then the class of the high byte, then of the high nibble */
    static const struct { uint16_t code; const char *name; } names[] = {
        {0x0000, "error reset or no error"},
        {0x1000, "generic error"},
        {0x8110, "CAN overrun (objects lost)"},
        {0x8250, "RPDO timeout"},
        {0x8611, "following error"},
        {0x3210, "DC link over-voltage"},
        {0x3211, "voltage inside the device"},
        {0x8199, "communication"},
        {0x8612, "monitoring"},
        {0x5530, "device hardware"},
        {0x6320, "data set"},
        {0xFF01, "device specific"},
        {0xA000, "unknown error code"},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) assert_string_equal(msid_co_emcy_name(names[i].code), names[i].name);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_nmt_frames),         cmocka_unit_test(test_sync_frames), cmocka_unit_test(test_states),
        cmocka_unit_test(test_heartbeat_consumer), cmocka_unit_test(test_emcy),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
