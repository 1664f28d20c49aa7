/* daq/: msid-can/1 codec, configuration upload, candump log format, and the
 * frame decoder feeding msid_meas - no kernel needed (frames are built here). */
#define _GNU_SOURCE
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <unistd.h>

#include "msid/msid.h"
#include "msid_daq/msid_can_decoder.h"
#include "msid_daq/msid_params.h"
#include "msid_daq/msid_candump.h"

/* Candump logs and CSV records of a long run pass 2 GiB. On 32-bit Linux (armhf) glibc's stat, fstat and
 * ftello fail on such a file with EOVERFLOW unless off_t is 64 bits (measured under qemu-arm: stat of a
 * 3 GiB file gave EOVERFLOW with a 4-byte off_t and 3221225472 bytes with an 8-byte one); CMakeLists.txt
 * makes it 64 bits for every Linux target. */
_Static_assert(sizeof(off_t) == 8, "file offsets must be 64 bits (_FILE_OFFSET_BITS=64)");

#define BASE 0x200u
#define P 32u
#define NU 2u
#define NY 2u
#define C (NU + NY)
#define KP 5u          /* periods per experiment */
#define M 2u

static const uint32_t BINS[3] = {1, 3, 5};

/* ---- codec ---------------------------------------------------------------- */

static void codec_roundtrip(void **st)
{
    (void)st;
    double row[32], back[32];
    for (int c = 0; c < 32; ++c) row[c] = 0.37 * (c - 15) + 0.00049;
    for (uint32_t enc = 0; enc < 2; ++enc)
        for (uint32_t fd = 0; fd < 2; ++fd) {
            const uint32_t n = 16, chunks = msid_can_chunks(n, enc, fd);
            memset(back, 0, sizeof back);
            for (uint32_t k = 0; k < chunks; ++k) {
                uint8_t d[64];
                msid_can_encode_sample(d, enc, fd, k, 0x123456u, 5, MSID_CAN_PSTART, row, n, 0.001);
                assert_int_equal(d[0] | d[1] << 8 | d[2] << 16, 0x123456);
                assert_int_equal(d[3], 5 | MSID_CAN_PSTART);
                msid_can_decode_values(d, enc, fd, k, back, n, 0.001);
            }
            for (uint32_t c = 0; c < n; ++c) {
                if (enc == MSID_CAN_ENC_F32) assert_true(back[c] == (double)(float)row[c]);
                else assert_true(fabs(back[c] - row[c]) <= 0.0005 + 1e-12);
            }
        }
    /* out of int16 range and NaN decode as NaN (the period is then rejected, never clipped) */
    double big[2] = {40.0, NAN}, out[2];
    uint8_t d[8];
    msid_can_encode_sample(d, MSID_CAN_ENC_S16, 0, 0, 0, 0, 0, big, 2, 0.001);
    msid_can_decode_values(d, MSID_CAN_ENC_S16, 0, 0, out, 2, 0.001);
    assert_true(isnan(out[0]) && isnan(out[1]));
    /* identifiers */
    uint32_t e, f, k;
    assert_true(msid_can_classify_sample(MSID_CAN_ID_FD_F32 + 2, &e, &f, &k) && e == 1 && f == 1 && k == 2);
    assert_false(msid_can_classify_sample(MSID_CAN_ID_FD_F32 + 3, &e, &f, &k));
    assert_int_equal(msid_can_chunks(4, MSID_CAN_ENC_S16, 0), 2);
    assert_int_equal(msid_can_chunks(16, MSID_CAN_ENC_F32, 1), 2);
    /* CRC-32 check value */
    assert_int_equal(msid_can_crc32(0, (const uint8_t *)"123456789", 9), 0xCBF43926u);
}

static msid_params CFG, RX;

static void fill_config(msid_params *c, int ct)
{
    memset(c, 0, sizeof *c);
    c->period = 64; c->n_lines = 3; c->n_inputs = 2; c->n_experiments = 2;
    c->pattern = MSID_PATTERN_DFT; c->phase_mode = ct ? MSID_PHASE_USER : MSID_PHASE_RANDOM;
    c->seed = 0x123456789ull;
    for (uint32_t l = 0; l < 3; ++l) {
        c->bins[l] = BINS[l];
        c->omega[l] = 2 * M_PI * (l + 1) / (64 * 0.01);
    }
    c->is_ct = ct;
    c->sample_time = 0.01;
    c->have_amp = 1;
    c->have_phase = ct;
    for (uint32_t k = 0; k < 6; ++k) { c->amp[k] = 0.5 + 0.1 * k; c->phase[k] = 0.01 * k; }
    c->encoding = 1; c->scale = 0.002f; c->fd = 1; c->rate_hz = 1000; c->periods = 7;
}

