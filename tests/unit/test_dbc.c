/* DBC reader and signal codec (daq/src/msid_dbc.c): hand-computed Intel and Motorola layouts (across
   byte boundaries, 1 and 64 bits), signed values, float32/float64, multiplexing, extended identifiers,
   CAN FD lengths, cycle times, the sections that are skipped, encode refusals, and malformed files,
   each error naming its line. The bytes expected are worked out by hand in the comments; cantools
   checks the same codec on many real files (tests/dbc). */
#include <float.h>
#include <locale.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "msid_daq/msid_dbc.h"

static _Alignas(8) unsigned char MEM[1 << 16];

static void load(msid_dbc *d, const char *text)
{
    const size_t need = msid_dbc_mem_size(text, strlen(text));
    if (need == 0 || need > sizeof MEM) {
        msid_dbc_init(d, text, strlen(text), NULL, 0);
        fail_msg("mem_size %zu: %s", need, d->err);
    }
    const int rc = msid_dbc_init(d, text, strlen(text), MEM, sizeof MEM);
    if (rc) fail_msg("init %d: %s", rc, d->err);
}

/* The error of a text msid refuses: its code, and err names `line` and contains `what`. */
static void refused(const char *text, uint32_t line, const char *what)
{
    msid_dbc d;
    const int rc = msid_dbc_init(&d, text, strlen(text), MEM, sizeof MEM);
    if (rc != -MSID_DAQ_E_FORMAT) fail_msg("accepted (rc %d), expected line %u: %s", rc, (unsigned)line, what);
    char want[32];
    snprintf(want, sizeof want, "line %u: ", (unsigned)line);
    if (strncmp(d.err, want, strlen(want)) || !strstr(d.err, what))
        fail_msg("err '%s', expected '%s...%s'", d.err, want, what);
    assert_int_equal(d.err_line, line);
}

static const msid_dbc_message *msg_id(const msid_dbc *d, uint32_t id)
{
    const msid_dbc_message *m = msid_dbc_message_by_id(d, id);
    if (!m) fail_msg("no message of id 0x%X", (unsigned)id);
    return m;
}

static const msid_dbc_message *msg_name(const msid_dbc *d, const char *name)
{
    const msid_dbc_message *m = msid_dbc_message_by_name(d, name);
    if (!m) fail_msg("no message %s", name);
    return m;
}

static const msid_dbc_signal *sig(const msid_dbc *d, const char *msg, const char *name)
{
    const msid_dbc_message *m = msid_dbc_message_by_name(d, msg);
    assert_non_null(m);
    const msid_dbc_signal *s = msid_dbc_signal_by_name(d, m, name);
    if (!s) fail_msg("no signal %s.%s", msg, name);
    return s;
}

static const char LAYOUTS[] =
    "VERSION \"\"\n"
    "\n"
    "NS_ :\n"
    "\tNS_DESC_\n"
    "\tCM_\n"
    "\tBA_DEF_\n"
    "\tSIG_VALTYPE_\n"
    "\n"
    "BS_:\n"
    "\n"
    "BU_: ECU HOST\n"
    "\n"
    "BO_ 256 Intel: 8 ECU\n"
    " SG_ cross : 4|12@1+ (1,0) [0|0] \"\" HOST\n"
    " SG_ bit : 20|1@1+ (1,0) [0|1] \"\" HOST\n"
    " SG_ sgn : 24|12@1- (0.5,10) [0|0] \"degC\" HOST,ECU\n"
    "BO_ 257 Moto: 8 ECU\n"
    " SG_ word : 7|16@0+ (1,0) [0|0] \"\" HOST\n"
    " SG_ cross : 19|12@0+ (1,0) [0|0] \"\" HOST\n"
    " SG_ bit : 42|1@0+ (1,0) [0|0] \"\" HOST\n"
    " SG_ sgn : 55|10@0- (1,0) [0|0] \"\" HOST\n"
    "BO_ 258 Wide: 8 ECU\n"
    " SG_ le64 : 0|64@1+ (1,0) [0|0] \"\" HOST\n"
    "BO_ 259 WideM: 8 ECU\n"
    " SG_ be64 : 7|64@0- (1,0) [0|0] \"\" HOST\n"
    "BO_ 260 Floats: 16 ECU\n"
    " SG_ f32 : 0|32@1- (1,0) [0|0] \"\" HOST\n"
    " SG_ f64 : 71|64@0- (2,1) [0|0] \"\" HOST\n";
static const char LAYOUTS_TYPES[] = "SIG_VALTYPE_ 260 f32 : 1;\nSIG_VALTYPE_ 260 f64 : 2;\n";

