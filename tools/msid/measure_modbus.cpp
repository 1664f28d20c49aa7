// `msid measure --device modbus-tcp://... | modbus-rtu://...`: the Modbus session of measure.hpp,
// over the daq API (msid_mb_acq: retried requests, ring polling, stream into msid_meas), with live
// progress and a clean stop on SIGINT/SIGTERM.
#include "measure.hpp"

extern "C" {
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_modbus.h"
}

#include <cerrno>
#include <cstring>
#include <ctime>
#include <unistd.h>

namespace msidcli {

// ---- stop requests -------------------------------------------------------------

static volatile sig_atomic_t g_stop_signal = 0;

static void on_stop_signal(int sig) { g_stop_signal = sig; }

StopOnSignal::StopOnSignal()
{
    g_stop_signal = 0;
    struct sigaction sa{};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;   // no SA_RESTART: a sleep or a blocking read returns at once
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
}

StopOnSignal::~StopOnSignal()
{
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
}

bool measure_stop_requested() { return g_stop_signal != 0; }
int measure_stop_signal() { return (int)g_stop_signal; }

void mark_completeness(Json &doc, bool complete, uint32_t experiments_done, uint32_t experiments,
                       const std::string &reason)
{
    doc["complete"] = complete;
    doc["experiments_completed"] = experiments_done;
    doc["experiments_planned"] = experiments;
    if (!complete) doc["incomplete_reason"] = reason;
}

// ---- helpers ---------------------------------------------------------------------

static double now_s()
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

// Mean over excited lines and outputs of the per-period output SNR |mean Y|^2 / var Y (dB).
static double running_snr_db(const msid_pstats *ps, uint32_t nu, uint32_t ny, uint32_t L)
{
    if (!ps) return NAN;
    const uint32_t K = msid_pstats_count(ps), q = nu + ny;
    if (K < 2) return NAN;
    double sum = 0;
    uint32_t n = 0;
    for (uint32_t l = 0; l < L; ++l) {
        const msid_cplx *mu = msid_pstats_mean(ps, l), *S = msid_pstats_scatter(ps, l);
        for (uint32_t i = nu; i < q; ++i) {
            const double var = S[(size_t)i * q + i].re / (K - 1), p = mu[i].re * mu[i].re + mu[i].im * mu[i].im;
            if (var > 0 && p > 0) { sum += 10 * std::log10(p / var); ++n; }
        }
    }
    return n ? sum / n : NAN;
}

struct MbLink {
    msid_modbus m{};
    bool open = false;
    ~MbLink() { if (open) m.tr.be->close(m.tr.ctx); }
};

// Registers per second the link carries: RTU from the baud rate and framing, TCP measured with
// 0.1 s of full reads of the ring (sizes the poll batches; reported as link_reg_rate).
static double link_reg_rate(const DeviceUri &dev, msid_mb_client &cl, uint32_t max_regs)
{
    if (dev.kind == DeviceUri::MODBUS_RTU)
        return msid_mb_rtu_reg_rate(dev.baud, 1u + dev.data_bits + (dev.parity != 'N') + dev.stop_bits, max_regs);
    std::vector<uint16_t> buf(max_regs);
    const double t0 = now_s();
    uint64_t regs = 0;
    double el = 0;
    while ((el = now_s() - t0) < 0.1) {
        if (msid_mb_call(&cl, MSID_MB_READ_INPUT, MSID_MB_RING_ADDR, max_regs, buf.data()) < 0)
            throw Error(std::string("measuring the link: ") + cl.err);
        regs += max_regs;
    }
    return (double)regs / el;
}

static Json acquisition_json(const DeviceUri &dev, const msid_mb_client &cl, const msid_mb_acq &q,
                             const StreamFmt &sf, uint32_t crc, double lrate, double stream_s)
{
    const msid_mb_link_counters &k = cl.cnt;
    Json j;
    j["transport"] = dev.kind == DeviceUri::MODBUS_TCP ? "modbus-tcp" : "modbus-rtu";
    j["device"] = dev.text;
    j["endpoint"] = dev.name().substr(4);
    j["unit"] = dev.unit;
    j["protocol"] = fmt("msid-modbus/%u", MSID_MB_PROTO_VERSION);
    j["encoding"] = msid_mb_encoding_name(MSID_MB_ENC_S16);
    j["word_order"] = msid_mb_word_order_name(0);
    j["link_reg_rate"] = lrate;
    j["link_reg_rate_measured"] = dev.kind == DeviceUri::MODBUS_TCP;
    j["scale"] = (double)sf.scale;
    j["rate_hz"] = sf.rate;
    j["config_crc"] = crc;
    j["samples"] = q.st.cnt.samples;
    j["samples_lost"] = q.st.cnt.samples_lost;
    j["gap_events"] = q.st.cnt.gap_events;
    j["overrun_samples"] = q.cnt.overrun_samples;
    j["stale_replies"] = q.cnt.stale_replies;
    j["device_restarts"] = q.cnt.restarts;
    j["device_overruns"] = q.cnt.device_overruns;
    j["done_missing"] = q.cnt.done_missing;
    j["requests"] = k.requests;
    j["retries"] = k.retries;
    j["timeouts"] = k.timeouts;
    j["crc_errors"] = k.crc_errors;
    j["exceptions"] = k.exceptions;
    j["bad_replies"] = k.bad_replies;
    j["reconnects"] = k.reconnects;
    j["stream_seconds"] = stream_s;
    return j;
}

// ---- the session -------------------------------------------------------------------

MeasureResult measure_modbus(const DeviceUri &dev, const PlanFn &plan, Progress &pg)
{
    const std::string where = dev.name();
    MbLink L;
    msid_modbus_cfg c{};
    c.response_timeout_ms = 200;
    c.byte_timeout_ms = 50;
    c.unit = (int)dev.unit;
    if (dev.kind == DeviceUri::MODBUS_TCP) {
        c.host = dev.host.c_str();
        c.port = (int)dev.port;
    } else {
        c.rtu = 1;
        c.device = dev.device.c_str();
        c.baud = (int)dev.baud;
        c.parity = dev.parity;
        c.data_bits = (int)dev.data_bits;
        c.stop_bits = (int)dev.stop_bits;
    }
    if (msid_modbus_open(&L.m, &c) < 0) throw Error(fmt("cannot connect to %s: %s", dev.text.c_str(), L.m.err));
    L.open = true;
    msid_mb_client cl;
    msid_mb_client_init(&cl, &L.m.tr, 5, 20);

    // 1. who is there, and what runs
    if (msid_mb_read_header(&cl) < 0) throw Error(fmt("no msid-modbus device at %s: %s", dev.text.c_str(), cl.err));
    const msid_mb_header h = cl.h;
    if (h.version != MSID_MB_PROTO_VERSION)
        throw Error(fmt("register map version mismatch: the device at %s serves msid-modbus/%u, this host msid-modbus/%u",
                        dev.text.c_str(), h.version, MSID_MB_PROTO_VERSION));
    MeasurePlan P;
    plan(h.nu, P);
    const msid_design &d = P.D->d;
    if (h.nu != d.n_inputs) throw Error(fmt("the device has %u input(s) but the design has %u", h.nu, d.n_inputs));
    const uint32_t nu = h.nu, ny = h.ny, m = d.n_experiments, C = nu + ny, max_regs = 125;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS || C > MSID_MAX_CHANNELS) throw Error(fmt("the device reports %u outputs", ny));
    const uint32_t W = msid_mb_sample_regs(MSID_MB_ENC_S16, C);
    const double lrate = link_reg_rate(dev, cl, max_regs);
    if (P.sf.rate > 0 && (double)P.sf.rate * W > 0.8 * lrate)
        throw Error(fmt("the link cannot carry %u channels at %u Hz: %.0f registers/s but %s carries about %.0f "
                        "registers/s (80%% is usable); lower --rate",
                        C, P.sf.rate, (double)P.sf.rate * W, where.c_str(), lrate));

