/* The Modbus TCP reply reader of our own (daq/src/msid_mbap.c), frame by frame on a socket pair: the
 * scripted "device" end writes its frames before the request is sent, so nothing depends on timing.
 * A stale reply (an earlier transaction id) and a foreign unit id are skipped and counted and the
 * matching frame is returned, whatever its position; a malformed header (protocol id, length out of
 * 2..254) is one error; a frame cut short, no matching reply or a closed connection end in bounded
 * time with the right status. Negative control: the reply taken is the matching one, not the first. */
#define _DEFAULT_SOURCE
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "msid_daq/msid_daq.h"
#include "msid_daq/msid_mbap.h"

typedef struct pair {
    msid_mbap c;
    int dev;   /* the device's end */
} pair;

static int setup(void **state)
{
    static pair p;
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM, 0, sv) != 0) return -1;
    memset(&p, 0, sizeof p);
    p.c.fd = sv[0];
    p.dev = sv[1];
    p.c.unit = 7;
    p.c.tid = 41;                    /* the next request carries 42 */
    p.c.response_timeout_ms = 200;   /* only the failing cases wait for it; nothing asserts how long */
    p.c.byte_timeout_ms = 100;
    *state = &p;
    return 0;
}

static int teardown(void **state)
{
    pair *p = *state;
    close(p->c.fd);
    if (p->dev >= 0) close(p->dev);
    return 0;
}

/* An MBAP frame: tid, protocol id, length (unit + PDU), unit, PDU. */
static size_t frame(uint8_t *f, uint16_t tid, uint16_t proto, uint8_t unit, const uint8_t *pdu, size_t n)
{
    f[0] = (uint8_t)(tid >> 8);
    f[1] = (uint8_t)tid;
    f[2] = (uint8_t)(proto >> 8);
    f[3] = (uint8_t)proto;
    f[4] = (uint8_t)((n + 1) >> 8);
    f[5] = (uint8_t)(n + 1);
    f[6] = unit;
    memcpy(f + 7, pdu, n);
    return 7 + n;
}

static void put(pair *p, uint16_t tid, uint16_t proto, uint8_t unit, const uint8_t *pdu, size_t n)
{
    uint8_t f[7 + 300];
    const size_t len = frame(f, tid, proto, unit, pdu, n);
    assert_int_equal(write(p->dev, f, len), (ssize_t)len);
}

static const uint8_t REQ[5] = {4, 0, 0, 0, 1};         /* read 1 input register at 0 */
static const uint8_t GOOD[4] = {4, 2, 0x12, 0x34};     /* its reply */
static const uint8_t STALE[4] = {4, 2, 0xde, 0xad};    /* a reply with other contents */

static void request_sent_as_specified(pair *p)
{
    uint8_t f[12];
    assert_int_equal(read(p->dev, f, sizeof f), 12);
    const uint8_t want[12] = {0, 42, 0, 0, 0, 6, 7, 4, 0, 0, 0, 1};
    assert_memory_equal(f, want, sizeof want);
}

static void test_stale_and_foreign_replies_are_skipped(void **state)
{
    pair *p = *state;
    put(p, 41, 0, 7, STALE, sizeof STALE);   /* the duplicate of the previous request */
    put(p, 42, 0, 9, STALE, sizeof STALE);   /* right transaction, another unit */
    put(p, 0xA5C3, 0, 7, STALE, sizeof STALE);   /* a transaction never sent */
    put(p, 42, 0, 7, GOOD, sizeof GOOD);
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    size_t n = 0;
    assert_int_equal(msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n), 0);
    assert_int_equal(n, sizeof GOOD);
    assert_memory_equal(rsp, GOOD, sizeof GOOD);   /* negative control: the first frame was STALE */
    assert_int_equal(p->c.skipped, 3);
    assert_int_equal(p->c.malformed, 0);
    request_sent_as_specified(p);
}

static void test_matching_reply_first_skips_nothing(void **state)
{
    pair *p = *state;
    put(p, 42, 0, 7, GOOD, sizeof GOOD);
    put(p, 42, 0, 7, STALE, sizeof STALE);   /* its duplicate: left for the next request to skip */
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    size_t n = 0;
    assert_int_equal(msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n), 0);
    assert_memory_equal(rsp, GOOD, sizeof GOOD);
    assert_int_equal(p->c.skipped, 0);
    put(p, 43, 0, 7, GOOD, sizeof GOOD);
    assert_int_equal(msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n), 0);
    assert_memory_equal(rsp, GOOD, sizeof GOOD);
    assert_int_equal(p->c.skipped, 1);
}