static void load_layouts(msid_dbc *d)
{
    static char text[sizeof LAYOUTS + sizeof LAYOUTS_TYPES];
    snprintf(text, sizeof text, "%s%s", LAYOUTS, LAYOUTS_TYPES);
    load(d, text);
}

static void test_intel_layouts(void **st)
{
    (void)st;
    msid_dbc d;
    load_layouts(&d);
    assert_int_equal(d.n_messages, 5);
    assert_int_equal(d.n_signals, 11);
    /* cross: 12 bits from bit 4: byte 0 bits 4..7 hold raw bits 0..3, byte 1 raw bits 4..11.
       raw 0xABC -> byte 0 = 0xC0, byte 1 = 0xAB */
    uint8_t b[8] = {0};
    const msid_dbc_signal *c = sig(&d, "Intel", "cross");
    assert_int_equal(msid_dbc_set_raw(c, 0xABC, b, 8), 0);
    const uint8_t want[8] = {0xC0, 0xAB, 0, 0, 0, 0, 0, 0};
    assert_memory_equal(b, want, 8);
    uint64_t raw = 0;
    assert_int_equal(msid_dbc_get_raw(c, b, 8, &raw), 0);
    assert_int_equal(raw, 0xABC);
    assert_int_equal(msid_dbc_signal_bytes(c), 2);
    /* bit: bit 20 is byte 2, bit 4 (0x10) */
    memset(b, 0, 8);
    assert_int_equal(msid_dbc_encode(sig(&d, "Intel", "bit"), 1.0, b, 8), 0);
    assert_int_equal(b[2], 0x10);
    /* sgn: 12 bits from 24, signed, 0.5 * raw + 10: raw 0x800 = -2048 -> -1014; bytes 3 = 0x00, 4 = 0x08 */
    memset(b, 0, 8);
    b[4] = 0x08;
    double v = 0;
    const msid_dbc_signal *s = sig(&d, "Intel", "sgn");
    assert_int_equal(msid_dbc_decode(s, b, 8, &v), 0);
    assert_true(v == -1014.0);
    assert_string_equal(s->unit, "degC");
    /* raw 0x7FF = 2047 -> 1033.5; encoding -1014 gives the bytes back; the neighbours untouched */
    memset(b, 0xFF, 8);
    assert_int_equal(msid_dbc_encode(s, -1014.0, b, 8), 0);
    const uint8_t want2[8] = {0xFF, 0xFF, 0xFF, 0x00, 0xF8, 0xFF, 0xFF, 0xFF};
    assert_memory_equal(b, want2, 8);
    b[3] = 0xFF;
    b[4] = 0xF7;   /* raw 0x7FF */
    assert_int_equal(msid_dbc_decode(s, b, 8, &v), 0);
    assert_true(v == 1033.5);
}

static void test_motorola_layouts(void **st)
{
    (void)st;
    msid_dbc d;
    load_layouts(&d);
    uint8_t b[8] = {0};
    uint64_t raw = 0;
    /* word: MSB at byte 0 bit 7, 16 bits: raw 0x1234 -> bytes 0x12 0x34 */
    assert_int_equal(msid_dbc_set_raw(sig(&d, "Moto", "word"), 0x1234, b, 8), 0);
    assert_int_equal(b[0], 0x12);
    assert_int_equal(b[1], 0x34);
    /* cross: start 19 = byte 2 bit 3 is the MSB; 12 bits: byte 2 bits 3..0 hold raw bits 11..8, byte 3 bits 7..0
       raw bits 7..0. raw 0xABC -> byte 2 = 0x0A, byte 3 = 0xBC */
    memset(b, 0, 8);
    const msid_dbc_signal *c = sig(&d, "Moto", "cross");
    assert_int_equal(msid_dbc_set_raw(c, 0xABC, b, 8), 0);
    const uint8_t want[8] = {0, 0, 0x0A, 0xBC, 0, 0, 0, 0};
    assert_memory_equal(b, want, 8);
    assert_int_equal(msid_dbc_get_raw(c, b, 8, &raw), 0);
    assert_int_equal(raw, 0xABC);
    assert_int_equal(msid_dbc_signal_bytes(c), 4);
    /* bit: 42 = byte 5 bit 2 (0x04) */
    memset(b, 0, 8);
    assert_int_equal(msid_dbc_set_raw(sig(&d, "Moto", "bit"), 1, b, 8), 0);
    assert_int_equal(b[5], 0x04);
    /* sgn: MSB byte 6 bit 7, 10 bits: byte 6 raw bits 9..2, byte 7 bits 7..6 raw bits 1..0.
       raw 0x201 (-511): byte 6 = 0x80, byte 7 = 0x40 */
    memset(b, 0, 8);
    b[6] = 0x80;
    b[7] = 0x40;
    double v = 0;
    assert_int_equal(msid_dbc_decode(sig(&d, "Moto", "sgn"), b, 8, &v), 0);
    assert_true(v == -511.0);
    /* -1: all ten bits set, the rest of byte 7 unchanged */
    memset(b, 0, 8);
    assert_int_equal(msid_dbc_encode(sig(&d, "Moto", "sgn"), -1.0, b, 8), 0);
    assert_int_equal(b[6], 0xFF);
    assert_int_equal(b[7], 0xC0);
}