static void config_upload(void **st)
{
    (void)st;
    uint8_t fr[200][8];
    for (int ct = 0; ct < 2; ++ct) {
        fill_config(&CFG, ct);
        const size_t n = msid_params_frames(&CFG, NULL, 0);
        assert_true(n > 10 && n <= 200);
        assert_int_equal(msid_params_frames(&CFG, fr, 200), n);
        msid_params_reset(&RX);
        for (size_t i = 0; i + 1 < n; ++i) assert_int_equal(msid_params_feed(&RX, fr[i], 8, 1), 0);
        assert_int_equal(msid_params_feed(&RX, fr[n - 1], 8, 1), 1);
        assert_int_equal(RX.period, 64);
        assert_int_equal(RX.is_ct, ct);
        assert_true(RX.seed == CFG.seed && RX.scale == CFG.scale && RX.periods == 7 && RX.rate_hz == 1000);
        assert_memory_equal(RX.amp, CFG.amp, 6 * sizeof(double));
        if (ct) assert_memory_equal(RX.omega, CFG.omega, 3 * sizeof(double));
        else assert_memory_equal(RX.bins, CFG.bins, 3 * sizeof(uint32_t));
        /* a lost frame or a flipped bit: the COMMIT's CRC does not match */
        msid_params_reset(&RX);
        for (size_t i = 0; i + 1 < n; ++i)
            if (i != 5) msid_params_feed(&RX, fr[i], 8, 1);
        assert_int_equal(msid_params_feed(&RX, fr[n - 1], 8, 1), -MSID_CAN_ERR_CRC);
        msid_params_reset(&RX);
        fr[4][6] ^= 1;
        for (size_t i = 0; i + 1 < n; ++i) msid_params_feed(&RX, fr[i], 8, 1);
        assert_int_equal(msid_params_feed(&RX, fr[n - 1], 8, 1), -MSID_CAN_ERR_CRC);
        /* regression: a valid CRC does not make an absurd count acceptable. An upload asking
           for 5,000,000 periods (replay sized 4.58 GB from a 7 KB log), 1 period, or a period beyond
           MSID_MAX_PERIOD is refused at COMMIT; 100000 periods is the limit */
        const uint32_t bad_periods[] = {5000000u, 1u, MSID_PARAMS_MAX_PERIODS + 1u};
        for (int b = 0; b < 4; ++b) {
            static msid_params big;
            big = CFG;
            if (b < 3) big.periods = bad_periods[b]; else big.period = MSID_MAX_PERIOD + 1u;
            uint8_t fb[200][8];
            const size_t nb = msid_params_frames(&big, fb, 200);
            msid_params_reset(&RX);
            for (size_t i = 0; i + 1 < nb; ++i) msid_params_feed(&RX, fb[i], 8, 1);
            assert_int_equal(msid_params_feed(&RX, fb[nb - 1], 8, 1), -MSID_CAN_ERR_CFG);
        }
        {
            static msid_params lim;
            lim = CFG;
            lim.periods = MSID_PARAMS_MAX_PERIODS;
            uint8_t fb[200][8];
            const size_t nb = msid_params_frames(&lim, fb, 200);
            msid_params_reset(&RX);
            for (size_t i = 0; i + 1 < nb; ++i) msid_params_feed(&RX, fb[i], 8, 1);
            assert_int_equal(msid_params_feed(&RX, fb[nb - 1], 8, 1), 1);
        }
        /* another protocol version is refused at BEGIN */
        assert_int_equal(msid_params_feed(&RX, fr[0], 8, 2), -MSID_CAN_ERR_VERSION);
        assert_int_equal(msid_params_feed(&RX, fr[1], 8, 1), -MSID_CAN_ERR_CFG);
        assert_int_equal(msid_params_feed(&RX, fr[0], 5, 1), -MSID_CAN_ERR_CFG);
    }
}

/* ---- candump format ------------------------------------------------------ */

