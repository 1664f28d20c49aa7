/* The Modbus acquisition adapter: retried requests, design upload, commands, ring polling. */
#define _POSIX_C_SOURCE 200809L
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_can_proto.h"   /* device error codes: the same on both protocols */

#include <stdio.h>
#include <string.h>
#include <time.h>

static size_t up(size_t n) { return (n + MSID_MEM_ALIGN - 1) / MSID_MEM_ALIGN * MSID_MEM_ALIGN; }
static uint32_t mregs(const msid_mb_acq_cfg *c) { return c->max_regs ? c->max_regs : MSID_MB_MAX_READ; }

size_t msid_mb_acq_mem_size(const msid_mb_acq_cfg *c)
{
    if (!c) return 0;
    const uint32_t C = c->n_inputs + c->n_outputs;
    if (c->n_inputs == 0 || c->n_outputs == 0 || C > MSID_MAX_CHANNELS || !msid_mb_value_regs(c->encoding) ||
        c->word_order > MSID_MB_DCBA || mregs(c) > MSID_MB_MAX_READ || msid_mb_sample_regs(c->encoding, C) > mregs(c))
        return 0;
    const msid_stream_cfg sc = {C, 0, c->meas};
    return up(sizeof(uint16_t) * MSID_MB_MAX_READ) + up(sizeof(double) * C) + msid_stream_mem_size(&sc);
}

int msid_mb_acq_init(msid_mb_acq *a, const msid_mb_acq_cfg *c, void *mem, size_t len)
{
    if (!a || !c || !mem || !c->meas || !c->client) return msid_daq_core(MSID_E_NULL);
    const size_t need = msid_mb_acq_mem_size(c);
    if (need == 0) return msid_daq_core(MSID_E_DIMS);
    if (c->encoding != MSID_MB_ENC_F32 && !(c->scale > 0)) return msid_daq_core(MSID_E_ARG);
    if (((uintptr_t)mem) % MSID_MEM_ALIGN) return msid_daq_core(MSID_E_MEM_ALIGN);
    if (len < need) return msid_daq_core(MSID_E_MEM_SIZE);
    memset(a, 0, sizeof *a);
    a->cfg = *c;
    a->cl = c->client;
    a->cfg.max_regs = mregs(c);
    a->cfg.batch = c->batch ? c->batch : 8;
    a->C = c->n_inputs + c->n_outputs;
    a->W = msid_mb_sample_regs(c->encoding, a->C);
    char *p = mem;
    a->buf = (uint16_t *)p; p += up(sizeof(uint16_t) * MSID_MB_MAX_READ);
    a->row = (double *)p; p += up(sizeof(double) * a->C);
    const msid_stream_cfg sc = {a->C, 0, c->meas};
    return msid_daq_core(msid_stream_init(&a->st, &sc, p, need - (size_t)(p - (char *)mem)));
}

static void sleep_ms(uint32_t ms)
{
    struct timespec t = {(time_t)(ms / 1000), (long)(ms % 1000) * 1000000L};
    while (nanosleep(&t, &t) != 0) {}
}

static const char *kind_name(int k)
{
    return k == MSID_MB_READ_INPUT ? "read input registers" : k == MSID_MB_READ_HOLDING ? "read holding registers"
                                                                                         : "write holding registers";
}

void msid_mb_client_init(msid_mb_client *c, msid_mb_transport *tr, uint32_t retries, uint32_t backoff_ms)
{
    memset(c, 0, sizeof *c);
    c->tr = tr;
    c->retries = retries ? retries : 5;
    c->backoff_ms = backoff_ms ? backoff_ms : 20;
}

/* One request with up to `retries` retries; *transient set when the last failure may pass (a
   timeout, bad CRC or reply, lost connection, busy): the link has been flushed or reconnected. */