static void test_64_bit_signals(void **st)
{
    (void)st;
    msid_dbc d;
    load_layouts(&d);
    uint8_t b[8];
    uint64_t raw = 0;
    /* Intel 64 bits from 0: the payload little endian */
    const uint8_t le[8] = {0xEF, 0xCD, 0xAB, 0x89, 0x67, 0x45, 0x23, 0x01};
    assert_int_equal(msid_dbc_get_raw(sig(&d, "Wide", "le64"), le, 8, &raw), 0);
    assert_true(raw == 0x0123456789ABCDEFull);
    double v = 0;
    memset(b, 0xFF, 8);   /* all ones, unsigned: 2^64 - 1 rounds to 2^64 as a double */
    assert_int_equal(msid_dbc_decode(sig(&d, "Wide", "le64"), b, 8, &v), 0);
    assert_true(v == 18446744073709551616.0);
    /* ... which no longer fits: refused, not clamped */
    assert_int_equal(msid_dbc_encode(sig(&d, "Wide", "le64"), v, b, 8), -MSID_DAQ_E_RANGE);
    assert_int_equal(msid_dbc_encode(sig(&d, "Wide", "le64"), 18446744073709549568.0, b, 8), 0);   /* 2^64 - 2048 */
    assert_int_equal(msid_dbc_get_raw(sig(&d, "Wide", "le64"), b, 8, &raw), 0);
    assert_true(raw == 0xFFFFFFFFFFFFF800ull);
    /* Motorola 64 bits from 7, signed: the payload big endian; 0x8000000000000000 is -2^63 */
    const msid_dbc_signal *m = sig(&d, "WideM", "be64");
    const uint8_t be[8] = {0x80, 0, 0, 0, 0, 0, 0, 0};
    assert_int_equal(msid_dbc_decode(m, be, 8, &v), 0);
    assert_true(v == -9223372036854775808.0);
    memset(b, 0, 8);
    assert_int_equal(msid_dbc_encode(m, -9223372036854775808.0, b, 8), 0);
    assert_memory_equal(b, be, 8);
    assert_int_equal(msid_dbc_encode(m, 9223372036854775808.0, b, 8), -MSID_DAQ_E_RANGE);   /* 2^63 */
    const uint8_t one[8] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFE};
    assert_int_equal(msid_dbc_decode(m, one, 8, &v), 0);
    assert_true(v == -2.0);
    assert_int_equal(msid_dbc_set_raw(m, 0x0102030405060708ull, b, 8), 0);
    const uint8_t seq[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    assert_memory_equal(b, seq, 8);
}

static void test_floats(void **st)
{
    (void)st;
    msid_dbc d;
    load_layouts(&d);
    const msid_dbc_signal *f = sig(&d, "Floats", "f32"), *g = sig(&d, "Floats", "f64");
    assert_int_equal(f->type, MSID_DBC_FLOAT32);
    assert_int_equal(g->type, MSID_DBC_FLOAT64);
    uint8_t b[16] = {0};
    /* 1.5f = 0x3FC00000, Intel: 00 00 C0 3F */
    assert_int_equal(msid_dbc_encode(f, 1.5, b, 16), 0);
    const uint8_t w32[4] = {0x00, 0x00, 0xC0, 0x3F};
    assert_memory_equal(b, w32, 4);
    /* float64 Motorola from bit 71 (byte 8 MSB), 2 x + 1: 4.0 -> raw 1.5 = 0x3FF8000000000000, big endian */
    assert_int_equal(msid_dbc_encode(g, 4.0, b, 16), 0);
    const uint8_t w64[8] = {0x3F, 0xF8, 0, 0, 0, 0, 0, 0};
    assert_memory_equal(b + 8, w64, 8);
    double v = 0;
    assert_int_equal(msid_dbc_decode(g, b, 16, &v), 0);
    assert_true(v == 4.0);
    /* 0.1 as a float32 is 0.100000001490116...: decoded as that float, rounded to nearest on encode */
    assert_int_equal(msid_dbc_encode(f, 0.1, b, 16), 0);
    assert_int_equal(msid_dbc_decode(f, b, 16, &v), 0);
    assert_true(v == (double)0.1f);
    /* beyond float32's range: refused (it would be infinity); NaN refused */
    assert_int_equal(msid_dbc_encode(f, 3.5e38, b, 16), -MSID_DAQ_E_RANGE);
    assert_int_equal(msid_dbc_encode(f, NAN, b, 16), -MSID_DAQ_E_RANGE);
    assert_int_equal(msid_dbc_encode(f, (double)FLT_MAX, b, 16), 0);
    /* a float32 NaN on the bus decodes as NaN */
    const uint8_t nan32[4] = {0x00, 0x00, 0xC0, 0x7F};
    memcpy(b, nan32, 4);
    assert_int_equal(msid_dbc_decode(f, b, 16, &v), 0);
    assert_true(isnan(v));
}