static void candump_lines(void **st)
{
    (void)st;
    msid_can_frame f = {0}, g;
    char buf[256], ifn[32];
    f.id = 0x212; f.len = 8; f.t_ns = 1700000000123456000ull;
    for (int i = 0; i < 8; ++i) f.data[i] = (uint8_t)(0x11 * i);
    assert_true(msid_candump_format(buf, sizeof buf, &f, "vcan0") > 0);
    assert_string_equal(buf, "(1700000000.123456) vcan0 212#0011223344556677 R\n");
    assert_int_equal(msid_candump_parse(buf, &g, ifn, sizeof ifn), 0);
    assert_int_equal(g.id, 0x212); assert_int_equal(g.len, 8); assert_memory_equal(g.data, f.data, 8);
    assert_true(g.t_ns == f.t_ns);
    assert_string_equal(ifn, "vcan0");
    f.id = 0x248; f.len = 64; f.flags = MSID_CANF_FD | MSID_CANF_BRS;
    for (int i = 0; i < 64; ++i) f.data[i] = (uint8_t)(255 - i);
    msid_candump_format(buf, sizeof buf, &f, "can1");
    assert_non_null(strstr(buf, " can1 248##1FFFEFD"));
    assert_int_equal(msid_candump_parse(buf, &g, ifn, sizeof ifn), 0);
    assert_true(g.flags == (MSID_CANF_FD | MSID_CANF_BRS) && g.len == 64 && !memcmp(g.data, f.data, 64));
    f.id = MSID_CAN_ERR_FLAG | 0x40u; f.len = 8; f.flags = 0;
    msid_candump_format(buf, sizeof buf, &f, "vcan0");
    assert_non_null(strstr(buf, " 20000040#"));
    assert_int_equal(msid_candump_parse(buf, &g, ifn, sizeof ifn), 0);
    assert_int_equal(g.id, MSID_CAN_ERR_FLAG | 0x40u);
    f.id = MSID_CAN_EFF_FLAG | 0x1ABCDEF0u; f.len = 2;
    msid_candump_format(buf, sizeof buf, &f, "vcan0");
    assert_int_equal(msid_candump_parse(buf, &g, ifn, sizeof ifn), 0);
    assert_int_equal(g.id, MSID_CAN_EFF_FLAG | 0x1ABCDEF0u);
    /* regressions: an RTR frame keeps its length (123#R8), an error frame read from a
       log keeps only the error flag and its class bits */
    memset(&f, 0, sizeof f);
    f.id = MSID_CAN_RTR_FLAG | 0x123u; f.len = 8;
    msid_candump_format(buf, sizeof buf, &f, "vcan0");
    assert_non_null(strstr(buf, " 123#R8 R\n"));
    assert_int_equal(msid_candump_parse(buf, &g, ifn, sizeof ifn), 0);
    assert_true(g.id == (MSID_CAN_RTR_FLAG | 0x123u) && g.len == 8);
    f.len = 0;
    msid_candump_format(buf, sizeof buf, &f, "vcan0");
    assert_non_null(strstr(buf, " 123#R R\n"));
    assert_int_equal(msid_candump_parse("(1.0) vcan0 E0000044#0004000000000000\n", &g, ifn, sizeof ifn), 0);
    assert_int_equal(g.id, MSID_CAN_ERR_FLAG | 0x44u);
    assert_int_equal(msid_candump_parse("   \n", &g, ifn, sizeof ifn), 1);
    /* direction: T sets MSID_CANF_TX and is written back, R and none are received frames,
       an error frame carries none; python-can's remote frame line "123#R T" reads too */
    memset(&f, 0, sizeof f);
    f.id = 0x201; f.len = 2; f.flags = MSID_CANF_TX;
    msid_candump_format(buf, sizeof buf, &f, "vcan0");
    assert_non_null(strstr(buf, " 201#0000 T\n"));
    assert_int_equal(msid_candump_parse(buf, &g, ifn, sizeof ifn), 0);
    assert_true(g.flags == MSID_CANF_TX && g.id == 0x201 && g.len == 2);
    assert_int_equal(msid_candump_parse("(1.000000) vcan0 212#0011 R\n", &g, ifn, sizeof ifn), 0);
    assert_true(g.flags == 0 && g.len == 2);
    assert_int_equal(msid_candump_parse("(1.000000) vcan0 212#0011\n", &g, ifn, sizeof ifn), 0);
    assert_true(g.flags == 0 && g.len == 2);
    assert_int_equal(msid_candump_parse("(1.000000) vcan0 123#R T\n", &g, ifn, sizeof ifn), 0);
    assert_true(g.id == (MSID_CAN_RTR_FLAG | 0x123u) && g.flags == MSID_CANF_TX);
    assert_int_equal(msid_candump_parse("(1.000000) vcan0 248##1AABB T\r\n", &g, ifn, sizeof ifn), 0);
    assert_true(g.flags == (MSID_CANF_FD | MSID_CANF_BRS | MSID_CANF_TX) && g.len == 2);
    assert_int_equal(msid_candump_parse("(1.000000) vcan0 20000040#00 T\n", &g, ifn, sizeof ifn), 0);
    assert_true(g.flags == 0);
    f.id = MSID_CAN_ERR_FLAG | 0x40u; f.len = 1; f.flags = MSID_CANF_TX;
    msid_candump_format(buf, sizeof buf, &f, "vcan0");
    assert_non_null(strstr(buf, " 20000040#00\n"));
    static const char *bad[] = {
        "1700000000.1 vcan0 212#00\n", "(1700000000.1) vcan0 2123#00\n", "(1700000000.1) vcan0 212#0\n",
        "(1700000000.1) vcan0 212#001122334455667788\n", "(1700000000.1) vcan0 212##G00\n",
        "(x) vcan0 212#00\n", "(1700000000.1) vcan0 800#00\n", "(1700000000.1)  212#00\n",
        "(1700000000.1) vcan0 212#00 garbage\n", "(1700000000.1) vcan0 212\n",
        "(1700000000.1) vcan0 212#00T\n", "(1700000000.1) vcan0 212#00 TR\n", "(1700000000.1) vcan0 212#00 T x\n",
        "(1700000000.1) vcan0 123#RT\n"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i)
        assert_int_equal(msid_candump_parse(bad[i], &g, ifn, sizeof ifn), -MSID_DAQ_E_FORMAT);
}

