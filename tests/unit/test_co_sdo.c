/* CANopen SDO client (daq/src/msid_co_sdo.c) against an SDO server written here from CiA 301 7.2.4.3, on
   frames in memory with the test's own clock: every size around the expedited limit and the 7-byte segment
   boundaries, up and down, each server form (expedited, segmented with and without a size); the node's
   aborts by name; toggle errors both ways; timeouts at the first and a later response; frames of other
   COB-IDs met while waiting; a buffer too small; a response naming another entry. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "msid_daq/msid_co_sdo.h"

#define NODE 5u
#define MAXLEN 64u

/* the server: one entry 0x2000:01 */
typedef struct server {
    uint8_t entry[MAXLEN];
    size_t entry_len;
    /* upload form: 0 expedited where it fits, 1 always segmented with size, 2 segmented without size */
    int upload_form;
    int silent_after;          /* answer only this many requests (-1: all) */
    int toggle_error_segment;  /* flip the toggle of this segment response (0-based; -1 none) */
    uint32_t abort_with;       /* answer the first request with this abort (0: none) */
    int wrong_mux;             /* initiate responses name 0x2001:00 */
    int others_before;         /* frames of other COB-IDs queued before each response */
    /* what it saw */
    int requests;
    uint32_t abort_received;
    int download_done;
    size_t announced;
    /* its state */
    int mode;  /* 0 idle, 1 uploading, 2 downloading */
    unsigned toggle;
    size_t pos;
    int segment;
    /* frames to the client */
    msid_can_frame q[256];
    int qh, qt;
    /* frames from the client */
    msid_can_frame sent[64];
    int n_sent;
    uint64_t now;
    int others_handed;
} server;

static void push(server *sv, const uint8_t b[8], uint32_t id)
{
    msid_can_frame *f = &sv->q[sv->qt++ % 256];
    memset(f, 0, sizeof *f);
    f->id = id;
    f->len = 8;
    memcpy(f->data, b, 8);
}

static void respond(server *sv, uint8_t b[8])
{
    for (int i = 0; i < sv->others_before; i++) {
        const uint8_t hb[8] = {0x05};
        push(sv, hb, 0x700u + NODE);
    }
    push(sv, b, 0x580u + NODE);
}

static void mux(server *sv, uint8_t b[8])
{
    b[1] = sv->wrong_mux ? 0x01 : 0x00;
    b[2] = 0x20;
    b[3] = sv->wrong_mux ? 0x00 : 0x01;
}

static void abort_resp(server *sv, uint32_t code)
{
    uint8_t b[8] = {0x80, 0x00, 0x20, 0x01};
    for (int i = 0; i < 4; i++) b[4 + i] = (uint8_t)(code >> (8 * i));
    respond(sv, b);
    sv->mode = 0;
}

static void serve_upload_segment(server *sv, const uint8_t *r)
{
    const unsigned t = (r[0] >> 4) & 1u;
    if (sv->mode != 1) return abort_resp(sv, 0x05040001u);
    if (t != sv->toggle) return abort_resp(sv, 0x05030000u);
    const size_t rem = sv->entry_len - sv->pos, n = rem < 7 ? rem : 7;
    const unsigned last = sv->pos + n == sv->entry_len;
    unsigned tb = t;
    if (sv->segment == sv->toggle_error_segment) tb ^= 1u;
    uint8_t b[8] = {(uint8_t)(tb << 4 | (unsigned)(7 - n) << 1 | last)};
    memcpy(&b[1], sv->entry + sv->pos, n);
    sv->pos += n;
    sv->toggle ^= 1u;
    sv->segment++;
    if (last) sv->mode = 0;
    respond(sv, b);
}

static void serve_download_segment(server *sv, const uint8_t *r)
{
    const unsigned t = (r[0] >> 4) & 1u;
    if (sv->mode != 2) return abort_resp(sv, 0x05040001u);
    if (t != sv->toggle) return abort_resp(sv, 0x05030000u);
    const size_t n = 7u - ((r[0] >> 1) & 7u);
    memcpy(sv->entry + sv->pos, &r[1], n);
    sv->pos += n;
    unsigned tb = t;
    if (sv->segment == sv->toggle_error_segment) tb ^= 1u;
    const uint8_t b[8] = {(uint8_t)(0x20u | tb << 4)};
    sv->toggle ^= 1u;
    sv->segment++;
    if (r[0] & 1u) {
        sv->mode = 0;
        sv->entry_len = sv->pos;
        sv->download_done = 1;
    }
    respond(sv, (uint8_t *)b);
}