static void test_encode_refuses_and_rounds(void **st)
{
    (void)st;
    static const char text[] = "BO_ 16 M: 8 ECU\n"
                               " SG_ u8 : 0|8@1+ (1,0) [0|0] \"\" HOST\n"
                               " SG_ r : 8|8@1+ (0.5,0) [0|100] \"\" HOST\n"
                               " SG_ s4 : 16|4@1- (1,0) [0|0] \"\" HOST\n"
                               " SG_ deg : 24|8@1+ (1,0) [5|5] \"\" HOST\n";
    msid_dbc d;
    load(&d, text);
    uint8_t b[8] = {0}, keep[8];
    const msid_dbc_signal *u8 = sig(&d, "M", "u8"), *r = sig(&d, "M", "r"), *s4 = sig(&d, "M", "s4");
    assert_int_equal(msid_dbc_encode(u8, 255.0, b, 8), 0);
    memcpy(keep, b, 8);
    assert_int_equal(msid_dbc_encode(u8, 256.0, b, 8), -MSID_DAQ_E_RANGE);   /* not clamped to 255 */
    assert_int_equal(msid_dbc_encode(u8, -1.0, b, 8), -MSID_DAQ_E_RANGE);
    assert_int_equal(msid_dbc_encode(u8, 255.4, b, 8), 0);                   /* rounds to 255 */
    assert_int_equal(msid_dbc_encode(u8, 255.5, b, 8), -MSID_DAQ_E_RANGE);   /* rounds to 256 */
    assert_memory_equal(b, keep, 8);                                         /* refusals leave the payload */
    /* ties to even: 2.5 -> 2, 3.5 -> 4 */
    assert_int_equal(msid_dbc_encode(u8, 2.5, b, 8), 0);
    assert_int_equal(b[0], 2);
    assert_int_equal(msid_dbc_encode(u8, 3.5, b, 8), 0);
    assert_int_equal(b[0], 4);
    /* the DBC's range [0|100] (raw 200 of 255 possible): 100 encodes, 100.5 is refused though it fits */
    assert_int_equal(msid_dbc_encode(r, 100.0, b, 8), 0);
    assert_int_equal(b[1], 200);
    assert_int_equal(msid_dbc_encode(r, 100.5, b, 8), -MSID_DAQ_E_RANGE);
    assert_int_equal(msid_dbc_encode(r, -0.25, b, 8), -MSID_DAQ_E_RANGE);
    assert_int_equal(msid_dbc_encode(r, 100.0000004, b, 8), 0);   /* within |factor| 1e-6 of the bound */
    /* a degenerate range [5|5] is no range: 200 encodes */
    assert_int_equal(msid_dbc_encode(sig(&d, "M", "deg"), 200.0, b, 8), 0);
    /* signed 4 bits: -8..7 */
    assert_int_equal(msid_dbc_encode(s4, -8.0, b, 8), 0);
    assert_int_equal(b[2] & 0x0F, 0x8);
    assert_int_equal(msid_dbc_encode(s4, 7.0, b, 8), 0);
    assert_int_equal(msid_dbc_encode(s4, 8.0, b, 8), -MSID_DAQ_E_RANGE);
    assert_int_equal(msid_dbc_encode(s4, -9.0, b, 8), -MSID_DAQ_E_RANGE);
    /* raw helpers: bits above the length refused */
    assert_int_equal(msid_dbc_set_raw(s4, 0x10, b, 8), -MSID_DAQ_E_RANGE);
    /* a payload shorter than the signal */
    double v;
    assert_int_equal(msid_dbc_decode(s4, b, 2, &v), -MSID_DAQ_E_SHORT);
    assert_int_equal(msid_dbc_encode(s4, 1.0, b, 2), -MSID_DAQ_E_SHORT);
    assert_int_equal(msid_dbc_decode(s4, b, 3, &v), 0);
}