static void candump_replay(void **st)
{
    (void)st;
    char path[] = "/tmp/msid-candump-XXXXXX";
    const int fd = mkstemp(path);
    assert_true(fd >= 0);
    FILE *fp = fdopen(fd, "w");
    msid_can_frame f = {0};
    char buf[256];
    for (int i = 0; i < 100; ++i) {
        f.id = 0x210u + (uint32_t)(i % 3); f.len = (uint8_t)(i % 9); f.t_ns = (uint64_t)i * 1000;
        for (int b = 0; b < 8; ++b) f.data[b] = (uint8_t)(i + b);
        msid_candump_format(buf, sizeof buf, &f, "vcan0");
        fputs(buf, fp);
    }
    fputs("(0000000001.000000) vcan0 not-a-frame\n", fp);
    fclose(fp);
    msid_candump_reader r;
    assert_int_equal(msid_candump_open(&r, path), 0);
    msid_can_frame got[64];
    int total = 0, k;
    while ((k = msid_can_recv(&r.tr, got, 64, 0)) > 0) {
        for (int i = 0; i < k; ++i) {
            assert_int_equal(got[i].len, (total + i) % 9);
            if (got[i].len) assert_int_equal(got[i].data[0], (uint8_t)(total + i));
        }
        total += k;
    }
    assert_int_equal(total, 100);
    assert_int_equal(k, -MSID_DAQ_E_FORMAT);
    assert_non_null(strstr(msid_can_error(&r.tr), "line 101"));
    assert_int_equal(msid_can_send(&r.tr, &f, 0), -MSID_DAQ_E_ARG);
    msid_candump_rewind(&r);
    assert_int_equal(msid_can_recv(&r.tr, got, 10, 0), 10);
    msid_can_close(&r.tr);
    unlink(path);
    assert_int_equal(msid_candump_open(&r, "/nonexistent/x.log"), -MSID_DAQ_E_IO);
}

/* ---- decoder ---------------------------------------------------------------- */

typedef struct bench {
    msid_twiddle tw;
    msid_meas ms;
    msid_can_decoder dec;
    void *mt, *mm, *md;
} bench;

static void *amem(size_t n) { return aligned_alloc(64, (n + 63) / 64 * 64); }

static void bench_init(bench *b, uint32_t enc, uint32_t fd, uint32_t window)
{
    b->mt = amem(msid_twiddle_mem_size(P));
    assert_int_equal(msid_twiddle_init(&b->tw, P, b->mt, msid_twiddle_mem_size(P)), MSID_OK);
    msid_meas_cfg mc = {0};
    mc.period = P; mc.n_inputs = NU; mc.n_outputs = NY; mc.n_experiments = M; mc.n_lines = 3; mc.bins = BINS;
    mc.twiddle = &b->tw; mc.path = MSID_DFT_STREAM; mc.skip_periods = 0; mc.max_periods = 0;
    const size_t n = msid_meas_mem_size(&mc);
    b->mm = amem(n);
    assert_int_equal(msid_meas_init(&b->ms, &mc, b->mm, n), MSID_OK);
    msid_can_decoder_cfg dc = {BASE, NU, NY, enc, fd, 0.001, P, window, 7, &b->ms};
    const size_t nd = msid_can_decoder_mem_size(&dc);
    assert_true(nd > 0);
    b->md = amem(nd);
    assert_int_equal(msid_can_decoder_init(&b->dec, &dc, b->md, nd), MSID_OK);
}

static void bench_free(bench *b) { free(b->mt); free(b->mm); free(b->md); }

/* Sample value: float-exact so that the float32 encoding is lossless. */
static double value(uint32_t e, uint64_t n, uint32_t c)
{
    const double x = sin(0.3 * (double)n * (c + 1) + e) + 0.01 * (double)((n * 7919 + c * 31 + e) % 97);
    return (double)(float)x;
}