static int call(msid_mb_client *a, int kind, uint32_t addr, uint32_t n, uint16_t *regs, uint32_t retries,
                int *transient)
{
    *transient = 0;
    const msid_mb_transport *t = a->tr;
    int rc = 0, reissued = 0;
    for (uint32_t attempt = 0;; ++attempt) {
        if (a->drain) msid_mb_flush(t);   /* no request is outstanding: whatever waits on the link is stale */
        a->cnt.requests++;
        const uint64_t skipped0 = msid_mb_skipped(t);
        rc = kind == MSID_MB_READ_INPUT     ? msid_mb_read_input(t, addr, n, regs)
             : kind == MSID_MB_READ_HOLDING ? msid_mb_read_holding(t, addr, n, regs)
                                            : msid_mb_write_holding(t, addr, n, regs);
        a->cnt.skipped_replies += msid_mb_skipped(t) - skipped0;   /* TCP: stale or foreign replies read past */
        if (rc == 0) {
            if (kind == MSID_MB_WRITE_HOLDING) a->cnt.registers_written += n;
            else a->cnt.registers_read += n;
            return 0;
        }
        int reconnect = 0;
        switch (-rc) {
        case MSID_DAQ_E_EXCEPTION: {
            a->cnt.exceptions++;
            const uint32_t x = msid_mb_exception(t);
            if (x != 5 && x != 6) {
                snprintf(a->err, sizeof a->err, "the device answered exception %u (%s) to %s %u..%u", x,
                         msid_mb_exception_name(x), kind_name(kind), addr, addr + n - 1);
                return rc;
            }
            break;
        }
        case MSID_DAQ_E_TIMEOUT: a->cnt.timeouts++; reconnect = 1; break;
        case MSID_DAQ_E_CRC: a->cnt.crc_errors++; break;
        case MSID_DAQ_E_BADDATA:
            /* a reply that does not match its request. TCP: the MBAP reader (msid_mbap.c) has already
               skipped stale and foreign transaction ids, so this is the request's own reply with wrong
               contents (a byte count or function code that does not fit): read whole, the link is still
               framed. RTU, which has no transaction id: possibly a stale duplicate or bytes left over from
               an oversized frame, with the real reply still in flight. Either way the backoff lets it
               arrive, the flush drops it, and the request is issued once more even when the caller allows
               no retry; from now on the link is drained before every request */
            a->cnt.bad_replies++;
            a->drain = 1;
            if (!reissued) {
                reissued = 1;
                retries++;
            }
            break;
        case MSID_DAQ_E_PROTOCOL:
            /* a malformed frame (TCP: an MBAP length or protocol id out of range): the byte stream has lost
               its framing, so only a new connection can be trusted */
            a->cnt.malformed_frames++;
            reconnect = 1;
            break;
        case MSID_DAQ_E_ARG:
            snprintf(a->err, sizeof a->err, "%s %u..%u: bad request", kind_name(kind), addr, addr + n - 1);
            return rc;
        default: a->cnt.io_errors++; reconnect = 1; break;
        }
        uint32_t b = a->backoff_ms << (attempt < 6 ? attempt : 6);
        sleep_ms(b < 1000 ? b : 1000);
        if (reconnect) {
            a->cnt.reconnects++;
            msid_mb_reconnect(t);   /* a failed connect is the next attempt's I/O error */
        } else {
            msid_mb_flush(t);
        }
        if (attempt >= retries) {
            snprintf(a->err, sizeof a->err, "no valid reply to %s %u..%u after %u attempts: %s", kind_name(kind), addr,
                     addr + n - 1, attempt + 1, msid_mb_error(t));
            *transient = 1;
            return rc;
        }
        a->cnt.retries++;
    }
}

int msid_mb_call(msid_mb_client *c, int kind, uint32_t addr, uint32_t n, uint16_t *regs)
{
    int transient;
    return call(c, kind, addr, n, regs, c->retries, &transient);
}