static void test_multiplexing(void **st)
{
    (void)st;
    static const char text[] = "BO_ 514 STATUS: 8 DEVICE\n"
                               " SG_ mux M : 0|8@1+ (1,0) [0|255] \"\" HOST\n"
                               " SG_ plain : 56|8@1+ (1,0) [0|255] \"\" HOST\n"
                               " SG_ state m0 : 8|8@1+ (1,0) [0|255] \"\" HOST\n"
                               " SG_ crc m1 : 8|32@1+ (1,0) [0|4294967295] \"\" HOST\n";
    msid_dbc d;
    load(&d, text);
    const msid_dbc_message *m = msid_dbc_message_by_id(&d, 514);
    assert_non_null(m);
    assert_int_equal(m->mux_signal, (int32_t)m->first_signal);
    const msid_dbc_signal *mux = sig(&d, "STATUS", "mux"), *st0 = sig(&d, "STATUS", "state"),
                          *crc = sig(&d, "STATUS", "crc"), *pl = sig(&d, "STATUS", "plain");
    assert_int_equal(mux->mux, MSID_DBC_SWITCH);
    assert_int_equal(st0->mux, MSID_DBC_MUXED);
    assert_int_equal(crc->mux_value, 1);
    uint8_t b[8] = {1, 0x78, 0x56, 0x34, 0x12, 0, 0, 9};
    assert_int_equal(msid_dbc_present(&d, crc, b, 8), 1);
    assert_int_equal(msid_dbc_present(&d, st0, b, 8), 0);
    assert_int_equal(msid_dbc_present(&d, pl, b, 8), 1);
    assert_int_equal(msid_dbc_present(&d, mux, b, 8), 1);
    double v;
    assert_int_equal(msid_dbc_decode(crc, b, 8, &v), 0);
    assert_true(v == (double)0x12345678u);
    b[0] = 0;
    assert_int_equal(msid_dbc_present(&d, crc, b, 8), 0);
    assert_int_equal(msid_dbc_present(&d, st0, b, 8), 1);
    assert_int_equal(msid_dbc_present(&d, st0, b, 0), -MSID_DAQ_E_SHORT);
}

