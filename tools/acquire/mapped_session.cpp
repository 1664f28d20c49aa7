// A described device measured with host-timed excitation (msid_mapped.hpp): open the link, write the safe
// values, find how one tick's exchange runs and whether the rate fits, check every value against the limits,
// run every experiment through msid_hx and the shared loop, write the safe values on every way out, and the
// FRF with its `acquisition` block (timing included). docs/devices.md.
#include "msid_mapped.hpp"
#include "mapped_link.hpp"
#include "session_loop.hpp"
#include "timing_report.hpp"

extern "C" {
#include "msid_daq/msid_devdesc_file.h"
#include "msid_daq/msid_hx.h"
#include "msid_daq/msid_mb_map.h"
#include "msid_daq/msid_mb_proto.h"
#include "msid_daq/msid_modbus.h"
}

#include <algorithm>
#include <cmath>
#include <cstring>

namespace msidacq {

using msidutil::fmt;
using msidutil::Mem;
using msidjob::FrfJob;

msid_devdesc load_description(const std::string &path)
{
    msid_devdesc d;
    char err[512];
    if (msid_devdesc_load(path.c_str(), &d, err, sizeof err) != 0) throw UsageError(err);
    return d;
}

ChannelPlan channel_plan(const msid_devdesc &d)
{
    ChannelPlan p;
    p.read_back = msid_devdesc_count(&d, MSID_DEV_ROLE_INPUT) == d.n_drive;
    for (uint32_t i = 0; i < d.n_drive; ++i) {
        const int rb = p.read_back ? msid_devdesc_readback(&d, i) : -1;
        p.input_of.push_back(rb);
        const msid_dev_chan &c = rb >= 0 ? d.measure[rb] : d.drive[i];
        p.input_names.push_back(c.name);
        p.input_units.push_back(c.unit);
    }
    for (uint32_t j = 0; j < d.n_measure; ++j) {
        const msid_dev_chan &c = d.measure[j];
        if (c.role == MSID_DEV_ROLE_OUTPUT) {
            p.outputs.push_back(j);
            p.output_names.push_back(c.name);
            p.output_units.push_back(c.unit);
        }
        if (c.role == MSID_DEV_ROLE_COUNTER) p.counter = (int)j;
    }
    return p;
}

namespace {

// The counter's wrap: 2^16 or 2^32 counts of its register type.
double register_modulus(const msid_dev_chan &c)
{
    switch (c.type) {
    case MSID_DEV_INT16: case MSID_DEV_UINT16: return 65536.0;
    case MSID_DEV_INT32: case MSID_DEV_UINT32: return 4294967296.0;
    default: return 9007199254740992.0;   // a float counter does not wrap within a run
    }
}

// The link of a URI with the description's unit (the URI's ?unit= wins when it names one).
ModbusLink mapped_link(const DeviceUri &dev, const msid_devdesc &d)
{
    ModbusLink l = modbus_link_from_uri(dev);
    if (d.unit && dev.text.find("unit=") == std::string::npos) l.unit = d.unit;
    return l;
}

void check_transport(const DeviceUri &dev, const msid_devdesc &d)
{
    if (d.transport == MSID_DEV_MODBUS && !dev.is_modbus())
        throw UsageError(fmt("%s describes a Modbus device, but the device URI is %s", d.source, dev.text.c_str()));
    if (d.transport == MSID_DEV_CAN && dev.kind != DeviceUri::CAN)
        throw UsageError(fmt("%s describes a CAN device, but the device URI is %s", d.source, dev.text.c_str()));
    if (d.transport == MSID_DEV_CANOPEN && dev.kind != DeviceUri::CANOPEN)
        throw UsageError(fmt("%s describes a CANopen drive, but the device URI is %s: use canopen://IFACE?node=N",
                             d.source, dev.text.c_str()));
    if (d.transport != MSID_DEV_CANOPEN && dev.kind == DeviceUri::CANOPEN)
        throw UsageError(fmt("%s does not describe a CANopen drive (transport = \"canopen\"), but the device URI is %s",
                             d.source, dev.text.c_str()));
}

// The drive channels as the runner sees them: the operating point, the gain that gives the amplitude, limits.
void drive_channels(const msid_devdesc &d, const double *peak, msid_hx_cfg &c)
{
    for (uint32_t i = 0; i < d.n_drive; ++i) {
        const msid_dev_chan &ch = d.drive[i];
        msid_hx_drive &x = c.drive[i];
        x.name = ch.name;
        x.safe = ch.safe;
        x.op = std::isnan(ch.op) ? ch.safe : ch.op;
        x.min = ch.min;
        x.max = ch.max;
        x.max_step = ch.max_step;
        double amp = ch.amplitude;
        if (std::isnan(amp)) {
            // half the room to the nearest limit
            double room = INFINITY;
            if (!std::isnan(ch.min)) room = std::min(room, x.op - ch.min);
            if (!std::isnan(ch.max)) room = std::min(room, ch.max - x.op);
            if (!std::isfinite(room))
                throw UsageError(fmt("%s line %u: drive channel '%s' has neither amplitude nor min/max: give amplitude "
                                     "(the excitation's peak around the operating point, %s)",
                                     d.source, ch.line, ch.name, ch.unit[0] ? ch.unit : "physical units"));
            if (!(room > 0))
                throw UsageError(fmt("%s line %u: drive channel '%s': the operating point %g leaves no room to a limit; "
                                     "give amplitude, or an operating_point inside (min, max)",
                                     d.source, ch.line, ch.name, x.op));
            amp = 0.5 * room;
        }
        if (!(peak[i] > 0)) throw UsageError(fmt("the design's input %u is zero", i + 1));
        x.gain = amp / peak[i];
    }
}

// Exchanges at full speed writing the safe values: the round trip of one tick's exchange, p90 and max (s).
struct Probe {
    double p90 = 0, max = 0, median = 0;
    uint32_t n = 0;
};
// A link whose device answers no request (CAN: the status frames come on the device's own cycle) probes the
// writes alone: what the bus takes to carry one tick's frames.
Probe probe_round_trip(msid_devio &io, const msid_devdesc &d, uint32_t n, bool writes_only)
{
    std::vector<double> drive(d.n_drive), meas(d.n_measure + 1), rtt;   // (+1: a link's own counter)
    for (uint32_t i = 0; i < d.n_drive; ++i) drive[i] = d.drive[i].safe;
    for (uint32_t k = 0; k < n; ++k) {
        msid_devio_times t{};
        const int rc = writes_only ? msid_devio_write(&io, drive.data(), &t)
                                   : msid_devio_exchange(&io, drive.data(), meas.data(), &t);
        if (rc < 0) throw Error(fmt("one tick's exchange failed: %s", msid_devio_error(&io)));
        const int64_t a = t.w0 ? t.w0 : t.r0, b = t.r1 ? t.r1 : t.w1;
        rtt.push_back(1e-9 * (double)(b - a));
    }
    std::sort(rtt.begin(), rtt.end());
    Probe p;
    p.n = n;
    p.median = rtt[rtt.size() / 2];
    p.p90 = rtt[std::min(rtt.size() - 1, (size_t)std::ceil(0.9 * (double)rtt.size()) - 1)];
    p.max = rtt.back();
    return p;
}

// The ticks of the shared loop: msid_hx_run per experiment; tick() every ~20 ms of ticks.
struct HxRunner : ExperimentRunner {
    msid_hx &h;
    const MappedLink &link;
    const std::function<bool()> *tick = nullptr;
    uint32_t every = 1, count = 0;
    HxRunner(msid_hx &h_, const MappedLink &l, double rate) : h(h_), link(l), every(std::max(1u, (uint32_t)(rate / 50))) {}
    static int on_tick(void *u)
    {
        auto *r = static_cast<HxRunner *>(u);
        if (++r->count % r->every) return 0;
        if (!r->link.fatal().empty()) return 1;
        return (*r->tick)() ? 1 : 0;
    }
    bool run(uint32_t e, uint32_t, const std::function<bool()> &t) override
    {
        tick = &t;
        h.cfg.on_tick = on_tick;
        h.cfg.user = this;
        const int rc = msid_hx_run(&h, e);
        const std::string why = link.fatal();
        if (!why.empty())
            throw Error(fmt("experiment %u: %s: the run ended (safe target, quick stop, disable voltage)", e + 1,
                            why.c_str()), 1, msidutil::ErrorKind::io);
        if (rc == -MSID_DAQ_E_STOPPED) return false;
        if (rc < 0) {
            if (msid_daq_core_status(rc) != MSID_OK) msidutil::check(msid_daq_core_status(rc), "measurement");
            throw Error(fmt("experiment %u: %s", e + 1, h.err), 1,
                        rc == -MSID_DAQ_E_DEVICE ? msidutil::ErrorKind::data : msidutil::ErrorKind::io);
        }
        return true;
    }
    uint64_t samples() const override { return h.cnt.samples; }
    uint64_t lost() const override { return h.cnt.samples_lost; }
    uint64_t link_errors() const override { return h.cnt.failed + h.cnt.failed_other; }
    void timing(ProgressState &s) const override
    {
        s.lateness_p99_s = 1e-9 * msid_tstats_quantile(&h.tick.lateness, 0.99);
        s.missed_ticks = h.tick.missed;
    }
};

// What lost a run's samples, for the message of a run that gave no FRF: ticks missed, exchanges that read
// nothing, device cycles not read, and the tick clock's lateness.
std::string losses_summary(const msid_hx &h, double rate_hz, const std::string &exchange)
{
    if (!h.cnt.samples_lost) return "";
    const Json t = timing_json(h, rate_hz, exchange, 0.0);
    // placed by the device's counter, a tick the host slept through loses no sample of its own: the cycles it
    // did not read are counted as such, and the tick clock's own count says how far the host fell behind
    const bool by_counter = h.cfg.index_by_counter || h.cfg.follow_counter;
    const std::string missed = by_counter ? fmt("%llu tick(s) the host slept through", (unsigned long long)h.tick.missed)
                                          : fmt("%llu tick(s) missed", (unsigned long long)h.cnt.missed);
    return fmt(" (of the run's %llu measured samples %llu were lost: %s, %llu exchange(s) that read nothing, %llu "
               "device cycle(s) not read; tick lateness p99 %.3g ms, wake-up p99 %.3g ms at %g Hz)",
               (unsigned long long)(h.cnt.samples + h.cnt.samples_lost), (unsigned long long)h.cnt.samples_lost,
               missed.c_str(), (unsigned long long)h.cnt.failed, (unsigned long long)h.cnt.cycles_not_read,
               1e3 * t["lateness_s"]["p99"].get<double>(), 1e3 * t["wake_lateness_s"]["p99"].get<double>(), rate_hz);
}

// The safe values on every way out: the destructor writes them unless the run finished with its ramp.
// `patient` gives the link time to answer first (the tick's timeouts are for the ticks).
struct SafeGuard {
    msid_hx *h = nullptr;
    bool done = false;
    std::function<void()> patient;
    ~SafeGuard()
    {
        if (h && !done) {
            if (patient) patient();
            msid_hx_safe(h, 5);
        }
        if (h) msid_hx_release(h);
    }
};

// A Modbus description's link: the register map over TCP or RTU, FC 23 where the device answers it.
class ModbusMapped : public MappedLink {
public:
    ModbusMapped(const DeviceUri &dev, const msid_devdesc &d) : desc_(d), l_(mapped_link(dev, d))
    {
        open_modbus_link(l_, L_);
        if (msid_mb_map_init(&mm_, &d, &L_.m.tr, d.fc23 != 0) < 0) throw Error(mm_.err);
        if (d.fc23 == 1 && !mm_.use_fc23)
            throw UsageError(fmt("%s: fc23 = true, but function 23 cannot carry this map (it needs the drive channels "
                                 "in one span of at most 121 holding registers and a holding register to read)",
                                 d.source));
    }
    msid_devio &io() override { return mm_.io; }
    std::string name() const override { return l_.name; }
    std::string source() const override { return "modbus:" + l_.name; }
    // function 23 where the device answers it (fc23 = "auto")
    void prepare(const std::vector<double> &safe, std::vector<std::string> &notes) override
    {
        if (!mm_.use_fc23 || desc_.fc23 != -1) return;
        std::vector<double> meas(desc_.n_measure);
        msid_devio_times t{};
        if (msid_devio_exchange(&mm_.io, safe.data(), meas.data(), &t) < 0) {
            if (mm_.cnt.last_exception == 1 && mm_.cnt.last_function == 23) {
                mm_.use_fc23 = 0;
                notes.push_back("the device refused function 23 (illegal function): each tick writes (FC 16) and "
                                "reads (FC 03/04) in separate transactions");
            } else {
                throw Error(fmt("%s: %s", l_.name.c_str(), mm_.err));
            }
        }
    }
    void tick_timeouts(double T) override
    {
        const uint32_t tick_ms = std::max(2u, (uint32_t)std::ceil(0.9 * T * 1000.0));
        msid_mb_set_timeouts(&L_.m.tr, std::min<uint32_t>(tick_ms, 1000), std::min<uint32_t>(tick_ms, 50));
    }
    // a slow device is reported by its round trip, not by a timeout; the way out gives the link time to answer
    void probe_timeouts() override { msid_mb_set_timeouts(&L_.m.tr, 1000, 50); }
    void exit_timeouts() override { msid_mb_set_timeouts(&L_.m.tr, 500, 50); }
    std::string error() const override { return mm_.err; }
    double counter_modulus(uint32_t i) const override { return register_modulus(desc_.measure[i]); }
    void acquisition(Json &acq, const DeviceUri &dev) const override
    {
        acq["transport"] = l_.rtu ? "modbus-rtu" : "modbus-tcp";
        acq["device"] = dev.text;
        acq["endpoint"] = l_.name.substr(4);
        acq["unit"] = l_.unit;
        acq["requests"] = mm_.cnt.requests;
        acq["failures"] = mm_.cnt.failures;
        acq["timeouts"] = mm_.cnt.timeouts;
        acq["exceptions"] = mm_.cnt.exceptions;
        acq["bad_replies"] = mm_.cnt.bad_replies;
        acq["io_errors"] = mm_.cnt.io_errors;
        acq["recoveries"] = mm_.cnt.recoveries;
        acq["skipped_replies"] = msid_mb_skipped(&const_cast<MbLink &>(L_).m.tr);
    }

private:
    const msid_devdesc &desc_;
    ModbusLink l_;
    MbLink L_;
    msid_mb_map mm_;
};

Json channels_json(const msid_devdesc &d)
{
    Json a = Json::array();
    auto one = [&](const msid_dev_chan &c, const char *kind) {
        Json j;
        j["name"] = c.name;
        j["kind"] = kind;
        if (c.unit[0]) j["unit"] = c.unit;
        if (std::strcmp(kind, "measure") == 0) {
            static const char *const roles[] = {"", "input", "output", "reference", "counter"};
            j["role"] = roles[c.role];
        }
        if (d.transport == MSID_DEV_CANOPEN) {
            j["object"] = fmt("0x%04X:%02X", (unsigned)c.co_index, (unsigned)c.co_sub);
            j["type"] = msid_dev_type_name(c.type);
        } else if (d.transport == MSID_DEV_MODBUS) {
            j["register"] = fmt("%s:%u", c.table == MSID_DEV_HOLDING ? "holding" : "input", c.addr);
            j["type"] = msid_dev_type_name(c.type);
            j["word_order"] = msid_mb_word_order_name(c.word_order);
        } else {
            j["message"] = c.message;
            j["signal"] = c.signal;
        }
        j["scale"] = c.scale;
        j["offset"] = c.offset;
        if (std::strcmp(kind, "drive") == 0) {
            j["safe"] = c.safe;
            for (auto [k, v] : {std::pair<const char *, double>{"min", c.min}, {"max", c.max}, {"max_step", c.max_step}})
                if (!std::isnan(v)) j[k] = v;
        }
        a.push_back(j);
    };
    for (uint32_t i = 0; i < d.n_drive; ++i) one(d.drive[i], "drive");
    for (uint32_t i = 0; i < d.n_measure; ++i) one(d.measure[i], "measure");
    return a;
}

}  // namespace

MeasureResult measure_mapped(const DeviceUri &dev, const msid_devdesc &desc, const MappedOptions &o, const PlanFn &plan,
                             Control &ctl)
{
    check_transport(dev, desc);
    if (!(o.rate_hz > 0 && o.rate_hz <= 100000))
        throw UsageError("a described device needs the tick rate: " MSID_OPT("rate") " HZ (0 < HZ <= 100000)");
    ChannelPlan cp = channel_plan(desc);
    MeasurePlan P;
    plan(desc.n_drive, P);
    const msid_design &d = P.D->d;
    if (d.n_inputs != desc.n_drive)
        throw UsageError(fmt("the design has %u input(s) but %s has %u drive channel(s)", d.n_inputs, desc.source,
                             desc.n_drive));
    if (d.is_ct) throw UsageError("a described device is excited on the host's tick clock: give a discrete-time design");
    P.rq.fs = o.rate_hz;
    P.rq.sample_time = 1.0 / o.rate_hz;
    P.rq.input_names = cp.input_names;
    P.rq.input_units = cp.input_units;
    P.rq.output_names = cp.output_names;
    P.rq.output_units = cp.output_units;
    const uint32_t nu = d.n_inputs, ny = (uint32_t)cp.outputs.size(), m = d.n_experiments;

    // 1. the link
    std::unique_ptr<MappedLink> link;
    if (desc.transport == MSID_DEV_CAN) link = open_can_mapped(dev, desc);
    else if (desc.transport == MSID_DEV_CANOPEN) link = open_canopen_mapped(dev, desc, o.rate_hz);
    else link = std::make_unique<ModbusMapped>(dev, desc);
    const msid_devdesc &rdesc = link->resolved() ? *link->resolved() : desc;
    msid_devio &io = link->io();
    // a counter the link keeps (the kernel's SYNC count) places the samples as a device's own counter would
    const bool own_counter = link->own_counter() >= 0;
    if (own_counter) cp.counter = link->own_counter();
    const std::string lname = link->name();

    // 2. the safe values first: the device holds them before the excitation's approach starts
    std::vector<double> safe(desc.n_drive);
    for (uint32_t i = 0; i < desc.n_drive; ++i) safe[i] = desc.drive[i].safe;
    {
        msid_devio_times t{};
        if (msid_devio_write(&io, safe.data(), &t) < 0)
            throw Error(fmt("%s: the device did not accept the safe values: %s", lname.c_str(), link->error().c_str()));
    }
    std::vector<std::string> notes;   // (with the rate probe's below)
    link->prepare(safe, notes);
    const double T = 1.0 / o.rate_hz;
    link->tick_timeouts(T);

    // 3. can the link carry the rate? the round trip of one exchange, measured at full speed
    link->check_rate(o.rate_hz);
    const uint32_t nprobe = (uint32_t)std::clamp(o.rate_hz * 0.25, 20.0, 200.0);
    Probe pr;
    // measured with generous timeouts: a slow device is reported by its round trip, not by a timeout
    link->probe_timeouts();
    pr = probe_round_trip(io, desc, nprobe, link->probe_writes_only());
    link->tick_timeouts(T);
    // the median decides (what the link carries); a slow tail is said, and costs missing samples, counted
    if (pr.median > 0.8 * T)
        throw UsageError(fmt("%s cannot carry %g ticks per second: one tick's exchange (%s) takes %.3g ms (median of "
                             "%u; p90 %.3g ms), %g Hz leaves %.3g ms per tick; it carries at most about %.0f Hz",
                             lname.c_str(), o.rate_hz, msid_devio_describe(&io), 1e3 * pr.median, pr.n,
                             1e3 * pr.p90, o.rate_hz, 1e3 * T, std::floor(0.8 / pr.median)));
    std::vector<std::string> early_notes;
    if (pr.p90 > 0.8 * T)
        early_notes.push_back(fmt("one in ten of the first %u exchanges took more than %.3g ms (p90 %.3g ms) of the %.3g "
                                  "ms a tick leaves: expect missing samples (counted), or lower the rate",
                                  pr.n, 0.8e3 * T, 1e3 * pr.p90, 1e3 * T));

    // 4. the runner: every value checked against the limits before anything more is written
    FrfJob job(P.rq, nu, ny, m, P.sf.periods, 4 * P.sf.periods + 8);
    msid_hx_cfg hc{};
    hc.design = &d;
    hc.twiddle = &P.D->tw;
    hc.periods = P.sf.periods;
    hc.fade_periods = desc.fade_periods;
    hc.n_measure = desc.n_measure + (own_counter ? 1u : 0u);
    {
        msid_gen_cfg gc{};
        gc.design = &d;
        gc.twiddle = &P.D->tw;
        gc.waveform_table = 1;
        Mem gm(msid_gen_mem_size(&gc));
        std::vector<double> peak(nu);
        if (msid_hx_peaks(&d, &P.D->tw, gm.p, gm.n, peak.data()) < 0) throw Error("excitation generator failed");
        drive_channels(desc, peak.data(), hc);
    }
    for (uint32_t i = 0; i < nu; ++i) hc.input_of[i] = cp.input_of[i];
    hc.n_outputs = ny;
    for (uint32_t j = 0; j < ny; ++j) hc.output_of[j] = cp.outputs[j];
    hc.counter = cp.counter;
    hc.counter_modulus = cp.counter >= 0 ? link->counter_modulus((uint32_t)cp.counter) : 0;
    // the device's cycles as the samples: a counter of a device that cycles at the tick rate (each cycle gets its
    // sample and is read as itself, so that the read-back and the commanded value are both the cycle's)
    const bool cycles_at_rate = std::isnan(desc.cycle_hz) || std::fabs(desc.cycle_hz / o.rate_hz - 1) < 0.01;
    hc.follow_counter = desc.clock == MSID_DEV_CLOCK_DEVICE ? 1 : 0;
    hc.index_by_counter = cp.counter >= 0 && cycles_at_rate ? 1 : 0;
    if (hc.follow_counter && !cycles_at_rate)
        throw UsageError(fmt("%s: clock = \"device\" follows a device that cycles at the tick rate, but cycle_hz is %g and "
                             MSID_OPT("rate") " %g", desc.source, desc.cycle_hz, o.rate_hz));
    hc.io = &io;
    hc.meas = job.meas();
    hc.tick.rate_hz = o.rate_hz;
    hc.tick.realtime = o.realtime ? 1 : 0;
    hc.silence_ms = (uint32_t)std::ceil(o.timeout * 1000.0);
    Mem hm(msid_hx_mem_size(&hc));
    if (!hm.n) throw Error("host excitation: invalid configuration");
    msid_hx h;
    SafeGuard guard;
    const int irc = msid_hx_init(&h, &hc, hm.p, hm.n);
    if (irc == -MSID_DAQ_E_ARG) throw UsageError(fmt("%s: %s", desc.source, h.err));
    if (irc < 0) throw Error(h.err[0] ? h.err : msid_daq_message(irc));
    guard.h = &h;
    guard.patient = [&link] { link->exit_timeouts(); };
    if (!h.tick.fifo || !h.tick.locked) notes.push_back("tick clock: " + std::string(h.tick.sched));
    notes.insert(notes.end(), early_notes.begin(), early_notes.end());

    // 5. every experiment through the shared loop; the safe values at the end (ramped) or on any way out
    HxRunner runner(h, *link, o.rate_hz);
    // a run that ends without an FRF (too few usable periods) says what lost its samples: no file will hold it
    const auto with_losses = [&](auto &&step) {
        try {
            return step();
        } catch (const msidutil::Error &e) {   // the FRF job's errors and the acquisition's alike
            throw Error(e.text() + losses_summary(h, o.rate_hz, msid_devio_describe(&io)), e.code, e.kind);
        }
    };
    const LoopResult lr = with_losses([&] { return run_experiments(runner, job.meas(), P, ctl); });
    guard.patient();
    const int frc = msid_hx_finish(&h);
    guard.done = true;
    if (frc < 0) notes.push_back(std::string("at the end: ") + h.err);
    link->close(notes);

    // 6. the FRF of what was measured, what it rests on, and the timing
    if (h.cnt.missed)
        notes.push_back(fmt("%llu tick(s) of the measured periods were missed (the host fell behind): their samples "
                            "are missing and the periods they touch were rejected",
                            (unsigned long long)h.cnt.missed));
    if (h.cnt.failed)
        notes.push_back(fmt("%llu exchange(s) of the measured periods read nothing (%s): their samples are missing and "
                            "the periods they touch were rejected",
                            (unsigned long long)h.cnt.failed, link->error().empty() ? "no answer" : link->error().c_str()));
    const bool by_counter = hc.index_by_counter || hc.follow_counter;
    if (!cp.read_back && !by_counter)
        notes.push_back("the FRF's input is the commanded value (no measure channel reads the applied input back): "
                        "the host's timing enters the estimate; each line's timing_bias bounds it");
    if (!cp.read_back && by_counter)
        notes.push_back("the FRF's input is the commanded value of each device cycle (placed by the device's counter: "
                        "a cycle whose write came late is a missing sample, so the host's timing does not enter)");
    if (h.cnt.cycles_not_read || h.cnt.cycles_read_twice)
        notes.push_back(fmt("by the device's counter, %llu cycle(s) of the measured periods were not read or ran on "
                            "another cycle's value (missing samples: their periods were rejected; %llu write(s) "
                            "straddled by a cycle) and %llu read twice (the second read dropped)",
                            (unsigned long long)h.cnt.cycles_not_read, (unsigned long long)h.cnt.writes_straddled,
                            (unsigned long long)h.cnt.cycles_read_twice));
    MeasureResult R = with_losses([&] { return finish_measure(job, P, lr, link->source(), notes); });
    // the device's clock against the host's (from its counter): reported; with the samples placed by the counter
    // its offset moves no sample to another cycle, and without a counter it cannot be seen
    const double nominal_hz = std::isnan(desc.cycle_hz) ? o.rate_hz : desc.cycle_hz;
    if (cp.counter < 0)
        R.o.notes.push_back("the device's clock is not observed (no channel with role = \"counter\"): a device that "
                            "samples on its own clock drifts against the host's unseen; docs/devices.md");
    if (!cp.read_back && !by_counter) {
        const std::string note = add_timing_bias(R.o.tree(), tick_timing(h, desc.cycle_hz), o.rate_hz, d.period);
        if (!note.empty()) R.o.notes.push_back(note);
    }
    Json acq;
    link->acquisition(acq, dev);
    acq["protocol"] = "msid-device/1";
    acq["description"] = o.desc_path.empty() ? std::string(desc.source) : o.desc_path;
    if (desc.name[0]) acq["device_name"] = desc.name;
    acq["input"] = cp.read_back ? "read back" : "commanded";
    acq["channels"] = channels_json(rdesc);
    acq["fade_periods"] = desc.fade_periods;
    acq["probe_round_trip_s"] = {{"median", pr.median}, {"p90", pr.p90}, {"max", pr.max}, {"count", pr.n}};
    acq["samples"] = h.cnt.samples;
    acq["samples_lost"] = h.cnt.samples_lost;
    acq["safe_values_written"] = frc == 0;
    acq["timing"] = timing_json(h, o.rate_hz, msid_devio_describe(&io), cp.counter >= 0 ? nominal_hz : 0.0);
    R.o.tail()["acquisition"] = acq;
    if (desc.co_closed_loop) {
        // the FRF ran on the reference (the target the drive applied: the velocity target, or the torque offset
        // of the torque-loop preset); the plant through it is the file
        const auto it = std::find(cp.output_names.begin(), cp.output_names.end(), std::string("Torque demand"));
        const uint32_t iu = (uint32_t)(it - cp.output_names.begin());
        R.o.notes.push_back(
            desc.co_closed_loop == 2
                ? fmt("closed loop (preset csv-torque-loop, the velocity loop holding %g %s): frf.json is the plant "
                      "from the torque demand to the actual values, estimated through the reference (G = G_yr "
                      "G_ur^-1); reference.json is the FRF from the torque reference (the torque offset 0x60B2) to "
                      "every signal (its torque demand row the loop's sensitivity S = 1 / (1 + C Gp), its velocity "
                      "row Gp S as the TPDOs sample it)", desc.co_hold_velocity, desc.velocity_unit)
                : std::string("closed loop (preset csv-loop): frf.json is the plant from the torque demand to the "
                              "actual values, estimated through the reference (G = G_yr G_ur^-1); reference.json is "
                              "the FRF from the velocity reference to every signal (its torque demand row the control "
                              "sensitivity C S, its velocity row the complementary sensitivity T as the TPDOs sample "
                              "it)"));
        R.reference = R.o.tree();   // the document of the reference path (the typed result left empty)
        R.o.doc = plant_through_reference(R.reference, iu);
        if (R.o.doc.contains("notes")) R.o.doc["notes"].push_back(R.o.notes.back());
        if (R.reference.contains("notes")) R.reference["notes"].push_back(R.o.notes.back());
    }
    set_summary(R, P, ny, nu, lr.done, fmt("%s (%s)", lname.c_str(), msid_devio_describe(&io)), h.cnt.samples,
                h.cnt.samples_lost);
    R.D = std::move(P.D);
    return R;
}

CheckResult check_device(const DeviceUri &dev, const msid_devdesc &desc)
{
    check_transport(dev, desc);
    if (desc.transport == MSID_DEV_CAN) return check_can_device(dev, desc);
    if (desc.transport == MSID_DEV_CANOPEN)
        throw UsageError(fmt("%s: check a CANopen node with msid device check --device %s (and " MSID_OPT("eds") " FILE): it reads "
                             "the node's identity and PDO mapping without a description", desc.source, dev.text.c_str()));
    CheckResult r;
    ModbusLink l = mapped_link(dev, desc);
    MbLink L;
    open_modbus_link(l, L);
    msid_mb_map mm;
    if (msid_mb_map_init(&mm, &desc, &L.m.tr, 0) < 0) throw Error(mm.err);
    r.lines.push_back(fmt("%s: %s, unit %u: %u drive and %u measure channel(s) in %u write and %u read request(s)",
                          desc.source, l.name.c_str(), l.unit, desc.n_drive, desc.n_measure, mm.n_wspan, mm.n_rspan));
    // each read span on its own, so that one refused address names its channels
    std::vector<double> safe(desc.n_drive);
    for (uint32_t i = 0; i < desc.n_drive; ++i) safe[i] = desc.drive[i].safe;
    msid_devio_times t{};
    if (msid_devio_write(&mm.io, safe.data(), &t) < 0) {
        r.lines.push_back(fmt("writing the safe values: %s", mm.err));
        ++r.problems;
    } else {
        r.lines.push_back(fmt("wrote the safe values (%s)", [&] {
            std::string s;
            for (uint32_t i = 0; i < desc.n_drive; ++i)
                s += fmt("%s%s = %g%s%s", i ? ", " : "", desc.drive[i].name, desc.drive[i].safe,
                         desc.drive[i].unit[0] ? " " : "", desc.drive[i].unit);
            return s;
        }().c_str()));
    }
    // each span of measure channels on its own: a refused address names its own channels, the others are read
    std::vector<double> v(desc.n_measure, NAN);
    std::vector<std::string> refused(desc.n_measure);
    for (uint32_t sp = 0; sp < mm.n_rspan; ++sp)
        if (msid_mb_map_read_span(&mm, sp, v.data()) < 0)
            for (uint32_t i = 0; i < desc.n_measure; ++i)
                if (mm.rspan_of[i] == sp) refused[i] = mm.err;
    for (uint32_t i = 0; i < desc.n_measure; ++i) {
        const msid_dev_chan &c = desc.measure[i];
        static const char *const roles[] = {"", "input", "output", "reference", "counter"};
        const bool ok = refused[i].empty() && std::isfinite(v[i]);
        if (!ok) ++r.problems;
        const std::string mark = !refused[i].empty()     ? "  <- refused: " + refused[i]
                                 : !std::isfinite(v[i]) ? std::string("  <- not a finite number")
                                                        : std::string();
        r.lines.push_back(fmt("  %-24s %-9s %s:%u %-7s = %.9g%s%s%s", c.name, roles[c.role],
                              c.table == MSID_DEV_HOLDING ? "holding" : "input", c.addr, msid_dev_type_name(c.type),
                              v[i], c.unit[0] ? " " : "", c.unit, mark.c_str()));
    }
    // the drive registers read back: the device holds what was written
    for (uint32_t i = 0; i < desc.n_drive; ++i) {
        const msid_dev_chan &c = desc.drive[i];
        uint16_t regs[4];
        const int q = msid_mb_read_holding(&L.m.tr, c.addr, msid_dev_type_regs(c.type), regs);
        if (q < 0) {
            r.lines.push_back(fmt("  %-24s drive     holding:%u: cannot be read back (%s)", c.name, c.addr,
                                  msid_mb_error(&L.m.tr)));
            continue;
        }
        const double x = msid_dev_decode(&c, regs);
        const bool same = std::fabs(x - c.safe) <= 0.5 * std::fabs(c.scale) + 1e-12 * std::fabs(c.safe);
        if (!same) ++r.problems;
        r.lines.push_back(fmt("  %-24s drive     holding:%u %-7s = %.9g%s%s%s", c.name, c.addr,
                              msid_dev_type_name(c.type), x, c.unit[0] ? " " : "", c.unit,
                              same ? " (the safe value)" : "  <- not the safe value just written"));
    }
    return r;
}

}  // namespace msidacq
