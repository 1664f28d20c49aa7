// The Modbus session (msid_acquire.hpp): open the link, identify the device, upload the design, run
// every experiment with daq's msid_mb_acq_run (retried requests, ring polling, stream into msid_meas)
// through the shared loop, and the FRF with its `acquisition` block. docs/modbus-registers.md,
// docs/measure.md.
#include "session_loop.hpp"

extern "C" {
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_modbus.h"
#include "msid_daq/msid_params.h"
}

#include <cmath>
#include <ctime>

namespace msidacq {

using msidutil::check;
using msidutil::fmt;
using msidutil::Mem;
using msidjob::FrfJob;

ModbusLink modbus_link_from_uri(const DeviceUri &dev)
{
    ModbusLink l;
    l.rtu = dev.kind == DeviceUri::MODBUS_RTU;
    l.host = dev.host;
    l.port = dev.port;
    l.device = dev.device;
    l.baud = dev.baud;
    l.parity = dev.parity;
    l.data_bits = dev.data_bits;
    l.stop_bits = dev.stop_bits;
    l.unit = dev.unit;
    l.name = dev.name();
    l.uri = dev.text;
    return l;
}

static double secs_since(const timespec &t0)
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec);
}

void open_modbus_link(const ModbusLink &l, MbLink &L)
{
    msid_modbus_cfg c{};
    c.response_timeout_ms = (int)l.response_ms;
    c.byte_timeout_ms = (int)l.byte_ms;
    c.unit = (int)l.unit;
    if (!l.rtu) {
        c.host = l.host.c_str();
        c.port = (int)l.port;
    } else {
        c.rtu = 1;
        c.device = l.device.c_str();
        c.baud = (int)l.baud;
        c.parity = l.parity;
        c.data_bits = (int)l.data_bits;
        c.stop_bits = (int)l.stop_bits;
    }
    if (msid_modbus_open(&L.m, &c) < 0)
        throw Error(l.uri.empty() ? std::string(L.m.err) : fmt("%s (%s)", L.m.err, l.uri.c_str()));
    L.open = true;
}

// Register rate of the link: RTU from baud and framing, TCP measured with 0.25 s of full reads.
static double link_reg_rate(const ModbusLink &l, msid_mb_client &cl)
{
    if (l.rtu) return msid_mb_rtu_reg_rate(l.baud, 1u + l.data_bits + (l.parity != 'N') + l.stop_bits, l.max_regs);
    std::vector<uint16_t> buf(l.max_regs);
    timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    uint64_t regs = 0;
    double el = 0;
    while ((el = secs_since(t0)) < 0.25) {
        if (msid_mb_call(&cl, MSID_MB_READ_INPUT, MSID_MB_RING_ADDR, l.max_regs, buf.data()) < 0)
            throw Error(std::string("measuring the link: ") + cl.err);
        regs += l.max_regs;
    }
    return (double)regs / el;
}

static Json acquisition_json(const ModbusLink &l, const msid_mb_client &cl, const msid_mb_acq &q, double scale,
                             uint32_t rate, uint32_t crc, double lrate)
{
    const msid_mb_link_counters &k = cl.cnt;
    const msid_mb_counters &c = q.cnt;
    const msid_stream_counters &s = q.st.cnt;
    Json j;
    j["transport"] = l.rtu ? "modbus-rtu" : "modbus-tcp";
    if (!l.uri.empty()) j["device"] = l.uri;
    j["endpoint"] = l.name.substr(4);
    j["unit"] = l.unit;
    j["protocol"] = fmt("msid-modbus/%u", MSID_MB_PROTO_VERSION);
    j["encoding"] = msid_mb_encoding_name(l.encoding);
    j["word_order"] = msid_mb_word_order_name(l.word_order);
    j["scale"] = scale;
    j["rate_hz"] = rate;
    j["config_crc"] = crc;
    j["ring_samples"] = cl.h.ring_samples;
    j["sample_regs"] = q.W;
    j["link_reg_rate"] = lrate;
    j["link_reg_rate_from"] = l.rtu ? "baud and framing" : "measured";
    j["samples"] = s.samples;
    j["samples_lost"] = s.samples_lost;
    j["gap_events"] = s.gap_events;
    j["overrun_samples"] = c.overrun_samples;
    j["overrun_events"] = c.overrun_events;
    j["device_overruns"] = c.device_overruns;
    j["stale_replies"] = c.stale_replies;
    j["device_restarts"] = c.restarts;
    j["polls"] = c.polls;
    j["requests"] = k.requests;
    j["registers_read"] = k.registers_read;
    j["registers_written"] = k.registers_written;
    j["retries"] = k.retries;
    j["timeouts"] = k.timeouts;
    j["crc_errors"] = k.crc_errors;
    j["exceptions"] = k.exceptions;
    j["bad_replies"] = k.bad_replies;
    j["skipped_replies"] = k.skipped_replies;
    j["malformed_frames"] = k.malformed_frames;
    j["io_errors"] = k.io_errors;
    j["reconnects"] = k.reconnects;
    j["stream_seconds"] = 1e-9 * (double)c.stream_ns;
    return j;
}