static void start_segments(server *sv, int mode)
{
    sv->mode = mode;
    sv->toggle = 0;
    sv->pos = 0;
    sv->segment = 0;
}

static void serve(server *sv, const msid_can_frame *f)
{
    const uint8_t *r = f->data;
    if ((r[0] >> 5) == 4) {
        sv->abort_received = (uint32_t)r[4] | (uint32_t)r[5] << 8 | (uint32_t)r[6] << 16 | (uint32_t)r[7] << 24;
        sv->mode = 0;
        return;
    }
    if (sv->silent_after >= 0 && sv->requests >= sv->silent_after) return;
    sv->requests++;
    if (sv->abort_with) return abort_resp(sv, sv->abort_with);
    uint8_t b[8] = {0};
    switch (r[0] >> 5) {
    case 2: /* initiate upload */
        mux(sv, b);
        if (sv->upload_form == 0 && sv->entry_len >= 1 && sv->entry_len <= 4) {
            b[0] = (uint8_t)(0x43u | (unsigned)(4 - sv->entry_len) << 2);
            memcpy(&b[4], sv->entry, sv->entry_len);
        } else {
            b[0] = sv->upload_form == 2 ? 0x40 : 0x41;
            for (int i = 0; i < 4 && sv->upload_form != 2; i++) b[4 + i] = (uint8_t)(sv->entry_len >> (8 * i));
            start_segments(sv, 1);
        }
        return respond(sv, b);
    case 3: return serve_upload_segment(sv, r);
    case 1: /* initiate download */
        mux(sv, b);
        b[0] = 0x60;
        if (r[0] & 2u) {
            const size_t n = (r[0] & 1u) ? 4u - ((r[0] >> 2) & 3u) : 4u;
            memcpy(sv->entry, &r[4], n);
            sv->entry_len = n;
            sv->download_done = 1;
        } else {
            sv->announced = (size_t)r[4] | (size_t)r[5] << 8 | (size_t)r[6] << 16 | (size_t)r[7] << 24;
            start_segments(sv, 2);
        }
        return respond(sv, b);
    case 0: return serve_download_segment(sv, r);
    default: return abort_resp(sv, 0x05040001u);
    }
}

static int io_send(void *ctx, const msid_can_frame *f)
{
    server *sv = ctx;
    assert_int_equal(f->id, 0x600u + NODE);
    assert_int_equal(f->len, 8);
    if (sv->n_sent < 64) sv->sent[sv->n_sent++] = *f;
    serve(sv, f);
    return 0;
}

static int io_recv(void *ctx, msid_can_frame *f, int timeout_ms)
{
    server *sv = ctx;
    assert_true(timeout_ms >= 0);
    if (sv->qh == sv->qt) {
        sv->now += (uint64_t)timeout_ms;
        return -MSID_DAQ_E_TIMEOUT;
    }
    *f = sv->q[sv->qh++ % 256];
    sv->now += 1;  /* every frame takes a while: a flood of others runs into the deadline */
    return 1;
}

static uint64_t io_now(void *ctx) { return ((server *)ctx)->now; }

static void io_other(void *ctx, const msid_can_frame *f)
{
    server *sv = ctx;
    assert_int_equal(f->id, 0x700u + NODE);
    sv->others_handed++;
}

static void setup(server *sv, msid_co_sdo *s)
{
    memset(sv, 0, sizeof *sv);
    sv->silent_after = -1;
    sv->toggle_error_segment = -1;
    const msid_co_io io = {sv, io_send, io_recv, io_now, io_other};
    assert_int_equal(msid_co_sdo_init(s, &io, NODE, 100), 0);
}

static void fill(uint8_t *b, size_t n, unsigned seed)
{
    for (size_t i = 0; i < n; i++) b[i] = (uint8_t)(seed * 31u + i * 7u + 1u);
}

/* segments a transfer of n bytes takes when segmented (at least one: a 0-byte transfer ends in one) */
static int segments(size_t n) { return n == 0 ? 1 : (int)((n + 6) / 7); }