static void test_ids_fd_and_cycle_times(void **st)
{
    (void)st;
    /* 2147483898 = 0x800000FA: extended 0xFA; 2566848512 = 0x98FF0000: extended 0x18FF0000.
       The FD message is 64 bytes, its last signal in the last byte (bits 504..511). The CM_ string runs over
       three lines and holds ';' and text that looks like statements; BA_DEF_ defines the cycle time,
       BA_DEF_DEF_ gives 100 ms, BA_ gives message 256 10 ms. */
    static const char text[] =
        "VERSION \"x\"\n"
        "BU_: A B\n"
        "VAL_TABLE_ States 1 \"on\" 0 \"off\" ;\n"
        "BO_ 256 Std: 8 A\n"
        " SG_ a : 0|8@1+ (1,0) [0|0] \"\" B\n"
        "BO_ 2147483898 ExtSmall: 8 A\n"
        " SG_ a : 0|8@1+ (1,0) [0|0] \"\" B\n"
        "BO_ 2566848512 J1939: 8 A\n"
        " SG_ a : 0|8@1+ (1,0) [0|0] \"\" B\n"
        "BO_ 250 StdFA: 8 A\n"
        " SG_ a : 0|8@1+ (1,0) [0|0] \"\" B\n"
        "BO_ 1792 Fd: 64 A\n"
        " SG_ last : 504|8@1+ (1,0) [0|0] \"\" B\n"
        " SG_ first : 7|8@0+ (1,0) [0|0] \"\" B\n"
        "BO_ 3221225472 VECTOR__INDEPENDENT_SIG_MSG: 0 Vector__XXX\n"
        " SG_ orphan : 0|8@1+ (1,0) [0|0] \"\" B\n"
        "\n"
        "CM_ BO_ 256 \"first line; with a semicolon\n"
        "BO_ 999 NotAMessage: 8 A\n"
        " and an escaped \\\" quote\";\n"
        "CM_ \"file comment\";\n"
        "BA_DEF_ BO_  \"GenMsgCycleTime\" INT 0 65535;\n"
        "BA_DEF_ SG_  \"Other\" ENUM  \"a\",\"b\";\n"
        "BA_DEF_DEF_  \"GenMsgCycleTime\" 100;\n"
        "BA_DEF_DEF_  \"Other\" \"a\";\n"
        "BA_ \"GenMsgCycleTime\" BO_ 256 10;\n"
        "BA_ \"Other\" SG_ 256 a 1;\n"
        "VAL_ 256 a 1 \"on\" 0 \"off\" ;\n"
        "EV_ v: 0 [0|1] \"\" 0 1 DUMMY_NODE_VECTOR0 Vector__XXX;\n";
    msid_dbc d;
    load(&d, text);
    assert_int_equal(d.n_messages, 5);   /* the independent-signals message is left out */
    assert_null(msid_dbc_message_by_name(&d, "NotAMessage"));
    assert_null(msid_dbc_message_by_name(&d, "VECTOR__INDEPENDENT_SIG_MSG"));
    const msid_dbc_message *e = msid_dbc_message_by_id(&d, 0xFAu | MSID_CAN_EFF_FLAG);
    assert_non_null(e);
    assert_string_equal(e->name, "ExtSmall");
    assert_string_equal(msg_id(&d, 0xFAu)->name, "StdFA");
    assert_string_equal(msg_id(&d, 0x18FF0000u | MSID_CAN_EFF_FLAG)->name, "J1939");
    assert_null(msid_dbc_message_by_id(&d, 0x18FF0000u));
    assert_null(msid_dbc_message_by_id(&d, 0x101u));
    const msid_dbc_message *fd = msg_name(&d, "Fd");
    assert_int_equal(fd->dlc, 64);
    assert_int_equal(msid_dbc_signal_bytes(sig(&d, "Fd", "last")), 64);
    uint8_t b[64] = {0};
    b[63] = 0xA5;
    double v;
    assert_int_equal(msid_dbc_decode(sig(&d, "Fd", "last"), b, 64, &v), 0);
    assert_true(v == 165.0);
    assert_int_equal(msid_dbc_decode(sig(&d, "Fd", "last"), b, 48, &v), -MSID_DAQ_E_SHORT);
    assert_int_equal(msg_name(&d, "Std")->cycle_ms, 10);
    assert_int_equal(msg_name(&d, "J1939")->cycle_ms, 100);
    assert_string_equal(msg_name(&d, "Std")->sender, "A");
    assert_int_equal(msg_name(&d, "Fd")->line, 12);
    /* without the BA_DEF_ (as cantools) there is no cycle time */
    load(&d, "BO_ 256 Std: 8 A\nBA_DEF_DEF_ \"GenMsgCycleTime\" 100;\nBA_ \"GenMsgCycleTime\" BO_ 256 10;\n");
    assert_int_equal(msg_name(&d, "Std")->cycle_ms, 0);
    /* the names are in the arena: the text can go */
    char copy[64];
    snprintf(copy, sizeof copy, "BO_ 5 Gone: 1 X\n SG_ s : 0|8@1+ (1,0) [0|0] \"V\" Y\n");
    load(&d, copy);
    memset(copy, 0, sizeof copy);
    assert_string_equal(d.messages[0].name, "Gone");
    assert_string_equal(d.signals[0].unit, "V");
}

/* What production files write beside the grammar: // comment lines, one node per line after BU_, a bare
   'm' indicator in a message without a switch (a plain signal, as cantools reads it), one signal name in
   two multiplexed branches (daq/can/msid.dbc's MSID_EST.index). */
static void test_what_real_files_write(void **st)
{
    (void)st;
    static const char text[] = "// written by a tool\n"
                               "BU_:\n"
                               "\tNEO\n"
                               "\tMCU\n"
                               "BO_ 1 M: 8 NEO // the sender\n"
                               " SG_ code m : 6|2@1+ (1,0) [0|3] \"\" MCU\n"
                               "BO_ 2 EST: 8 MCU\n"
                               " SG_ mux M : 0|8@1+ (1,0) [0|255] \"\" NEO\n"
                               " SG_ index m16 : 8|24@1+ (1,0) [0|0] \"\" NEO\n"
                               " SG_ index m17 : 8|24@1+ (1,0) [0|0] \"\" NEO\n";
    msid_dbc d;
    load(&d, text);
    assert_int_equal(d.n_messages, 2);
    assert_int_equal(sig(&d, "M", "code")->mux, MSID_DBC_PLAIN);
    assert_string_equal(msg_name(&d, "M")->sender, "NEO");
    assert_int_equal(msg_name(&d, "EST")->n_signals, 3);
    assert_int_equal(sig(&d, "EST", "index")->mux_value, 16);   /* the first of the name */
    refused("BO_ 1 M: 8 A\n SG_ a M : 0|8@1+ (1,0) [0|0] \"\" B\n SG_ b m : 8|8@1+ (1,0) [0|0] \"\" B\n", 3,
            "'m' without a value");
    refused("BO_ 1 M: 8 A\n SG_ a M : 0|8@1+ (1,0) [0|0] \"\" B\n SG_ b m1 : 8|8@1+ (1,0) [0|0] \"\" B\n"
            " SG_ b m1 : 16|8@1+ (1,0) [0|0] \"\" B\n",
            4, "two signals named b");
}