    // 2. upload the design as parameters (param_upload.hpp)
    auto cfg = config_from_design(*P.D, P.sf);
    const size_t nf = msid_params_frames(cfg.get(), nullptr, 0);
    std::vector<uint8_t> rec(nf * 8);
    msid_params_frames(cfg.get(), reinterpret_cast<uint8_t(*)[8]>(rec.data()), nf);
    const uint32_t crc = msid_can_get_u32(&rec[(nf - 1) * 8 + 4]);
    if (msid_mb_upload(&cl, MSID_MB_ENC_S16, 0, reinterpret_cast<const uint8_t(*)[8]>(rec.data()), nf) < 0)
        throw Error(fmt("design upload to %s failed: %s", where.c_str(), cl.err));
    if (cl.h.state == MSID_MB_STATE_ERROR) throw Error(fmt("the device refused the configuration: %s", msid_can_device_error_name(cl.h.error)));
    if (cl.h.state != MSID_MB_STATE_CONFIGURED)
        throw Error(fmt("the device did not confirm the configuration (state %u)", cl.h.state));
    if (cl.h.crc != crc) throw Error(fmt("the device confirmed configuration CRC %08X, the host sent %08X", cl.h.crc, crc));

    // 3. every experiment into one FRF job
    FrfJob job(P.rq, nu, ny, m, P.sf.periods, 4 * P.sf.periods + 8);
    msid_mb_acq_cfg qc{};
    qc.client = &cl;
    qc.max_regs = max_regs;
    const double per_poll = lrate * 0.02 / max_regs;   // about 20 ms of link time per poll
    qc.batch = per_poll < 1 ? 1u : per_poll > 64 ? 64u : (uint32_t)per_poll;
    qc.n_inputs = nu;
    qc.n_outputs = ny;
    qc.encoding = MSID_MB_ENC_S16;
    qc.word_order = 0;
    qc.scale = (double)P.sf.scale;
    qc.meas = job.meas();
    qc.period = d.period;
    Mem mq(msid_mb_acq_mem_size(&qc));
    msid_mb_acq q;
    check(msid_daq_core_status(msid_mb_acq_init(&q, &qc, mq.p, mq.n)), "Modbus adapter setup");