int msid_mb_read_header(msid_mb_client *a)
{
    uint16_t r[MSID_MB_IR_HEADER];
    const int rc = msid_mb_call(a, MSID_MB_READ_INPUT, 0, MSID_MB_IR_HEADER, r);
    if (rc < 0) return rc;
    msid_mb_header_decode(&a->h, r);
    if (a->h.magic != MSID_MB_MAGIC) {
        snprintf(a->err, sizeof a->err, "not an msid-modbus device: input register 0 holds 0x%04X, not 0x%04X",
                 a->h.magic, MSID_MB_MAGIC);
        return -MSID_DAQ_E_BADDATA;
    }
    return 0;
}

int msid_mb_upload(msid_mb_client *a, uint32_t encoding, uint32_t word_order, const uint8_t (*rec)[8], size_t n)
{
    uint16_t r[2 + 4 * MSID_MB_CFG_RECORDS];
    int rc = msid_mb_read_header(a);
    if (rc < 0) return rc;
    a->cfg_seq = a->h.cfg_done;
    r[0] = (uint16_t)encoding;
    r[1] = (uint16_t)word_order;
    if ((rc = msid_mb_call(a, MSID_MB_WRITE_HOLDING, MSID_MB_HR_ENCODING, 2, r)) < 0) return rc;
    for (size_t i = 0; i < n; i += MSID_MB_CFG_RECORDS) {
        const size_t k = n - i < MSID_MB_CFG_RECORDS ? n - i : MSID_MB_CFG_RECORDS;
        a->cfg_seq = (a->cfg_seq + 1) & 0xFFFFu;
        r[0] = (uint16_t)a->cfg_seq;
        r[1] = (uint16_t)k;
        msid_mb_pack_records(r + 2, rec + i, k);
        if ((rc = msid_mb_call(a, MSID_MB_WRITE_HOLDING, MSID_MB_HR_CFG_SEQ, (uint32_t)(2 + 4 * k), r)) < 0) return rc;
        /* like the CAN upload's flow control: stop at the first refusal */
        if ((rc = msid_mb_read_header(a)) < 0) return rc;
        if (a->h.state == MSID_MB_STATE_ERROR) return 0;
    }
    return 0;
}

int msid_mb_identify(msid_mb_client *a)
{
    const int rc = msid_mb_read_header(a);
    if (rc < 0) return rc;
    if (a->h.version != MSID_MB_PROTO_VERSION) {
        snprintf(a->err, sizeof a->err, "register map version mismatch: the device serves msid-modbus/%u, this host "
                 "msid-modbus/%u", a->h.version, MSID_MB_PROTO_VERSION);
        return -MSID_DAQ_E_PROTOCOL;
    }
    return 0;
}

int msid_mb_configure(msid_mb_client *a, uint32_t encoding, uint32_t word_order, const uint8_t (*rec)[8], size_t n)
{
    if (!rec || n < 2) return -MSID_DAQ_E_ARG;
    const int rc = msid_mb_upload(a, encoding, word_order, rec, n);
    if (rc < 0) return rc;
    const msid_mb_header *h = &a->h;
    if (h->state == MSID_MB_STATE_ERROR) {
        if (h->error == MSID_CAN_ERR_DESIGN)
            snprintf(a->err, sizeof a->err, "the device refused the configuration: %s (%s)",
                     msid_can_device_error_name(h->error), msid_strerror((msid_status)h->detail));
        else
            snprintf(a->err, sizeof a->err, "the device refused the configuration: %s",
                     msid_can_device_error_name(h->error));
        return -MSID_DAQ_E_DEVICE;
    }
    if (h->state != MSID_MB_STATE_CONFIGURED) {
        snprintf(a->err, sizeof a->err, "the device did not confirm the configuration (state %u)", h->state);
        return -MSID_DAQ_E_PROTOCOL;
    }
    const uint32_t crc = (uint32_t)rec[n - 1][4] | (uint32_t)rec[n - 1][5] << 8 | (uint32_t)rec[n - 1][6] << 16 |
                         (uint32_t)rec[n - 1][7] << 24;
    if (h->crc != crc) {
        snprintf(a->err, sizeof a->err, "the device confirmed configuration CRC %08X, the host sent %08X", h->crc, crc);
        return -MSID_DAQ_E_PROTOCOL;
    }
    return 0;
}