static void test_many_messages_sorted(void **st)
{
    (void)st;
    /* 200 messages in a scrambled order: every one found by id and by name */
    static char text[200 * 64];
    size_t n = 0;
    for (unsigned k = 0; k < 200; ++k) {
        const unsigned id = (k * 73u) % 200u + ((k & 1) ? 0x80000000u + 0x10000u : 0u);
        n += (size_t)snprintf(text + n, sizeof text - n, "BO_ %u M%u: 8 A\n SG_ s : 0|8@1+ (1,0) [0|0] \"\" B\n", id, id);
    }
    msid_dbc d;
    load(&d, text);
    assert_int_equal(d.n_messages, 200);
    for (unsigned k = 0; k < 200; ++k) {
        const unsigned id = (k * 73u) % 200u + ((k & 1) ? 0x80000000u + 0x10000u : 0u);
        const uint32_t cid = (id & 0x80000000u) ? (id & 0x1FFFFFFFu) | MSID_CAN_EFF_FLAG : id;
        const msid_dbc_message *m = msid_dbc_message_by_id(&d, cid);
        assert_non_null(m);
        char nm[32];
        snprintf(nm, sizeof nm, "M%u", id);
        assert_string_equal(m->name, nm);
        assert_ptr_equal(msid_dbc_message_by_name(&d, nm), m);
    }
    assert_null(msid_dbc_message_by_name(&d, "M"));
}

static void test_numbers_in_any_locale(void **st)
{
    (void)st;
    /* a caller's setlocale() with a decimal comma must not change what "0.5" reads as */
    const char *loc = setlocale(LC_NUMERIC, "de_DE.UTF-8");
    if (!loc) loc = setlocale(LC_NUMERIC, "fr_FR.UTF-8");
    msid_dbc d;
    load(&d, "BO_ 1 M: 8 A\n SG_ s : 0|8@1+ (0.5,-1.25e1) [-1E+1|1.5e2] \"\" B\n");
    assert_true(d.signals[0].factor == 0.5);
    assert_true(d.signals[0].offset == -12.5);
    assert_true(d.signals[0].min == -10.0 && d.signals[0].max == 150.0);
    setlocale(LC_NUMERIC, "C");
    if (!loc) print_message("(no locale with a decimal comma installed: checked in the C locale only)\n");
}

