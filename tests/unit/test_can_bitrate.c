/* A CAN interface's bit rate from the kernel's RTM_GETLINK reply (msid_can_bitrate_parse), on replies built
 * here from the kernel's UAPI structures (nlmsghdr, ifinfomsg, rtattr nested as the kernel nests them, with
 * NLA_F_NESTED): a CAN controller at 500 kbit/s, a CAN FD one at 1 and 5 Mbit/s, one without a bit rate set,
 * vcan and vxcan (virtual: no rate), interfaces of other kinds and of none (lo), the kernel's errors (no such
 * device, another), and replies cut short or with lengths that do not add up: refused, never read past
 * their end (each cut is a heap copy of exactly its length, for the sanitizer build to see an overread),
 * and at an odd address. Then the request itself on this host's lo (not CAN) and on a name that is no
 * interface (the host has no CAN in its kernel: a real vcan is the VM's, tests/vcan/in_vm). */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include <sys/socket.h>

#include <linux/can/netlink.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>

#include "msid_daq/msid_can_bitrate.h"

/* a reply under construction: bytes, and the offsets of the open nests (their rta_len set at close) */
typedef struct {
    unsigned char b[4096];
    size_t n;
    size_t nest[4];
    int depth;
    size_t msg;
} reply;

static void pad(reply *r)
{
    while (r->n % 4) r->b[r->n++] = 0;
}

static void put(reply *r, const void *p, size_t n)
{
    assert_true(r->n + n <= sizeof r->b);
    memcpy(r->b + r->n, p, n);
    r->n += n;
}

static void msg_begin(reply *r, uint16_t type)
{
    r->msg = r->n;
    struct nlmsghdr h = {0};
    h.nlmsg_type = type;
    h.nlmsg_seq = 1;
    put(r, &h, sizeof h);
}

static void msg_end(reply *r)
{
    pad(r);
    struct nlmsghdr h;
    memcpy(&h, r->b + r->msg, sizeof h);
    h.nlmsg_len = (uint32_t)(r->n - r->msg);
    memcpy(r->b + r->msg, &h, sizeof h);
}

static void link_msg(reply *r, int index, unsigned short arphrd)
{
    msg_begin(r, RTM_NEWLINK);
    struct ifinfomsg i = {0};
    i.ifi_family = AF_UNSPEC;
    i.ifi_type = arphrd;
    i.ifi_index = index;
    put(r, &i, sizeof i);
}

static void attr(reply *r, unsigned short type, const void *p, size_t n)
{
    struct rtattr a = {(unsigned short)RTA_LENGTH(n), type};
    put(r, &a, sizeof a);
    put(r, p, n);
    pad(r);
}

static void attr_str(reply *r, unsigned short type, const char *s) { attr(r, type, s, strlen(s) + 1); }

static void attr_u32(reply *r, unsigned short type, uint32_t v) { attr(r, type, &v, sizeof v); }

static void nest_begin(reply *r, unsigned short type)
{
    r->nest[r->depth++] = r->n;
    struct rtattr a = {0, (unsigned short)(type | NLA_F_NESTED)};
    put(r, &a, sizeof a);
}

static void nest_end(reply *r)
{
    const size_t at = r->nest[--r->depth];
    struct rtattr a;
    memcpy(&a, r->b + at, sizeof a);
    a.rta_len = (unsigned short)(r->n - at);
    memcpy(r->b + at, &a, sizeof a);
}

static void bittiming(reply *r, unsigned short type, uint32_t rate)
{
    struct can_bittiming bt = {0};
    bt.bitrate = rate;
    bt.sample_point = 875;
    bt.tq = 1000000000u / rate / 16;
    bt.prop_seg = 6;
    bt.phase_seg1 = 7;
    bt.phase_seg2 = 2;
    bt.sjw = 1;
    bt.brp = 1;
    attr(r, type, &bt, sizeof bt);
}