/* The device's frames for experiment e: RUNNING, samples (F32 classic: 4 frames each), DONE. */
static size_t device_frames(msid_can_frame *out, uint32_t e, uint32_t enc, uint32_t fd)
{
    size_t n = 0;
    msid_can_frame f;
    memset(&f, 0, sizeof f);
    f.id = BASE + MSID_CAN_ID_STATUS; f.len = 8;
    msid_can_encode_state(f.data, MSID_CAN_STATE_RUNNING, e, 0, P * KP);
    out[n++] = f;
    const uint32_t chunks = msid_can_chunks(C, enc, fd);
    for (uint64_t s = 0; s < (uint64_t)P * KP; ++s) {
        double row[C];
        for (uint32_t c = 0; c < C; ++c) row[c] = value(e, s, c);
        for (uint32_t k = 0; k < chunks; ++k) {
            memset(&f, 0, sizeof f);
            f.id = BASE + msid_can_chunk_id(enc, fd, k);
            f.len = (uint8_t)msid_can_sample_len(fd);
            f.flags = fd ? MSID_CANF_FD : 0;
            msid_can_encode_sample(f.data, enc, fd, k, (uint32_t)s, e,
                                   (s % P == 0 ? MSID_CAN_PSTART : 0u) | (s == 0 ? MSID_CAN_SEGSTART : 0u), row, C, 0.001);
            out[n++] = f;
        }
    }
    memset(&f, 0, sizeof f);
    f.id = BASE + MSID_CAN_ID_STATUS; f.len = 8;
    msid_can_encode_state(f.data, MSID_CAN_STATE_DONE, e, 0, P * KP);
    out[n++] = f;
    return n;
}

/* Reference: the same rows pushed straight into msid_meas. */
static void direct(bench *b)
{
    for (uint32_t e = 0; e < M; ++e) {
        assert_int_equal(msid_meas_begin(&b->ms, e), MSID_OK);
        for (uint64_t s = 0; s < (uint64_t)P * KP; ++s) {
            double row[C];
            for (uint32_t c = 0; c < C; ++c) row[c] = value(e, s, c);
            assert_int_equal(msid_meas_push(&b->ms, row, 1), MSID_OK);
        }
        assert_int_equal(msid_meas_end(&b->ms, NULL), MSID_OK);
    }
}

static void assert_same_stats(const bench *a, const bench *b)
{
    for (uint32_t e = 0; e < M; ++e) {
        const msid_pstats *x = msid_meas_stats(&a->ms, e), *y = msid_meas_stats(&b->ms, e);
        assert_int_equal(msid_pstats_count(x), msid_pstats_count(y));
        for (uint32_t l = 0; l < 3; ++l) {
            assert_memory_equal(msid_pstats_mean(x, l), msid_pstats_mean(y, l), C * sizeof(msid_cplx));
            assert_memory_equal(msid_pstats_scatter(x, l), msid_pstats_scatter(y, l), C * C * sizeof(msid_cplx));
        }
    }
}

static msid_can_frame FR[2][P * KP * 4 + 8];
static size_t NFR[2];

static void feed_all(bench *b, size_t skip_e, size_t skip_i)
{
    for (uint32_t e = 0; e < M; ++e)
        for (size_t i = 0; i < NFR[e]; ++i)
            if (!(e == skip_e && i == skip_i)) assert_int_equal(msid_can_decoder_feed(&b->dec, &FR[e][i]), MSID_OK);
}

static void build(uint32_t enc, uint32_t fd)
{
    for (uint32_t e = 0; e < M; ++e) NFR[e] = device_frames(FR[e], e, enc, fd);
}

static void decoder_bit_identical_to_direct_push(void **st)
{
    (void)st;
    for (uint32_t fd = 0; fd < 2; ++fd) {
        bench a, b;
        build(MSID_CAN_ENC_F32, fd);
        bench_init(&a, MSID_CAN_ENC_F32, fd, 16);
        bench_init(&b, MSID_CAN_ENC_F32, fd, 16);
        feed_all(&a, 99, 0);
        direct(&b);
        assert_same_stats(&a, &b);
        assert_int_equal(a.dec.cnt.samples, M * P * KP);
        assert_int_equal(a.dec.cnt.samples_lost, 0);
        assert_int_equal(a.dec.cnt.experiments_done, M);
        bench_free(&a);
        bench_free(&b);
    }
}

static void decoder_gap_rejects_the_period(void **st)
{
    (void)st;
    bench a;
    build(MSID_CAN_ENC_S16, 0);
    bench_init(&a, MSID_CAN_ENC_S16, 0, 16);
    /* experiment 1, frame of sample 70 (period 2), chunk 1 */
    feed_all(&a, 1, 1 + 70 * 2 + 1);
    assert_int_equal(a.dec.cnt.samples_lost, 1);
    assert_int_equal(a.dec.cnt.frames_missing, 1);
    assert_int_equal(a.dec.cnt.gap_events, 1);
    const msid_pstats_counts c0 = msid_pstats_get_counts(msid_meas_stats(&a.ms, 0));
    const msid_pstats_counts c1 = msid_pstats_get_counts(msid_meas_stats(&a.ms, 1));
    assert_int_equal(c0.gap, 0); assert_int_equal(c0.used, KP);
    assert_int_equal(c1.gap, 1); assert_int_equal(c1.used, KP - 1);
    bench_free(&a);
    /* the last frame before DONE: found missing by DONE's sample count, not lost silently */
    bench_init(&a, MSID_CAN_ENC_S16, 0, 16);
    feed_all(&a, 0, NFR[0] - 2);
    assert_int_equal(a.dec.cnt.samples_lost, 1);
    assert_int_equal(msid_pstats_get_counts(msid_meas_stats(&a.ms, 0)).gap, 1);
    bench_free(&a);
}