int msid_mb_command(msid_mb_client *a, uint32_t cmd, uint32_t e, uint32_t periods)
{
    int rc = msid_mb_read_header(a);
    if (rc < 0) return rc;
    a->cmd_seq = (a->h.cmd_done + 1) & 0xFFFFu;
    uint16_t r[5] = {(uint16_t)a->cmd_seq, (uint16_t)cmd, (uint16_t)e, 0, 0};
    msid_mb_put_u32(r + 3, periods);
    if ((rc = msid_mb_call(a, MSID_MB_WRITE_HOLDING, MSID_MB_HR_CMD_SEQ, 5, r)) < 0) return rc;
    for (int i = 0; i < 200; ++i) {
        if ((rc = msid_mb_read_header(a)) < 0) return rc;
        if (a->h.cmd_done == a->cmd_seq) return 0;
        sleep_ms(10);
    }
    snprintf(a->err, sizeof a->err, "the device did not execute command %u within 2 s", cmd);
    return -MSID_DAQ_E_TIMEOUT;
}

int msid_mb_acq_start(msid_mb_acq *a, uint32_t e, uint32_t periods)
{
    const int rc = msid_mb_command(a->cl, MSID_MB_CMD_START, e, periods);
    if (rc < 0) return rc;
    if (a->cl->h.state == MSID_MB_STATE_ERROR) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device refused to start experiment %u: %s (error %u)", e + 1,
                 msid_can_device_error_name(a->cl->h.error), a->cl->h.error);
        return -MSID_DAQ_E_DEVICE;
    }
    if (a->cl->h.ring_samples == 0 || a->cl->h.sample_regs != a->W || a->cl->h.ring_addr < MSID_MB_IR_HEADER ||
        a->cl->h.ring_addr + (uint64_t)a->cl->h.ring_samples * a->W > 65536u) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device's ring (%u samples of %u registers at %u) does not match %u "
                 "channels of %s", a->cl->h.ring_samples, a->cl->h.sample_regs, a->cl->h.ring_addr, a->C,
                 msid_mb_encoding_name(a->cfg.encoding));
        return -MSID_DAQ_E_BADDATA;
    }
    const uint64_t want = (uint64_t)(periods ? periods : a->cl->h.periods) * a->cfg.period;
    if (a->cfg.period && (a->cl->h.period != a->cfg.period || a->cl->h.total != want || want == 0)) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device announces %u samples of period %u per segment, the design "
                 "%llu of period %u", a->cl->h.total, a->cl->h.period, (unsigned long long)want, a->cfg.period);
        return -MSID_DAQ_E_BADDATA;
    }
    a->total = a->cfg.period ? want : 0;
    a->exp = e;
    a->r = 0;
    a->seg = 0;          /* START opens segment 0 at sample 0 (the device may be further already) */
    a->seg_start = 0;
    const msid_status st = msid_stream_begin(&a->st, e);
    a->open = st == MSID_OK;
    return msid_daq_core(st);
}

/* Samples [a->r, to) are gone: declare them missing (an overrun). */
static void overrun(msid_mb_acq *a, uint64_t to)
{
    if (to <= a->r) return;
    msid_stream_lost(&a->st, to - a->r);
    a->cnt.overrun_samples += to - a->r;
    a->cnt.overrun_events++;
    a->r = to;
}

/* A new segment begins at the header's segment start: finish the old one there. */
static void new_segment(msid_mb_acq *a)
{
    /* The old segment was read up to s0 unless segments in between were never seen (two restarts
       within one poll): their samples cannot be aligned, so they are declared missing. */
    overrun(a, a->cl->h.seg_start);
    const uint64_t s0 = a->cl->h.seg_start;
    msid_stream_begin(&a->st, a->exp);
    a->seg = a->cl->h.segment;
    a->seg_start = s0;
    a->cnt.restarts++;
}