static void test_malformed_files_name_their_line(void **st)
{
    (void)st;
    refused("BO_ 1 M: 8 A\n SG_ s : 0|8@1+ (1,0) [0|0] \"\" B\nBO_ x", 3, "message identifier");
    refused("VERSION \"\"\n\nBO_ 1 M: 8 A\n SG_ s : 0|8@2+ (1,0) [0|0] \"\" B\n", 4, "byte order");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|0@1+ (1,0) [0|0] \"\" B\n", 2, "length 0 is not 1..64");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|65@1+ (1,0) [0|0] \"\" B\n", 2, "length 65");
    refused("BO_ 1 M: 8 A\n SG_ s : 60|8@1+ (1,0) [0|0] \"\" B\n", 2, "leave the 8-byte payload");
    refused("BO_ 1 M: 2 A\n SG_ s : 7|17@0+ (1,0) [0|0] \"\" B\n", 2, "leave the 2-byte payload");
    refused("BO_ 1 M: 65 A\n", 1, "longer than a CAN FD frame");
    refused("BO_ 2048 M: 8 A\n", 1, "standard identifier 0x800 is beyond 0x7FF");
    refused("BO_ 3758096384 M: 8 A\n", 1, "extended identifier");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|8@1+ (0,0) [0|0] \"\" B\n", 2, "factor of 0");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|8@1+ (1,0) [0|0] \"\" B\n SG_ s : 8|8@1+ (1,0) [0|0] \"\" B\n", 3,
            "two signals named s");
    refused("BO_ 1 M: 8 A\nBO_ 2 N: 8 A\nBO_ 1 O: 8 A\n", 3, "has the identifier of message M (line 1)");
    refused("BO_ 1 M: 8 A\nBO_ 2 M: 8 A\n", 2, "two messages are named M");
    refused(" SG_ s : 0|8@1+ (1,0) [0|0] \"\" B\n", 1, "before any BO_");
    refused("BO_ 1 M: 8 A\n SG_ s m1 : 0|8@1+ (1,0) [0|0] \"\" B\n", 2, "no multiplexer");
    refused("BO_ 1 M: 8 A\n SG_ a M : 0|8@1+ (1,0) [0|0] \"\" B\n SG_ b M : 8|8@1+ (1,0) [0|0] \"\" B\n", 3,
            "extended multiplexing");
    refused("BO_ 1 M: 8 A\n SG_ a M : 0|8@1+ (1,0) [0|0] \"\" B\n SG_ b m1M : 8|8@1+ (1,0) [0|0] \"\" B\n", 3,
            "extended multiplexing");
    refused("BO_ 1 M: 8 A\n SG_ a M : 0|8@1+ (1,0) [0|0] \"\" B\n\nSG_MUL_VAL_ 1 a a 1-1;\n", 4,
            "SG_MUL_VAL_: extended multiplexing is not supported");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|16@1+ (1,0) [0|0] \"\" B\nSIG_VALTYPE_ 1 s : 1;\n", 3, "float32 of 16 bits");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|16@1+ (1,0) [0|0] \"\" B\nSIG_VALTYPE_ 1 t : 1;\n", 3, "does not define");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|8@1+ (1,x) [0|0] \"\" B\n", 2, "the offset");
    refused("BO_ 1 M: 8 A\n SG_ s : 0|8@1+ (1,0) [0|0] \"unit B\n", 2, "not closed");
    refused("CM_ \"no end\"\n\nBO_ 1 M: 8 A\n", 1, "CM_ statement is not ended by ';'");
    refused("BO_ 1 M: 8 A\nFOO_ 1;\n", 2, "unknown keyword 'FOO_'");
    refused("BO_ 1 M: 8 A junk\n", 1, "unexpected 'j'");
    refused("BA_DEF_ BO_ \"GenMsgCycleTime\" INT 0 1;\nBA_ \"GenMsgCycleTime\" BO_ 1 1.5;\n", 2,
            "not a whole number");
    /* mem_size refuses what init refuses for its syntax; init with no memory still names the line */
    const char *bad = "BO_ 1 M: 8 A\n SG_ s : 0|8@3+ (1,0) [0|0] \"\" B\n";
    assert_int_equal(msid_dbc_mem_size(bad, strlen(bad)), 0);
    msid_dbc d;
    assert_int_equal(msid_dbc_init(&d, bad, strlen(bad), NULL, 0), -MSID_DAQ_E_FORMAT);
    assert_int_equal(d.err_line, 2);
    /* too little or misaligned memory */
    const char *good = "BO_ 1 M: 8 A\n SG_ s : 0|8@1+ (1,0) [0|0] \"\" B\n";
    const size_t need = msid_dbc_mem_size(good, strlen(good));
    assert_true(need > 0);
    assert_int_equal(msid_dbc_init(&d, good, strlen(good), MEM, need - 1), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_dbc_init(&d, good, strlen(good), MEM + 4, need), -MSID_DAQ_E_ARG);
    assert_int_equal(msid_dbc_init(&d, good, strlen(good), MEM, need), 0);
    /* an empty text is a DBC of no messages */
    assert_int_equal(msid_dbc_init(&d, "", 0, MEM, sizeof MEM), 0);
    assert_int_equal(d.n_messages, 0);
    assert_null(msid_dbc_message_by_id(&d, 1));
}

int main(void)
{
    const struct CMUnitTest t[] = {
        cmocka_unit_test(test_intel_layouts),
        cmocka_unit_test(test_motorola_layouts),
        cmocka_unit_test(test_64_bit_signals),
        cmocka_unit_test(test_floats),
        cmocka_unit_test(test_encode_refuses_and_rounds),
        cmocka_unit_test(test_multiplexing),
        cmocka_unit_test(test_ids_fd_and_cycle_times),
        cmocka_unit_test(test_what_real_files_write),
        cmocka_unit_test(test_many_messages_sorted),
        cmocka_unit_test(test_numbers_in_any_locale),
        cmocka_unit_test(test_malformed_files_name_their_line),
    };
    return cmocka_run_group_tests(t, NULL, NULL);
}