/* what the kernel sends for an interface before its link info: name, MTU, operational state */
static void head_attrs(reply *r, const char *name, uint32_t mtu)
{
    attr_str(r, IFLA_IFNAME, name);
    attr_u32(r, IFLA_MTU, mtu);
    const unsigned char oper = 6;   /* IF_OPER_UP */
    attr(r, IFLA_OPERSTATE, &oper, 1);
}

/* a CAN controller's reply: rate 0 leaves IFLA_CAN_BITTIMING out (no bit rate set), dbitrate 0 the data phase */
static void can_reply(reply *r, uint32_t rate, uint32_t drate)
{
    memset(r, 0, sizeof *r);
    link_msg(r, 4, 280 /* ARPHRD_CAN */);
    head_attrs(r, "can0", drate ? 72 : 16);
    nest_begin(r, IFLA_LINKINFO);
    attr_str(r, IFLA_INFO_KIND, "can");
    nest_begin(r, IFLA_INFO_DATA);
    attr_u32(r, IFLA_CAN_STATE, CAN_STATE_ERROR_ACTIVE);
    if (rate) bittiming(r, IFLA_CAN_BITTIMING, rate);
    struct can_clock clk = {80000000u};
    attr(r, IFLA_CAN_CLOCK, &clk, sizeof clk);
    attr_u32(r, IFLA_CAN_RESTART_MS, 100);
    if (drate) bittiming(r, IFLA_CAN_DATA_BITTIMING, drate);
    nest_end(r);
    nest_end(r);
    attr_u32(r, IFLA_TXQLEN, 10);
    msg_end(r);
}

static void virtual_reply(reply *r, const char *kind)
{
    memset(r, 0, sizeof *r);
    link_msg(r, 3, 280);
    head_attrs(r, "vcan0", 72);
    nest_begin(r, IFLA_LINKINFO);
    attr_str(r, IFLA_INFO_KIND, kind);
    nest_end(r);
    msg_end(r);
}

static int parse(const reply *r, msid_can_bitrate *out) { return msid_can_bitrate_parse(r->b, r->n, out); }

/* a CAN controller at rate (and drate in the data phase): known, both rates as set */
static void check_known(uint32_t rate, uint32_t drate)
{
    reply r;
    can_reply(&r, rate, drate);
    msid_can_bitrate o;
    assert_int_equal(parse(&r, &o), 0);
    assert_int_equal(o.status, MSID_CAN_BITRATE_KNOWN);
    assert_int_equal(o.bitrate, rate);
    assert_int_equal(o.data_bitrate, drate);
    assert_string_equal(o.kind, "can");
    assert_string_equal(msid_can_bitrate_status_name(o.status), "known");
}

static void test_can_at_500k(void **state)
{
    (void)state;
    check_known(500000, 0);
}

static void test_can_fd_1m_5m(void **state)
{
    (void)state;
    check_known(1000000, 5000000);
}

/* the kernel leaves IFLA_CAN_BITTIMING out while no bit rate is set */
static void test_can_without_a_bit_rate(void **state)
{
    (void)state;
    reply r;
    can_reply(&r, 0, 0);
    msid_can_bitrate o;
    assert_int_equal(parse(&r, &o), 0);
    assert_int_equal(o.status, MSID_CAN_BITRATE_UNSET);
    assert_int_equal(o.bitrate, 0);
    assert_string_equal(o.kind, "can");
}

/* a link of kind `kind` (no IFLA_INFO_DATA): read as status st, no rate, the kind kept (cut to its room) */
static void check_kind(const char *kind, msid_can_bitrate_status st)
{
    reply r;
    virtual_reply(&r, kind);
    msid_can_bitrate o;
    assert_int_equal(parse(&r, &o), 0);
    assert_int_equal(o.status, st);
    assert_int_equal(o.bitrate, 0);
    assert_int_equal(strncmp(o.kind, kind, sizeof o.kind - 1), 0);
}