static int check_state(msid_mb_acq *a)
{
    const msid_mb_header *h = &a->cl->h;
    if (h->state == MSID_MB_STATE_ERROR) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device reported error %u (%s, detail %u) during experiment %u",
                 h->error, msid_can_device_error_name(h->error), h->detail, a->exp + 1);
        return -MSID_DAQ_E_DEVICE;
    }
    if ((h->state != MSID_MB_STATE_RUNNING && h->state != MSID_MB_STATE_DONE) || h->experiment != a->exp) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device left experiment %u (state %u, experiment %u)", a->exp + 1, h->state,
                 h->experiment + 1);
        return -MSID_DAQ_E_BADDATA;
    }
    return 0;
}

/* Device restarts that may happen between two polls (each at most K P samples after the segment before it). */
#define MAX_RESTARTS_PER_POLL 2u

/* The header's counts against what the design and the samples read so far allow: a header that
   contradicts them is refused, not trusted. */
static int check_counts(msid_mb_acq *a)
{
    const msid_mb_header *h = &a->cl->h;
    if (!a->total) return 0;
    const uint64_t wi = h->write_index, s0 = h->seg_start;
    if (h->total != a->total) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device changed its samples per segment from %llu to %u during "
                 "experiment %u", (unsigned long long)a->total, h->total, a->exp + 1);
        return -MSID_DAQ_E_BADDATA;
    }
    if (wi < a->r || s0 < a->seg_start || s0 > wi || (h->segment == a->seg && s0 != a->seg_start)) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device's write index stepped back (segment %u from sample %llu, "
                 "write index %u, %llu samples read) during experiment %u", h->segment, (unsigned long long)s0,
                 h->write_index, (unsigned long long)a->r, a->exp + 1);
        return -MSID_DAQ_E_BADDATA;
    }
    /* each restart starts within the K P samples of the segment before it; a segment number that jumped by more
       than MAX_RESTARTS_PER_POLL is not trusted to size the samples declared lost */
    const uint64_t jumps = (uint64_t)((h->segment - a->seg) & 0xFFFFu);
    if (h->segment != a->seg &&
        s0 > a->seg_start + a->total * (jumps < MAX_RESTARTS_PER_POLL ? jumps : MAX_RESTARTS_PER_POLL)) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device's new segment starts at sample %llu, beyond the %llu "
                 "samples of the segment before it (experiment %u)", (unsigned long long)s0,
                 (unsigned long long)a->total, a->exp + 1);
        return -MSID_DAQ_E_BADDATA;
    }
    if (h->state == MSID_MB_STATE_DONE && h->segment == a->seg && wi - s0 < a->total) {
        snprintf(a->cl->err, sizeof a->cl->err, "the device reported DONE after %llu of the design's %llu samples of "
                 "experiment %u", (unsigned long long)(wi - s0), (unsigned long long)a->total, a->exp + 1);
        return -MSID_DAQ_E_BADDATA;
    }
    return 0;
}

/* The first sample of the ring that has not been overwritten. */
static uint64_t ring_low(const msid_mb_acq *a)
{
    return a->cl->h.write_index > a->cl->h.ring_samples ? (uint64_t)a->cl->h.write_index - a->cl->h.ring_samples : 0;
}

/* Use the samples of a->buf (sample n at 0) from position i on while their tags follow a->r; returns where it stopped. */
static uint32_t take(msid_mb_acq *a, uint64_t n, uint32_t i, uint32_t k, uint64_t to, int *prog)
{
    const uint32_t W = a->W, vr = msid_mb_value_regs(a->cfg.encoding);
    for (; i < k && a->r < to; ++i) {
        const uint16_t *s = a->buf + (size_t)i * W;
        if (n + i != a->r || s[0] != (uint16_t)(n + i)) break;
        for (uint32_t c = 0; c < a->C; ++c)
            a->row[c] = msid_mb_decode_value(s + 1 + c * vr, a->cfg.encoding, a->cfg.word_order, a->cfg.scale);
        msid_stream_row(&a->st, a->row);
        a->r++;
        *prog = 1;
    }
    return i;
}