static void test_upload_sizes(void **state)
{
    (void)state;
    for (int form = 0; form < 3; form++)
        for (size_t n = 0; n <= 31; n++) {
            server sv;
            msid_co_sdo s;
            setup(&sv, &s);
            sv.upload_form = form;
            sv.entry_len = n;
            fill(sv.entry, n, (unsigned)n);
            uint8_t buf[MAXLEN];
            size_t len = 999;
            const int rc = msid_co_sdo_upload(&s, 0x2000, 1, buf, sizeof buf, &len);
            if (rc) fail_msg("form %d size %zu: %d %s", form, n, rc, s.err);
            if (len != n) fail_msg("form %d size %zu: read %zu bytes", form, n, len);
            assert_memory_equal(buf, sv.entry, n);
            const int expedited = form == 0 && n >= 1 && n <= 4;
            assert_int_equal(sv.n_sent, 1 + (expedited ? 0 : segments(n)));
            assert_int_equal(sv.sent[0].data[0], 0x40);
            for (int k = 1; k < sv.n_sent; k++) assert_int_equal(sv.sent[k].data[0], 0x60 | ((k - 1) & 1) << 4);
            assert_int_equal(sv.abort_received, 0);
            assert_string_equal(s.err, "");
        }
}

static void test_download_sizes(void **state)
{
    (void)state;
    for (size_t n = 0; n <= 31; n++) {
        server sv;
        msid_co_sdo s;
        setup(&sv, &s);
        uint8_t data[MAXLEN];
        fill(data, n, (unsigned)n + 100u);
        const int rc = msid_co_sdo_download(&s, 0x2000, 1, data, n);
        if (rc) fail_msg("size %zu: %d %s", n, rc, s.err);
        assert_true(sv.download_done);
        assert_int_equal(sv.entry_len, n);
        assert_memory_equal(sv.entry, data, n);
        const int expedited = n >= 1 && n <= 4;
        /* CiA 301: 0x2F, 0x2B, 0x27, 0x23 for 1..4 bytes; 0x21 and the size for a segmented one */
        static const uint8_t exp_cmd[5] = {0, 0x2F, 0x2B, 0x27, 0x23};
        assert_int_equal(sv.sent[0].data[0], expedited ? exp_cmd[n] : 0x21);
        assert_int_equal(sv.sent[0].data[1], 0x00);
        assert_int_equal(sv.sent[0].data[2], 0x20);
        assert_int_equal(sv.sent[0].data[3], 0x01);
        if (!expedited) assert_int_equal(sv.announced, n);
        assert_int_equal(sv.n_sent, 1 + (expedited ? 0 : segments(n)));
        for (int k = 1; k < sv.n_sent; k++) {
            const size_t left = n - (size_t)(k - 1) * 7, in = left < 7 ? left : 7;
            const int last = k == sv.n_sent - 1;
            assert_int_equal(sv.sent[k].data[0], ((k - 1) & 1) << 4 | (int)(7 - in) << 1 | last);
        }
    }
}