static void test_vcan_and_vxcan_are_virtual(void **state)
{
    (void)state;
    check_kind("vcan", MSID_CAN_BITRATE_VIRTUAL);
    check_kind("vxcan", MSID_CAN_BITRATE_VIRTUAL);
    assert_string_equal(msid_can_bitrate_status_name(MSID_CAN_BITRATE_VIRTUAL), "virtual");
}

/* a kind that starts as "can" does but is another is not CAN, and neither is a link without a kind (lo) */
static void test_other_kinds_are_not_can(void **state)
{
    (void)state;
    const char *kinds[] = {"veth", "cann", "ca", "a-kind-longer-than-sixteen"};
    for (int k = 0; k < 4; ++k) check_kind(kinds[k], MSID_CAN_BITRATE_NOT_CAN);
    reply r;
    memset(&r, 0, sizeof r);
    link_msg(&r, 1, 772 /* ARPHRD_LOOPBACK */);
    head_attrs(&r, "lo", 65536);
    msg_end(&r);
    msid_can_bitrate o;
    assert_int_equal(parse(&r, &o), 0);
    assert_int_equal(o.status, MSID_CAN_BITRATE_NOT_CAN);
    assert_string_equal(o.kind, "");
}

static void error_reply(reply *r, int error)
{
    memset(r, 0, sizeof *r);
    msg_begin(r, NLMSG_ERROR);
    struct nlmsgerr e = {0};
    e.error = error;
    e.msg.nlmsg_type = RTM_GETLINK;
    e.msg.nlmsg_len = NLMSG_LENGTH(sizeof(struct ifinfomsg));
    put(r, &e, sizeof e);
    msg_end(r);
}

static void test_kernel_errors(void **state)
{
    (void)state;
    reply r;
    msid_can_bitrate o;
    error_reply(&r, -ENODEV);
    assert_int_equal(parse(&r, &o), 0);
    assert_int_equal(o.status, MSID_CAN_BITRATE_MISSING);
    error_reply(&r, -EPERM);
    assert_int_equal(parse(&r, &o), -MSID_DAQ_E_IO);
    assert_int_equal(o.status, MSID_CAN_BITRATE_FAILED);
    assert_non_null(strstr(o.err, strerror(EPERM)));
    /* an acknowledgement (error 0) and no link message: nothing to read */
    error_reply(&r, 0);
    assert_int_equal(parse(&r, &o), -MSID_DAQ_E_PROTOCOL);
    assert_int_equal(o.status, MSID_CAN_BITRATE_FAILED);
    assert_int_equal(msid_can_bitrate_parse(NULL, 0, &o), -MSID_DAQ_E_PROTOCOL);
    assert_int_equal(msid_can_bitrate_parse(r.b, r.n, NULL), -MSID_DAQ_E_ARG);
}

static int parse_copy(const unsigned char *b, size_t n, msid_can_bitrate *o)
{
    unsigned char *c = malloc(n ? n : 1);
    assert_non_null(c);
    memcpy(c, b, n);
    const int rc = msid_can_bitrate_parse(c, n, o);
    free(c);
    return rc;
}

/* every cut of a complete reply is refused: each cut ends inside its one message */
static void test_cut_replies_are_refused(void **state)
{
    (void)state;
    reply r;
    can_reply(&r, 500000, 2000000);
    msid_can_bitrate o;
    assert_int_equal(parse_copy(r.b, r.n, &o), 0);   /* the whole: the control */
    assert_int_equal(o.bitrate, 500000);
    for (size_t k = 0; k < r.n; ++k) {
        const int rc = parse_copy(r.b, k, &o);
        assert_true(rc < 0);
        assert_int_equal(o.status, MSID_CAN_BITRATE_FAILED);
        assert_int_equal(o.bitrate, 0);
    }
}