/* Samples [a->r, to) from the ring, at most *left requests. */
static int read_ring(msid_mb_acq *a, uint64_t to, uint32_t *left, int *prog)
{
    const uint32_t R = a->cl->h.ring_samples, W = a->W, per = a->cfg.max_regs / W;
    uint32_t stale = 0;
    while (a->r < to && *left) {
        const uint64_t n = a->r;
        const uint32_t slot = (uint32_t)(n % R);
        uint64_t k = to - n;
        if (k > per) k = per;
        if (k > R - slot) k = R - slot;
        /* one attempt: after a failure the next poll reads the header first, so a retry never
           asks for slots the device has overwritten meanwhile (and the counts stay the device's) */
        int transient;
        int rc = call(a->cl, MSID_MB_READ_INPUT, a->cl->h.ring_addr + slot * W, (uint32_t)k * W, a->buf, 0, &transient);
        if (rc < 0) return transient ? 0 : rc;
        (*left)--;
        uint32_t i = take(a, n, 0, (uint32_t)k, to, prog);
        if (i == k) continue;
        /* a tag did not match: overwritten while we read (the header now says so), or a stale reply */
        if ((rc = msid_mb_read_header(a->cl)) < 0) return rc;
        /* this header is checked like the poll's (found by fuzz_mb_acq: a segment start far beyond the
           design's K P, read here, declared 65536 samples missing) */
        if ((rc = check_state(a)) < 0 || (rc = check_counts(a)) < 0) return rc;
        if (a->r < ring_low(a)) {
            /* within this segment the read position may move past `to`, up to the write index */
            uint64_t lim = a->cl->h.segment == a->seg ? a->cl->h.write_index : to;
            if (a->total && lim > a->seg_start + a->total) lim = a->seg_start + a->total;   /* never beyond K P */
            overrun(a, ring_low(a) < lim ? ring_low(a) : lim);
            *prog = 1;
            /* the reply may hold the newer samples from the new read position on: the device
               counts them as read, so they are used (their tags prove them) */
            if (a->r < n + k) take(a, n, (uint32_t)(a->r - n), (uint32_t)k, lim, prog);
        } else if (++stale > a->cl->retries) {
            snprintf(a->cl->err, sizeof a->cl->err, "the ring at sample %llu keeps answering tag %u: the device does not "
                     "follow msid-modbus/%u", (unsigned long long)a->r, a->buf[(size_t)i * W], MSID_MB_PROTO_VERSION);
            return -MSID_DAQ_E_BADDATA;
        } else {
            a->cnt.stale_replies++;
            msid_mb_flush(a->cl->tr);
        }
    }
    return 0;
}

/* The core refused what the stream handed it: its status in the daq error space, and the message. */
static int core_refused(msid_mb_acq *a)
{
    if (a->st.err == MSID_E_CAPACITY)
        snprintf(a->cl->err, sizeof a->cl->err, "more periods arrived than the measurement holds (device restarted too "
                 "often?)");
    else
        snprintf(a->cl->err, sizeof a->cl->err, "measurement: %s", msid_strerror(a->st.err));
    return msid_daq_core(a->st.err);
}