    const uint64_t per_exp = (uint64_t)P.sf.periods * d.period, total = per_exp * m;
    const double t_start = now_s();
    double stream_s = 0;
    uint32_t done = 0;
    auto state = [&](uint32_t e) {
        ProgressState s;
        s.exp = e + 1;
        s.n_exp = m;
        s.periods_target = P.sf.periods;
        for (uint32_t x = 0; x <= e && x < m; ++x) {
            const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(job.meas(), x));
            if (x == e) s.periods = k.offered;
            s.periods_total += k.offered;
            s.rejected += k.gap + k.nonfinite + k.transient_dropped;
        }
        s.lost = q.st.cnt.samples_lost;
        s.link_errors = cl.cnt.retries;
        s.snr_db = running_snr_db(msid_meas_stats(job.meas(), e), nu, ny, (uint32_t)P.rq.bins.size());
        const uint64_t got = q.st.cnt.samples + q.st.cnt.samples_lost;
        const double el = now_s() - t_start;
        if (got > 0 && el > 0) s.eta_s = el * (double)(total - std::min(total, got)) / (double)got;
        return s;
    };
    bool stopped = false;
    for (uint32_t e = 0; e < m && !stopped; ++e) {
        if (measure_stop_requested()) { stopped = true; break; }
        if (msid_mb_acq_start(&q, e, P.sf.periods) < 0)
            throw Error(fmt("experiment %u on %s: %s", e + 1, where.c_str(), cl.err));
        pg.update(state(e));
        const double t0 = now_s();
        double last = t0;
        uint64_t bad_at_progress = cl.cnt.bad_replies;
        for (;;) {
            if (measure_stop_requested()) {
                // keep what arrived: close the segment (an incomplete last period is discarded and counted)
                msid_stream_end(&q.st);
                q.open = 0;
                check(q.st.err, "measurement");
                msid_mb_command(&cl, MSID_MB_CMD_STOP, e, 0);   // best effort: the device may be gone
                stopped = true;
                break;
            }
            int prog = 0;
            const uint64_t nodone = q.cnt.done_missing;
            const int r = msid_mb_acq_poll(&q, &prog);
            if (r == 1 && q.cnt.done_missing != nodone && msid_mb_command(&cl, MSID_MB_CMD_STOP, e, 0) < 0)
                throw Error(fmt("experiment %u on %s: the device did not stop after the design's samples: %s", e + 1,
                                where.c_str(), cl.err));
            if (r == 1) { ++done; break; }
            // the core's refusal travels in the daq status (msid_daq.h: one error space)
            if (msid_daq_core_status(r) == MSID_E_CAPACITY)
                throw Error("more periods arrived than the measurement holds (device restarted too often?)");
            if (msid_daq_core_status(r) != MSID_OK) check(msid_daq_core_status(r), "measurement");
            if (r < 0 && measure_stop_requested()) continue;   // a request cut short by the signal
            if (r < 0) throw Error(fmt("experiment %u on %s: %s", e + 1, where.c_str(), cl.err));
            if (prog) {
                last = now_s();
                bad_at_progress = cl.cnt.bad_replies;
            } else if (now_s() - last > P.timeout) {
                if (cl.cnt.bad_replies > bad_at_progress)
                    throw Error(fmt("no new sample for %g s during experiment %u: replies from %s did not match "
                                    "their requests (a second master on the link?)",
                                    P.timeout, e + 1, where.c_str()));
                throw Error(fmt("the device at %s produced no new sample for %g s during experiment %u",
                                dev.text.c_str(), P.timeout, e + 1));
            } else {
                usleep(P.sf.rate ? 2000 : 200);
            }
            pg.update(state(e));
        }
        pg.update(state(e));
        stream_s += now_s() - t0;
        if (!stopped) pg.note(fmt("experiment %u/%u done", e + 1, m));
    }
    pg.done();

    // 4. the FRF of what was measured
    std::vector<ExpSource> src;
    const msid_meas *ms = job.meas();
    std::string short_of;
    for (uint32_t e = 0; e < m; ++e) {
        const msid_pstats_counts k = msid_pstats_get_counts(msid_meas_stats(ms, e));
        src.push_back({fmt("modbus:%s experiment %u", where.c_str(), e + 1), ms->samples[e], k.offered,
                       msid_meas_leftover(ms, e)});
        if (k.used < 2 && short_of.empty())
            short_of = fmt("experiment %u has %u usable period(s)", e + 1, k.used);
    }
    const std::string why = stopped ? fmt("stopped by signal %d during experiment %u of %u", measure_stop_signal(),
                                          std::min(done + 1, m), m)
                                    : "";
    if (stopped && !short_of.empty()) {
        uint64_t periods = 0;
        for (uint32_t e = 0; e < m; ++e) periods += msid_pstats_get_counts(msid_meas_stats(ms, e)).offered;
        throw Error(fmt("%s after %llu complete period(s): %s, and the FRF needs at least 2 of every experiment "
                        "(%u): nothing written",
                        why.c_str(), (unsigned long long)periods, short_of.c_str(), m),
                    128 + measure_stop_signal());
    }
    std::vector<std::string> notes;
    if (q.cnt.overrun_samples)
        notes.push_back(fmt("%llu sample(s) overwritten in the device's ring before they were read: the periods they "
                            "touch were rejected", (unsigned long long)q.cnt.overrun_samples));
    if (q.cnt.restarts) notes.push_back(fmt("the device restarted %llu time(s)", (unsigned long long)q.cnt.restarts));
    if (cl.cnt.retries)
        notes.push_back(fmt("%llu request(s) retried (%llu timeout(s), %llu bad CRC, %llu exception(s), %llu reconnect(s))",
                            (unsigned long long)cl.cnt.retries, (unsigned long long)cl.cnt.timeouts,
                            (unsigned long long)cl.cnt.crc_errors, (unsigned long long)cl.cnt.exceptions,
                            (unsigned long long)cl.cnt.reconnects));
    if (stopped) notes.push_back(why + ": the FRF uses the complete periods acquired before the stop");
    MeasureResult R;
    R.o = job.finish(src, notes);
    R.o.doc["acquisition"] = acquisition_json(dev, cl, q, P.sf, crc, lrate, stream_s);
    R.complete = !stopped;
    mark_completeness(R.o.doc, R.complete, done, m, why);
    R.summary = fmt("%zu lines, %u x %u, %u of %u experiment(s) over %s, %llu samples, %llu missing, %llu periods used, "
                    "%llu rejected%s",
                    P.rq.bins.size(), ny, nu, done, m, where.c_str(), (unsigned long long)q.st.cnt.samples,
                    (unsigned long long)q.st.cnt.samples_lost,
                    (unsigned long long)R.o.doc["periods_used"].get<uint64_t>(),
                    (unsigned long long)R.o.doc["periods_rejected"].get<uint64_t>(),
                    stopped ? " (INCOMPLETE: stopped)" : "");
    R.D = std::move(P.D);
    return R;
}

}  // namespace msidcli