// The poller as the shared loop sees it: one msid_mb_acq_run per experiment, tick() after every poll.
struct MbRunner : ExperimentRunner {
    msid_mb_acq &q;
    msid_mb_client &cl;
    const ModbusLink &l;
    uint32_t silence_ms, idle_us;
    const std::function<bool()> *tick = nullptr;
    MbRunner(msid_mb_acq &q_, msid_mb_client &cl_, const ModbusLink &l_, uint32_t s, uint32_t i)
        : q(q_), cl(cl_), l(l_), silence_ms(s), idle_us(i) {}
    static int on_poll(void *u)
    {
        auto *self = static_cast<MbRunner *>(u);
        return (*self->tick)() ? 1 : 0;
    }
    bool run(uint32_t e, uint32_t periods, const std::function<bool()> &t) override
    {
        tick = &t;
        q.cfg.on_poll = on_poll;
        q.cfg.user = this;
        const int rc = msid_mb_acq_run(&q, e, periods, silence_ms, idle_us);
        if (rc == -MSID_DAQ_E_STOPPED) return false;
        if (rc < 0) {
            if (msid_daq_core_status(rc) == MSID_E_CAPACITY) throw Error(cl.err);
            check(msid_daq_core_status(rc), "measurement");   // any other core refusal, as every command reports it
            throw Error(fmt("experiment %u on %s: %s", e + 1, l.name.c_str(), cl.err));
        }
        return true;
    }
    uint64_t samples() const override { return q.st.cnt.samples; }
    uint64_t lost() const override { return q.st.cnt.samples_lost; }
    uint64_t link_errors() const override { return cl.cnt.retries; }
};