/* Regression: a DONE frame claiming 0xFFFFFFFF samples. With the design's K P the
 * decoder closes at K P (counted as malformed and done_beyond): nothing is lost, the statistics are
 * those of the direct push; a sample index beyond K P is malformed. Without a bound the same DONE
 * costs O(1) (whole gap periods are counted, not walked). */
static void decoder_done_beyond_the_design(void **st)
{
    (void)st;
    bench a, b;
    build(MSID_CAN_ENC_F32, 0);
    for (uint32_t e = 0; e < M; ++e)
        msid_can_encode_state(FR[e][NFR[e] - 1].data, MSID_CAN_STATE_DONE, e, 0, 0xFFFFFFFFu);
    bench_init(&a, MSID_CAN_ENC_F32, 0, 16);
    a.dec.cfg.samples_total = (uint64_t)P * KP;
    bench_init(&b, MSID_CAN_ENC_F32, 0, 16);
    /* a frame of sample K P (beyond the design) before DONE: malformed, not a sample */
    msid_can_frame extra = FR[0][1];
    msid_can_encode_sample(extra.data, MSID_CAN_ENC_F32, 0, 0, P * KP, 0, MSID_CAN_PSTART, (const double[C]){0}, C, 0.001);
    for (uint32_t e = 0; e < M; ++e)
        for (size_t i = 0; i < NFR[e]; ++i) {
            if (e == 0 && i + 1 == NFR[e]) assert_int_equal(msid_can_decoder_feed(&a.dec, &extra), MSID_OK);
            assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i]), MSID_OK);
        }
    direct(&b);
    assert_same_stats(&a, &b);
    assert_int_equal(a.dec.cnt.done_beyond, M);
    assert_int_equal(a.dec.cnt.malformed, M + 1);
    assert_int_equal(a.dec.cnt.samples_lost, 0);
    assert_int_equal(a.dec.cnt.experiments_done, M);
    bench_free(&a);
    bench_free(&b);
    /* found by fuzz_can_decoder: RUNNING/DONE of an experiment the design does not have made the core's
       "argument out of range" sticky (the run failed with that message); it is a malformed frame now */
    bench_init(&a, MSID_CAN_ENC_F32, 0, 16);
    msid_can_frame bad = FR[0][0];
    msid_can_encode_state(bad.data, MSID_CAN_STATE_RUNNING, M + 3, 0, P * KP);
    assert_int_equal(msid_can_decoder_feed(&a.dec, &bad), MSID_OK);
    assert_int_equal(a.dec.cnt.malformed, 1);
    assert_int_equal(a.dec.open, 0);
    bench_free(&a);
    /* unbounded (samples_total 0): 2^32 - K P missing samples declared, in O(1) */
    bench_init(&a, MSID_CAN_ENC_F32, 0, 16);
    feed_all(&a, 99, 0);
    assert_int_equal(a.dec.cnt.samples_lost, (uint64_t)M * (0xFFFFFFFFull - P * KP));
    assert_int_equal(a.dec.cnt.done_beyond, 0);
    bench_free(&a);
    /* an adversarial device: every DONE sent twice, and experiment 0's DONE replayed inside experiment 1
       (and at the end): ignored, the statistics are the clean run's, every experiment closed once */
    build(MSID_CAN_ENC_F32, 0);
    bench_init(&a, MSID_CAN_ENC_F32, 0, 16);
    a.dec.cfg.samples_total = (uint64_t)P * KP;
    bench_init(&b, MSID_CAN_ENC_F32, 0, 16);
    for (uint32_t e = 0; e < M; ++e)
        for (size_t i = 0; i < NFR[e]; ++i) {
            assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i]), MSID_OK);
            if (i + 1 == NFR[e]) assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i]), MSID_OK);
            if (e == 1 && i == NFR[e] / 2) assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[0][NFR[0] - 1]), MSID_OK);
        }
    assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[0][NFR[0] - 1]), MSID_OK);
    direct(&b);
    assert_same_stats(&a, &b);
    assert_int_equal(a.dec.cnt.experiments_done, M);
    assert_int_equal(a.dec.cnt.samples_lost, 0);
    bench_free(&a);
    bench_free(&b);
}