static void test_only_foreign_replies_time_out_naming_them(void **state)
{
    pair *p = *state;
    put(p, 41, 0, 7, STALE, sizeof STALE);
    put(p, 40, 0, 7, STALE, sizeof STALE);
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    size_t n = 0;
    assert_int_equal(msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n), -MSID_DAQ_E_TIMEOUT);
    assert_int_equal(p->c.skipped, 2);
    assert_non_null(strstr(p->c.err, "no reply (response timeout of 200 ms) after 2 replies with another"));
}

static void test_malformed_headers_are_one_error(void **state)
{
    pair *p = *state;
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    size_t n = 0;
    put(p, 42, 1, 7, GOOD, sizeof GOOD);   /* protocol id 1 */
    assert_int_equal(msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n), -MSID_DAQ_E_PROTOCOL);
    assert_non_null(strstr(p->c.err, "malformed MBAP frame: protocol id 1, length 5"));
    uint8_t junk[64];   /* the caller reconnects after a malformed frame; here: drop what is left */
    while (recv(p->c.fd, junk, sizeof junk, MSG_DONTWAIT) > 0) {}
    uint8_t big[268] = {4, 255};
    put(p, 43, 0, 7, big, sizeof big);     /* length 269: beyond the 260-byte ADU */
    assert_int_equal(msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n), -MSID_DAQ_E_PROTOCOL);
    assert_non_null(strstr(p->c.err, "length 269 (must be 0 and 2..254)"));
    assert_int_equal(p->c.malformed, 2);
    assert_int_equal(p->c.skipped, 0);
}

static void test_header_lengths(void **state)
{
    (void)state;
    uint8_t h[7] = {0, 1, 0, 0, 0, 2, 1};
    assert_int_equal(msid_mbap_header_pdu_len(h), 1);
    h[5] = 254;
    assert_int_equal(msid_mbap_header_pdu_len(h), 253);
    h[5] = 1;
    assert_int_equal(msid_mbap_header_pdu_len(h), 0);
    h[5] = 0;
    assert_int_equal(msid_mbap_header_pdu_len(h), 0);
    h[5] = 255;
    assert_int_equal(msid_mbap_header_pdu_len(h), 0);
    h[4] = 1;
    h[5] = 0;
    assert_int_equal(msid_mbap_header_pdu_len(h), 0);
}

static void test_truncated_frame_hits_the_byte_timeout(void **state)
{
    pair *p = *state;
    uint8_t f[7 + 8];
    const size_t len = frame(f, 42, 0, 7, GOOD, sizeof GOOD);
    assert_int_equal(write(p->dev, f, len - 2), (ssize_t)(len - 2));   /* the rest never comes */
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    size_t n = 0;
    assert_int_equal(msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n), -MSID_DAQ_E_TIMEOUT);
    assert_non_null(strstr(p->c.err, "stopped after 2 of 4 bytes"));
}

static void test_closed_connection_is_io(void **state)
{
    pair *p = *state;
    put(p, 41, 0, 7, STALE, sizeof STALE);
    close(p->dev);
    p->dev = -1;
    uint8_t rsp[MSID_MBAP_MAX_PDU];
    size_t n = 0;
    const int rc = msid_mbap_request(&p->c, REQ, sizeof REQ, rsp, &n);
    assert_true(rc == -MSID_DAQ_E_IO);   /* the send fails (EPIPE) or the read sees the end */
}

static void test_bad_arguments(void **state)
{
    pair *p = *state;
    uint8_t rsp[MSID_MBAP_MAX_PDU], big[MSID_MBAP_MAX_PDU + 1] = {4};
    size_t n = 0;
    assert_int_equal(msid_mbap_request(&p->c, REQ, 0, rsp, &n), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_mbap_request(&p->c, big, sizeof big, rsp, &n), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_mbap_request(NULL, REQ, sizeof REQ, rsp, &n), -MSID_DAQ_E_ARG);
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test_setup_teardown(test_stale_and_foreign_replies_are_skipped, setup, teardown),
        cmocka_unit_test_setup_teardown(test_matching_reply_first_skips_nothing, setup, teardown),
        cmocka_unit_test_setup_teardown(test_only_foreign_replies_time_out_naming_them, setup, teardown),
        cmocka_unit_test_setup_teardown(test_malformed_headers_are_one_error, setup, teardown),
        cmocka_unit_test(test_header_lengths),
        cmocka_unit_test_setup_teardown(test_truncated_frame_hits_the_byte_timeout, setup, teardown),
        cmocka_unit_test_setup_teardown(test_closed_connection_is_io, setup, teardown),
        cmocka_unit_test_setup_teardown(test_bad_arguments, setup, teardown),
    };
    return cmocka_run_group_tests(t, NULL, NULL);
}