int msid_mb_acq_poll(msid_mb_acq *a, int *prog)
{
    *prog = 0;
    if (!a->open) return 1;
    a->cnt.polls++;
    int rc = msid_mb_read_header(a->cl);
    if (rc < 0) return rc;
    if ((rc = check_state(a)) < 0) return rc;
    if ((rc = check_counts(a)) < 0) return rc;
    uint32_t left = a->cfg.batch;
    for (;;) {
        const int newseg = a->cl->h.segment != a->seg;
        uint64_t end = newseg ? a->cl->h.seg_start : a->cl->h.write_index;
        if (a->total && end > a->seg_start + a->total) end = a->seg_start + a->total;   /* nothing beyond K P */
        /* overwritten before we read them (the part in this segment) */
        const uint64_t lo = ring_low(a);
        if (a->r < lo) {
            overrun(a, lo < end ? lo : end);
            *prog = 1;
        }
        if ((rc = read_ring(a, end, &left, prog)) < 0) return rc;
        if (a->st.err != MSID_OK) return core_refused(a);
        if (a->r < end) return 0;              /* out of requests for this poll */
        if (!newseg) break;
        new_segment(a);
        *prog = 1;
    }
    const int all = a->total && a->r >= a->seg_start + a->total;
    if (all || (a->cl->h.state == MSID_MB_STATE_DONE && a->r >= a->cl->h.write_index)) {
        if (all && a->cl->h.state != MSID_MB_STATE_DONE) a->cnt.done_missing++;
        msid_stream_end(&a->st);
        a->open = 0;
        a->cnt.experiments_done++;
        a->cnt.device_overruns += a->cl->h.overruns;
        return a->st.err != MSID_OK ? core_refused(a) : 1;
    }
    return 0;
}

static uint64_t now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

/* The caller asked to stop: close the experiment where it stands (complete periods kept), STOP the device. */
static int stop_run(msid_mb_acq *a, uint32_t e, uint64_t t0)
{
    a->cnt.stream_ns += now_ns() - t0;
    if (a->open) {
        msid_stream_end(&a->st);
        a->open = 0;
    }
    if (a->st.err != MSID_OK) return core_refused(a);
    char why[sizeof a->cl->err];
    memcpy(why, a->cl->err, sizeof why);
    (void)msid_mb_command(a->cl, MSID_MB_CMD_STOP, e, 0);   /* best effort: the device may be gone */
    memcpy(a->cl->err, why, sizeof why);
    return -MSID_DAQ_E_STOPPED;
}

int msid_mb_acq_run(msid_mb_acq *a, uint32_t e, uint32_t periods, uint32_t silence_ms, uint32_t idle_us)
{
    int rc = msid_mb_acq_start(a, e, periods);
    if (rc < 0) return rc;
    msid_mb_client *cl = a->cl;
    const uint64_t t0 = now_ns();
    uint64_t last = t0, bad_at_progress = cl->cnt.bad_replies;   /* bad replies when a sample last arrived */
    for (;;) {
        int prog = 0;
        const uint64_t nodone = a->cnt.done_missing;
        rc = msid_mb_acq_poll(a, &prog);
        if (rc == 1) {
            a->cnt.stream_ns += now_ns() - t0;
            if (a->cnt.done_missing != nodone && (rc = msid_mb_command(cl, MSID_MB_CMD_STOP, e, 0)) < 0) {
                char why[sizeof cl->err];
                memcpy(why, cl->err, sizeof why);
                snprintf(cl->err, sizeof cl->err, "the device did not stop after the design's samples: %.250s", why);
                return rc;
            }
            return 0;
        }
        if (a->cfg.on_poll && a->cfg.on_poll(a->cfg.user)) return stop_run(a, e, t0);
        if (rc < 0) return rc;
        const uint64_t t = now_ns();
        if (prog) {
            last = t;
            bad_at_progress = cl->cnt.bad_replies;
        } else if (t - last > (uint64_t)silence_ms * 1000000u) {
            const uint64_t bad = cl->cnt.bad_replies - bad_at_progress;
            if (bad) {   /* not a silent device: its replies do not match */
                snprintf(cl->err, sizeof cl->err, "no new sample for %g s: %llu repl%s did not match their requests "
                         "(a device that answers twice, or a second master on the link?)", (double)silence_ms / 1000.0,
                         (unsigned long long)bad, bad == 1 ? "y" : "ies");
                return -MSID_DAQ_E_BADDATA;
            }
            snprintf(cl->err, sizeof cl->err, "the device produced no new sample for %g s", (double)silence_ms / 1000.0);
            return -MSID_DAQ_E_TIMEOUT;
        } else if (idle_us) {
            const struct timespec d = {(time_t)(idle_us / 1000000u), (long)(idle_us % 1000000u) * 1000L};
            nanosleep(&d, NULL);
        }
    }
}