static void decoder_repairs_duplicates_and_reordering(void **st)
{
    (void)st;
    bench a, b;
    build(MSID_CAN_ENC_F32, 0);
    bench_init(&a, MSID_CAN_ENC_F32, 0, 16);
    bench_init(&b, MSID_CAN_ENC_F32, 0, 16);
    for (uint32_t e = 0; e < M; ++e)
        for (size_t i = 0; i < NFR[e]; ++i) {
            if (i > 1 && i + 2 < NFR[e] && i % 50 == 0) {   /* swap i and i+1 (5 samples apart at most) */
                assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i + 1]), MSID_OK);
                assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i]), MSID_OK);
                ++i;
                continue;
            }
            assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i]), MSID_OK);
            if (i % 33 == 0) assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i]), MSID_OK);
        }
    direct(&b);
    assert_same_stats(&a, &b);
    assert_true(a.dec.cnt.duplicates > 0 && a.dec.cnt.reordered > 0);
    assert_int_equal(a.dec.cnt.samples_lost, 0);
    bench_free(&a);
    bench_free(&b);
}

static void decoder_malformed_frames_are_counted(void **st)
{
    (void)st;
    bench a, b;
    build(MSID_CAN_ENC_S16, 0);
    bench_init(&a, MSID_CAN_ENC_S16, 0, 16);
    bench_init(&b, MSID_CAN_ENC_S16, 0, 16);
    uint64_t bad = 0;
    for (uint32_t e = 0; e < M; ++e)
        for (size_t i = 0; i < NFR[e]; ++i) {
            assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[e][i]), MSID_OK);
            if (i > 0 && i % 40 == 0 && i + 1 < NFR[e]) {
                msid_can_frame g = FR[e][i];
                g.len = 5; msid_can_decoder_feed(&a.dec, &g); ++bad;                 /* wrong DLC */
                g = FR[e][i]; g.flags = MSID_CANF_FD; msid_can_decoder_feed(&a.dec, &g); ++bad;   /* FD on a classic id */
                g = FR[e][i]; g.id = BASE + MSID_CAN_ID_S16 + 5; msid_can_decoder_feed(&a.dec, &g); ++bad; /* no such chunk */
                g = FR[e][i]; g.data[3] ^= MSID_CAN_PSTART; msid_can_decoder_feed(&a.dec, &g); ++bad;  /* marker */
                g = FR[e][i]; g.id = BASE + MSID_CAN_ID_STATUS; g.len = 3; msid_can_decoder_feed(&a.dec, &g); ++bad;
            }
        }
    direct(&b);
    /* int16 decoding rounds; compare counts, and that nothing was lost */
    assert_int_equal(a.dec.cnt.malformed, bad);
    assert_int_equal(a.dec.cnt.samples_lost, 0);
    assert_int_equal(a.dec.cnt.samples, M * P * KP);
    bench_free(&a);
    bench_free(&b);
}

static void decoder_device_restart_opens_a_segment(void **st)
{
    (void)st;
    bench a;
    build(MSID_CAN_ENC_F32, 1);
    bench_init(&a, MSID_CAN_ENC_F32, 1, 16);
    /* experiment 0 runs 70 samples, restarts, then runs fully */
    const uint32_t chunks = msid_can_chunks(C, MSID_CAN_ENC_F32, 1);
    for (size_t i = 0; i < 1 + 70 * chunks; ++i) assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[0][i]), MSID_OK);
    for (size_t i = 1; i < NFR[0]; ++i) assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[0][i]), MSID_OK);
    assert_int_equal(a.dec.cnt.restarts, 1);
    assert_int_equal(msid_meas_leftover(&a.ms, 0), 70 % P);
    const msid_pstats_counts c = msid_pstats_get_counts(msid_meas_stats(&a.ms, 0));
    assert_int_equal(c.used, 70 / P + KP);
    assert_int_equal(a.dec.cnt.samples_lost, 0);
    bench_free(&a);
}