/* every code of CiA 301's table has its own name; a code outside it is said to be unknown */
static void test_abort_names(void **state)
{
    (void)state;
    static const uint32_t codes[] = {
        0x05030000u, 0x05040000u, 0x05040001u, 0x05040002u, 0x05040003u, 0x05040004u, 0x05040005u, 0x06010000u,
        0x06010001u, 0x06010002u, 0x06020000u, 0x06040041u, 0x06040042u, 0x06040043u, 0x06040047u, 0x06060000u,
        0x06070010u, 0x06070012u, 0x06070013u, 0x06090011u, 0x06090030u, 0x06090031u, 0x06090032u, 0x06090036u,
        0x060A0023u, 0x08000000u, 0x08000020u, 0x08000021u, 0x08000022u, 0x08000023u, 0x08000024u};
    const size_t n = sizeof codes / sizeof codes[0];
    for (size_t i = 0; i < n; i++) {
        const char *a = msid_co_abort_name(codes[i]);
        if (!strcmp(a, "unknown abort code")) fail_msg("0x%08X has no name", (unsigned)codes[i]);
        for (size_t j = 0; j < i; j++)
            if (!strcmp(a, msid_co_abort_name(codes[j]))) fail_msg("0x%08X and 0x%08X share a name", (unsigned)codes[i], (unsigned)codes[j]);
        /* and the node's abort reaches the caller with it */
        server sv;
        msid_co_sdo s;
        setup(&sv, &s);
        sv.abort_with = codes[i];
        uint8_t buf[8];
        size_t len;
        assert_int_equal(msid_co_sdo_upload(&s, 0x2000, 1, buf, sizeof buf, &len), -MSID_DAQ_E_DEVICE);
        assert_int_equal(s.abort_code, codes[i]);
        assert_true(s.abort_by_node);
        char code[16];
        snprintf(code, sizeof code, "0x%08X", (unsigned)codes[i]);
        if (!strstr(s.err, a) || !strstr(s.err, code) || !strstr(s.err, "0x2000:01") || !strstr(s.err, "node 5"))
            fail_msg("err '%s' lacks '%s' or %s", s.err, a, code);
        assert_int_equal(sv.abort_received, 0);  /* msid does not answer an abort with one */
        setup(&sv, &s);
        sv.abort_with = codes[i];
        assert_int_equal(msid_co_sdo_write_uint(&s, 0x2000, 1, 2, 7), -MSID_DAQ_E_DEVICE);
        assert_int_equal(s.abort_code, codes[i]);
    }
    assert_string_equal(msid_co_abort_name(0x06010002u), "attempt to write a read only object");
    assert_string_equal(msid_co_abort_name(0x06020000u), "object does not exist in the object dictionary");
    assert_string_equal(msid_co_abort_name(0x06040042u),
                        "the number and length of the objects to be mapped would exceed PDO length");
    assert_string_equal(msid_co_abort_name(0), "unknown abort code");
    assert_string_equal(msid_co_abort_name(0x05030001u), "unknown abort code");
    assert_string_equal(msid_co_abort_name(0xFFFFFFFFu), "unknown abort code");
}

/* A 20-byte transfer (three segments) against a server with one fault: the toggle of segment toggle_seg
   flipped, or silence after `silent_after` answered requests (-1: no fault of that kind). */
static int faulty_transfer(server *sv, msid_co_sdo *s, int download, int toggle_seg, int silent_after)
{
    setup(sv, s);
    sv->upload_form = 1;
    sv->entry_len = 20;
    sv->toggle_error_segment = toggle_seg;
    sv->silent_after = silent_after;
    uint8_t buf[MAXLEN] = {0};
    size_t len;
    return download ? msid_co_sdo_download(s, 0x2000, 1, buf, 20) : msid_co_sdo_upload(s, 0x2000, 1, buf, sizeof buf, &len);
}

static void test_toggle_errors(void **state)
{
    (void)state;
    for (int seg = 0; seg < 3; seg++) {
        server sv;
        msid_co_sdo s;
        assert_int_equal(faulty_transfer(&sv, &s, 0, seg, -1), -MSID_DAQ_E_PROTOCOL);
        assert_int_equal(sv.abort_received, MSID_CO_ABORT_TOGGLE);
        assert_int_equal(s.abort_code, MSID_CO_ABORT_TOGGLE);
        assert_false(s.abort_by_node);
        assert_non_null(strstr(s.err, "toggle bit not alternated"));
        assert_int_equal(sv.n_sent, 1 + seg + 1 + 1);  /* initiate, segments up to the bad one, the abort */
        assert_int_equal(faulty_transfer(&sv, &s, 1, seg, -1), -MSID_DAQ_E_PROTOCOL);
        assert_int_equal(sv.abort_received, MSID_CO_ABORT_TOGGLE);
        assert_int_equal(sv.n_sent, 1 + seg + 1 + 1);
    }
}

static void test_timeouts(void **state)
{
    (void)state;
    for (int after = 0; after < 3; after++) {
        server sv;
        msid_co_sdo s;
        assert_int_equal(faulty_transfer(&sv, &s, 0, -1, after), -MSID_DAQ_E_TIMEOUT);
        assert_int_equal(sv.abort_received, MSID_CO_ABORT_TIMEOUT);
        assert_non_null(strstr(s.err, "no response within 100 ms"));
        assert_non_null(strstr(s.err, "SDO protocol timed out"));
        assert_int_equal(sv.now, (uint64_t)after + 100u);  /* one frame per answered request, then the wait */
        assert_int_equal(faulty_transfer(&sv, &s, 1, -1, after), -MSID_DAQ_E_TIMEOUT);
        assert_int_equal(sv.abort_received, MSID_CO_ABORT_TIMEOUT);
        assert_int_equal(sv.now, (uint64_t)after + 100u);
    }
}