/* lengths that do not add up inside a message whose own length is right */
static void test_inconsistent_lengths_are_refused(void **state)
{
    (void)state;
    reply r;
    msid_can_bitrate o;
    /* the linkinfo nest claims more than its message holds */
    can_reply(&r, 500000, 0);
    const size_t li = NLMSG_HDRLEN + NLMSG_ALIGN(sizeof(struct ifinfomsg)) + RTA_SPACE(5) + 2 * RTA_SPACE(4);
    struct rtattr a;
    memcpy(&a, r.b + li, sizeof a);
    assert_int_equal(a.rta_type & NLA_TYPE_MASK, IFLA_LINKINFO);   /* the offset above is the nest's */
    a.rta_len = (unsigned short)(r.n - li + 8);
    memcpy(r.b + li, &a, sizeof a);
    assert_int_equal(parse(&r, &o), -MSID_DAQ_E_PROTOCOL);
    assert_int_equal(o.status, MSID_CAN_BITRATE_FAILED);
    /* an attribute shorter than its own header */
    a.rta_len = 2;
    memcpy(r.b + li, &a, sizeof a);
    assert_int_equal(parse(&r, &o), -MSID_DAQ_E_PROTOCOL);
    /* a bit timing payload shorter than struct can_bittiming */
    memset(&r, 0, sizeof r);
    link_msg(&r, 4, 280);
    nest_begin(&r, IFLA_LINKINFO);
    attr_str(&r, IFLA_INFO_KIND, "can");
    nest_begin(&r, IFLA_INFO_DATA);
    attr_u32(&r, IFLA_CAN_BITTIMING, 500000);
    nest_end(&r);
    nest_end(&r);
    msg_end(&r);
    assert_int_equal(parse(&r, &o), -MSID_DAQ_E_PROTOCOL);
    assert_int_equal(o.bitrate, 0);
    /* a message shorter than its ifinfomsg */
    memset(&r, 0, sizeof r);
    msg_begin(&r, RTM_NEWLINK);
    attr_u32(&r, IFLA_MTU, 16);
    msg_end(&r);
    assert_int_equal(parse(&r, &o), -MSID_DAQ_E_PROTOCOL);
    /* a message length below its header */
    can_reply(&r, 500000, 0);
    struct nlmsghdr h;
    memcpy(&h, r.b, sizeof h);
    h.nlmsg_len = 8;
    memcpy(r.b, &h, sizeof h);
    assert_int_equal(parse(&r, &o), -MSID_DAQ_E_PROTOCOL);
}

/* the reply at an odd address reads the same (the parser copies its headers out) */
static void test_unaligned_reply(void **state)
{
    (void)state;
    reply r;
    can_reply(&r, 250000, 0);
    static unsigned char odd[sizeof r.b + 1];
    memcpy(odd + 1, r.b, r.n);
    msid_can_bitrate o;
    assert_int_equal(msid_can_bitrate_parse(odd + 1, r.n, &o), 0);
    assert_int_equal(o.bitrate, 250000);
}

/* the request on this host: lo is there and is not CAN; a name that is no interface is missing */
static void test_query_on_this_host(void **state)
{
    (void)state;
    msid_can_bitrate o;
    assert_int_equal(msid_can_bitrate_query("lo", &o), 0);
    assert_int_equal(o.status, MSID_CAN_BITRATE_NOT_CAN);
    assert_int_equal(o.bitrate, 0);
    assert_int_equal(msid_can_bitrate_query("msidnosuch0", &o), 0);
    assert_int_equal(o.status, MSID_CAN_BITRATE_MISSING);
    assert_int_equal(msid_can_bitrate_query("", &o), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_can_bitrate_query("a-name-of-16-chr", &o), -MSID_DAQ_E_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_can_at_500k),
        cmocka_unit_test(test_can_fd_1m_5m),
        cmocka_unit_test(test_can_without_a_bit_rate),
        cmocka_unit_test(test_vcan_and_vxcan_are_virtual),
        cmocka_unit_test(test_other_kinds_are_not_can),
        cmocka_unit_test(test_kernel_errors),
        cmocka_unit_test(test_cut_replies_are_refused),
        cmocka_unit_test(test_inconsistent_lengths_are_refused),
        cmocka_unit_test(test_unaligned_reply),
        cmocka_unit_test(test_query_on_this_host),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