static void decoder_bus_errors(void **st)
{
    (void)st;
    bench a;
    build(MSID_CAN_ENC_F32, 0);
    bench_init(&a, MSID_CAN_ENC_F32, 0, 16);
    msid_can_frame err = {0};
    err.id = MSID_CAN_ERR_FLAG | 0x004u; err.len = 8; err.data[1] = 0x04;   /* controller: rx warning */
    for (size_t i = 0; i < NFR[0]; ++i) {
        if (i == 200) {
            assert_int_equal(msid_can_decoder_feed(&a.dec, &err), MSID_OK);
            assert_int_equal(a.dec.bus, MSID_CAN_BUS_WARNING);
            err.data[1] = 0x20;   /* tx passive */
            msid_can_decoder_feed(&a.dec, &err);
            assert_int_equal(a.dec.bus, MSID_CAN_BUS_PASSIVE);
            err.id = MSID_CAN_ERR_FLAG | 0x040u;   /* bus-off: the period is discarded */
            msid_can_decoder_feed(&a.dec, &err);
            assert_int_equal(a.dec.bus, MSID_CAN_BUS_OFF);
            err.id = MSID_CAN_ERR_FLAG | 0x100u;
            msid_can_decoder_feed(&a.dec, &err);
            assert_int_equal(a.dec.bus, MSID_CAN_BUS_RESTARTED);
        }
        assert_int_equal(msid_can_decoder_feed(&a.dec, &FR[0][i]), MSID_OK);
    }
    assert_int_equal(a.dec.cnt.error_frames, 4);
    assert_int_equal(a.dec.cnt.err_bus_off, 1);
    assert_int_equal(a.dec.cnt.periods_marked, 1);
    const msid_pstats_counts c = msid_pstats_get_counts(msid_meas_stats(&a.ms, 0));
    assert_int_equal(c.gap, 1);
    assert_int_equal(c.used, KP - 1);
    assert_string_equal(msid_can_bus_state_name(MSID_CAN_BUS_OFF), "bus-off");
    bench_free(&a);
}

static void decoder_survives_random_frames(void **st)
{
    (void)st;
    bench a;
    build(MSID_CAN_ENC_S16, 0);
    bench_init(&a, MSID_CAN_ENC_S16, 0, 4);
    msid_rng r;
    msid_rng_seed(&r, 99);
    for (int i = 0; i < 200000; ++i) {
        msid_can_frame f;
        const uint64_t x = msid_rng_u64(&r);
        f.id = (x & 1) ? (BASE + (uint32_t)((x >> 1) & 0x7F)) : (uint32_t)(x >> 8);
        f.len = (uint8_t)((x >> 40) % 65);
        f.flags = (uint8_t)((x >> 50) & 7);
        for (int b = 0; b < 64; ++b) f.data[b] = (uint8_t)(msid_rng_u64(&r) >> 3);
        if (i % 1000 == 0) {   /* now and then a frame of the real stream */
            f = FR[0][(size_t)(x % NFR[0])];
        }
        const msid_status s = msid_can_decoder_feed(&a.dec, &f);
        assert_true(s == MSID_OK || s == MSID_E_STATE || s == MSID_E_ARG);
    }
    msid_can_decoder_abort(&a.dec);
    assert_true(a.dec.cnt.frames + a.dec.cnt.host_frames == 200000);
    bench_free(&a);
}

static void decoder_rejects_bad_config(void **st)
{
    (void)st;
    msid_meas ms;
    msid_can_decoder d;
    uint8_t _Alignas(64) mem[1 << 16];
    msid_can_decoder_cfg dc = {BASE, 2, 2, 0, 0, 0.001, P, 16, 0, &ms};
    assert_int_equal(msid_can_decoder_init(&d, &dc, mem, sizeof mem), MSID_OK);
    dc.base = 0x201; assert_int_equal(msid_can_decoder_init(&d, &dc, mem, sizeof mem), MSID_E_ARG);
    dc.base = BASE; dc.scale = 0; assert_int_equal(msid_can_decoder_init(&d, &dc, mem, sizeof mem), MSID_E_ARG);
    dc.scale = 0.001; dc.window = MSID_CAN_MAX_WINDOW + 1; assert_int_equal(msid_can_decoder_mem_size(&dc), 0);
    dc.window = 16; dc.n_outputs = 40; assert_int_equal(msid_can_decoder_mem_size(&dc), 0);
    dc.n_outputs = 2; assert_int_equal(msid_can_decoder_init(&d, &dc, mem + 1, sizeof mem - 1), MSID_E_MEM_ALIGN);
    assert_int_equal(msid_can_decoder_init(&d, &dc, mem, 64), MSID_E_MEM_SIZE);
    dc.meas = NULL; assert_int_equal(msid_can_decoder_init(&d, &dc, mem, sizeof mem), MSID_E_NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(codec_roundtrip),
        cmocka_unit_test(config_upload),
        cmocka_unit_test(candump_lines),
        cmocka_unit_test(candump_replay),
        cmocka_unit_test(decoder_bit_identical_to_direct_push),
        cmocka_unit_test(decoder_gap_rejects_the_period),
        cmocka_unit_test(decoder_done_beyond_the_design),
        cmocka_unit_test(decoder_repairs_duplicates_and_reordering),
        cmocka_unit_test(decoder_malformed_frames_are_counted),
        cmocka_unit_test(decoder_device_restart_opens_a_segment),
        cmocka_unit_test(decoder_bus_errors),
        cmocka_unit_test(decoder_survives_random_frames),
        cmocka_unit_test(decoder_rejects_bad_config),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