static void test_other_frames(void **state)
{
    (void)state;
    server sv;
    msid_co_sdo s;
    setup(&sv, &s);
    sv.others_before = 3;
    sv.upload_form = 1;
    sv.entry_len = 9;
    fill(sv.entry, 9, 3);
    uint8_t buf[MAXLEN];
    size_t len;
    assert_int_equal(msid_co_sdo_upload(&s, 0x2000, 1, buf, sizeof buf, &len), 0);
    assert_int_equal(len, 9);
    assert_memory_equal(buf, sv.entry, 9);
    assert_int_equal(sv.others_handed, 3 * 3);
    /* a node whose other frames keep coming never answers in time: the deadline holds */
    setup(&sv, &s);
    sv.others_before = 150;
    assert_int_equal(msid_co_sdo_upload(&s, 0x2000, 1, buf, sizeof buf, &len), -MSID_DAQ_E_TIMEOUT);
    assert_int_equal(sv.others_handed, 100);
}

static void test_refusals(void **state)
{
    (void)state;
    server sv;
    msid_co_sdo s;
    uint8_t buf[MAXLEN];
    size_t len;
    /* an entry longer than the buffer: expedited, announced, and unannounced */
    for (int form = 0; form < 3; form++) {
        setup(&sv, &s);
        sv.upload_form = form;
        sv.entry_len = form == 0 ? 4 : 17;
        assert_int_equal(msid_co_sdo_upload(&s, 0x2000, 1, buf, form == 0 ? 3 : 10, &len), -MSID_DAQ_E_RANGE);
        assert_int_equal(sv.abort_received, MSID_CO_ABORT_MEMORY);
        assert_non_null(strstr(s.err, "room for"));
    }
    /* a response naming another entry */
    setup(&sv, &s);
    sv.wrong_mux = 1;
    sv.entry_len = 2;
    assert_int_equal(msid_co_sdo_upload(&s, 0x2000, 1, buf, sizeof buf, &len), -MSID_DAQ_E_PROTOCOL);
    assert_non_null(strstr(s.err, "names 0x2001:00"));
    assert_int_equal(sv.abort_received, MSID_CO_ABORT_GENERAL);
    /* an entry of another size than the caller's type */
    setup(&sv, &s);
    sv.entry_len = 2;
    uint32_t v;
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x2000, 1, 4, &v), -MSID_DAQ_E_PROTOCOL);
    assert_non_null(strstr(s.err, "holds 2 bytes where 4 were expected"));
    setup(&sv, &s);
    sv.entry_len = 4;
    memcpy(sv.entry, "\x78\x56\x34\x12", 4);
    assert_int_equal(msid_co_sdo_read_uint(&s, 0x2000, 1, 4, &v), 0);
    assert_int_equal(v, 0x12345678u);
    /* node ids and timeouts */
    const msid_co_io io = {&sv, io_send, io_recv, io_now, NULL};
    assert_int_equal(msid_co_sdo_init(&s, &io, 0, 0), -MSID_DAQ_E_ARG);
    assert_string_equal(s.err, "node id 0 is out of range (1..127)");
    assert_int_equal(msid_co_sdo_init(&s, &io, 128, 0), -MSID_DAQ_E_ARG);
    assert_string_equal(s.err, "node id 128 is out of range (1..127)");
    assert_int_equal(msid_co_sdo_init(&s, &io, 127, 0), 0);
    assert_int_equal(s.timeout_ms, MSID_CO_SDO_TIMEOUT_MS);
    assert_int_equal(msid_co_sdo_init(&s, &io, 1, -1), -MSID_DAQ_E_ARG);
    const msid_co_io none = {0};
    assert_int_equal(msid_co_sdo_init(&s, &none, 1, 0), -MSID_DAQ_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_upload_sizes), cmocka_unit_test(test_download_sizes), cmocka_unit_test(test_abort_names),
        cmocka_unit_test(test_toggle_errors), cmocka_unit_test(test_timeouts),     cmocka_unit_test(test_other_frames),
        cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