MeasureResult measure_modbus(const ModbusLink &l, const PlanFn &plan, Control &ctl)
{
    MbLink L;
    open_modbus_link(l, L);
    msid_mb_client cl;
    msid_mb_client_init(&cl, &L.m.tr, l.retries, 20);

    // 1. who is there, and what runs
    int rc = msid_mb_identify(&cl);
    if (rc == -MSID_DAQ_E_PROTOCOL) throw Error(fmt("%s (on %s)", cl.err, l.name.c_str()));
    if (rc < 0) throw Error(fmt("no msid-modbus device answered on %s: %s", l.name.c_str(), cl.err));
    const msid_mb_header &h = cl.h;
    MeasurePlan P;
    plan(h.nu, P);
    const msid_design &d = P.D->d;
    if (h.nu != d.n_inputs)
        throw Error(fmt("the device has %u input(s) but the design has %u", h.nu, d.n_inputs), 1,
                    msidutil::ErrorKind::data);
    check_input_resolution(P, l.encoding != MSID_MB_ENC_F32);
    const uint32_t nu = h.nu, ny = h.ny, m = d.n_experiments, C = nu + ny;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS || C > MSID_MAX_CHANNELS) throw Error(fmt("the device reports %u outputs", ny));
    const uint32_t W = msid_mb_sample_regs(l.encoding, C);
    if (W > l.max_regs)
        throw Error(fmt("one sample of %u %s channels takes %u registers, more than " MSID_OPT("max_regs") " %u", C,
                        msid_mb_encoding_name(l.encoding), W, l.max_regs));

    // 2. can the link carry it?
    const double lrate = link_reg_rate(l, cl);
    if (P.sf.rate > 0 && (double)P.sf.rate * W > 0.8 * lrate)
        throw Error(fmt("the link cannot carry %u channels at %u Hz: %.0f registers/s (%u per sample: a tag and %u %s "
                        "value(s)) but %s carries about %.0f registers/s %s (80%% of it is usable beside header "
                        "polls and retries); lower " MSID_OPT("rate") "%s",
                        C, P.sf.rate, (double)P.sf.rate * W, W, C, msid_mb_encoding_name(l.encoding), l.name.c_str(),
                        lrate,
                        !l.rtu ? "(measured with 125-register reads)"
                               : fmt("(%u-register reads at %u baud, from the framing)", l.max_regs, l.baud).c_str(),
                        l.encoding != MSID_MB_ENC_S16 ? " or use int16" : ""));

    // 3. upload the design as parameters (the client decodes the device's verdict)
    auto cfg = config_from_design(*P.D, P.sf);
    const size_t nf = msid_params_frames(cfg.get(), nullptr, 0);
    std::vector<uint8_t> rec(nf * 8);
    msid_params_frames(cfg.get(), reinterpret_cast<uint8_t(*)[8]>(rec.data()), nf);
    const uint32_t crc = msid_can_get_u32(&rec[(nf - 1) * 8 + 4]);
    rc = msid_mb_configure(&cl, l.encoding, l.word_order, reinterpret_cast<const uint8_t(*)[8]>(rec.data()), nf);
    if (rc == -MSID_DAQ_E_DEVICE || rc == -MSID_DAQ_E_PROTOCOL) throw Error(cl.err);
    if (rc < 0) throw Error(fmt("design upload to %s failed: %s", l.name.c_str(), cl.err));

    // 4. every experiment into one FRF job, through the shared loop
    FrfJob job(P.rq, nu, ny, m, P.sf.periods, 4 * P.sf.periods + 8);
    msid_mb_acq_cfg qc{};
    qc.client = &cl;
    qc.max_regs = l.max_regs;
    const double per_poll = lrate * 0.02 / l.max_regs;   // batches sized to the link: about 20 ms per poll
    qc.batch = per_poll < 1 ? 1u : per_poll > 64 ? 64u : (uint32_t)per_poll;
    qc.n_inputs = nu;
    qc.n_outputs = ny;
    qc.encoding = l.encoding;
    qc.word_order = l.word_order;
    qc.scale = (double)P.sf.scale;
    qc.meas = job.meas();
    qc.period = d.period;   // the header's P and K P are checked against the design
    Mem mq(msid_mb_acq_mem_size(&qc));
    msid_mb_acq q;
    check(msid_daq_core_status(msid_mb_acq_init(&q, &qc, mq.p, mq.n)), "Modbus adapter setup");
    MbRunner runner(q, cl, l, (uint32_t)std::ceil(P.timeout * 1000.0), P.sf.rate ? 2000u : 200u);
    const LoopResult lr = run_experiments(runner, job.meas(), P, ctl);

    // 5. the FRF of what was measured
    std::vector<std::string> notes;
    if (q.cnt.overrun_samples)
        notes.push_back(fmt("%llu sample(s) overwritten in the device's ring before they were read (%llu overrun(s)): "
                            "the periods they touch were rejected",
                            (unsigned long long)q.cnt.overrun_samples, (unsigned long long)q.cnt.overrun_events));
    if (q.cnt.done_missing)
        notes.push_back(fmt("%llu experiment(s) ended after the design's %u x %u samples without the device "
                            "reporting DONE", (unsigned long long)q.cnt.done_missing, P.sf.periods, d.period));
    if (q.cnt.restarts) notes.push_back(fmt("the device restarted %llu time(s)", (unsigned long long)q.cnt.restarts));
    if (cl.cnt.retries)
        notes.push_back(fmt("%llu request(s) retried (%llu timeout(s), %llu bad CRC, %llu exception(s), %llu malformed "
                            "frame(s), %llu reconnect(s))",
                            (unsigned long long)cl.cnt.retries, (unsigned long long)cl.cnt.timeouts,
                            (unsigned long long)cl.cnt.crc_errors, (unsigned long long)cl.cnt.exceptions,
                            (unsigned long long)cl.cnt.malformed_frames, (unsigned long long)cl.cnt.reconnects));
    if (cl.cnt.skipped_replies)
        notes.push_back(fmt("%llu stale or foreign repl(ies) skipped (transaction or unit id not the request's)",
                            (unsigned long long)cl.cnt.skipped_replies));
    MeasureResult R = finish_measure(job, P, lr, "modbus:" + l.name, notes);
    R.o.tail()["acquisition"] = acquisition_json(l, cl, q, (double)P.sf.scale, P.sf.rate, crc, lrate);
    set_summary(R, P, ny, nu, lr.done,
                fmt("%s (%s %s)", l.name.c_str(), msid_mb_encoding_name(l.encoding), msid_mb_word_order_name(l.word_order)),
                q.st.cnt.samples, q.st.cnt.samples_lost);
    R.D = std::move(P.D);
    return R;
}

}  // namespace msidacq
