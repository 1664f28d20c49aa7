// The CAN session (msid_acquire.hpp): open the SocketCAN socket, identify the device, plan, upload
// the design with flow control, run every experiment through the shared loop, and the FRF with its
// `acquisition` block. docs/can-protocol.md, docs/measure.md.
#include "msid_can_acq.hpp"
#include "session_loop.hpp"

extern "C" {
#include "msid_daq/msid_can_session.h"
#include "msid_daq/msid_params.h"
#include "msid_daq/msid_socketcan.h"
}

#include <cmath>

namespace msidacq {

using msidutil::check;
using msidutil::fmt;

static std::string hex(uint32_t v) { return fmt("0x%X", v); }

// Seconds one sample frame occupies the bus.
static double can_frame_seconds(bool fd, double bitrate, double data_bitrate)
{
    // Worst case with bit stuffing. Classic 8-byte data frame, 11-bit id:
    // 111 bits incl. 3 bits interframe space, +24 stuff bits.
    if (!fd) return 135.0 / bitrate;
    // FD, 64 bytes: arbitration and end at the nominal rate (30 bits + 5 stuff),
    // data phase ESI..CRC (548 bits incl. fixed stuff bits) + 129 dynamic stuff bits.
    return 35.0 / bitrate + 677.0 / data_bitrate;
}

// The session's frame hook: every frame sent and received into the --log file.
static int log_hook(void *user, const msid_can_frame *f)
{
    try {
        static_cast<CanAcq *>(user)->log_frame(*f);
        return 0;
    } catch (const Error &) {
        return -1;
    }
}

// A failed session step: one message (the session decoded the device's error), the log's when it failed.
[[noreturn]] static void session_failed(const CanAcq &acq, const msid_can_session &s, int rc)
{
    if (rc == -MSID_DAQ_E_HOOK) throw Error("cannot write '" + acq.log_path + "'");
    const msid_status st = msid_daq_core_status(rc);
    if (st != MSID_OK && st != MSID_E_CAPACITY) check(st, "decoder");   // the core's reason, as every command reports it
    throw Error(s.err);
}

CanLink can_link_from_uri(const DeviceUri &dev)
{
    CanLink l;
    l.iface = dev.iface;
    l.base = dev.base;
    l.fd = dev.fd;
    return l;
}

// The session as the shared loop of `msid measure` sees it: msid_can_session_run, tick() after every batch.
struct CanRunner : ExperimentRunner {
    msid_can_session &s;
    const CanAcq &acq;
    const std::function<bool()> *tick = nullptr;
    CanRunner(msid_can_session &s_, const CanAcq &a) : s(s_), acq(a) {}
    static int on_poll(void *u) { return (*static_cast<CanRunner *>(u)->tick)() ? 1 : 0; }
    bool run(uint32_t e, uint32_t periods, const std::function<bool()> &t) override
    {
        tick = &t;
        s.cfg.on_poll = on_poll;
        s.cfg.poll_user = this;
        const int rc = msid_can_session_run(&s, e, periods);
        if (rc == -MSID_DAQ_E_STOPPED) return false;
        if (rc < 0) session_failed(acq, s, rc);
        return true;
    }
    uint64_t samples() const override { return acq.dec.cnt.samples; }
    uint64_t lost() const override { return acq.dec.cnt.samples_lost; }
    uint64_t link_errors() const override { return acq.dec.cnt.error_frames; }
};

MeasureResult measure_can(const CanLink &l, const PlanFn &plan, Control &ctl)
{
    const std::string &iface = l.iface;
    msid_socketcan sc;
    msid_socketcan_cfg scc{};
    scc.iface = iface.c_str();
    scc.fd_frames = l.fd ? 1 : 0;
    scc.n_filters = 1;
    scc.filter_id[0] = l.base;   // the device's 128 identifiers
    scc.filter_mask[0] = 0x780u | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
    scc.err_frames = 1;
    scc.rcvbuf = l.rcvbuf;
    const int r = msid_socketcan_open(&sc, &scc);
    if (r < 0) throw Error(sc.err);
    struct Closer { msid_socketcan &s; ~Closer() { msid_can_close(&s.tr); } } closer{sc};

    CanAcq acq;
    acq.iface = iface;
    if (!l.log.empty()) acq.open_log(l.log);

    // the session: who is there?
    auto s = std::make_unique<msid_can_session>();
    msid_can_session_cfg ssc{};
    ssc.tr = &sc.tr;
    ssc.base = l.base;
    ssc.on_frame = log_hook;
    ssc.user = &acq;
    if (msid_can_session_init(s.get(), &ssc) < 0) throw Error("CAN session setup");
    int rc = msid_can_session_identify(s.get(), 2000);
    if (rc == -MSID_DAQ_E_TIMEOUT)
        throw Error(fmt("no msid-can device answered at base %s on %s within 2 s", hex(l.base).c_str(), iface.c_str()));
    if (rc == -MSID_DAQ_E_PROTOCOL)
        throw Error(fmt("protocol version mismatch: the device on %s speaks msid-can/%u, this host msid-can/%u",
                        iface.c_str(), s->dev.version, MSID_CAN_PROTO_VERSION));
    if (rc < 0) session_failed(acq, *s, rc);
    const msid_can_device &dev = s->dev;
    MeasurePlan P;
    plan(dev.nu, P);
    P.sf.fd = l.fd ? 1 : 0;
    P.sf.encoding = l.encoding;
    s->cfg.silence_ms = (uint32_t)std::ceil(P.timeout * 1000.0);
    s->cfg.query_ms = s->cfg.silence_ms / 4 ? s->cfg.silence_ms / 4 : 1;
    const msid_design &d = P.D->d;
    if (dev.nu != d.n_inputs)
        throw Error(fmt("the device has %u input(s) but the design has %u", dev.nu, d.n_inputs), 1,
                    msidutil::ErrorKind::data);
    check_input_resolution(P, P.sf.encoding == MSID_CAN_ENC_S16);
    const uint32_t nu = dev.nu, ny = dev.ny, m = d.n_experiments, C = nu + ny;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS) throw Error(fmt("the device reports %u outputs", ny));
    const uint32_t chunks = msid_can_chunks(C, P.sf.encoding, P.sf.fd);
    if (l.bitrate > 0 && P.sf.rate > 0) {
        const double tf = can_frame_seconds(P.sf.fd, l.bitrate, l.data_bitrate > 0 ? l.data_bitrate : l.bitrate);
        const double rate = P.sf.rate, load = rate * chunks * tf;
        if (load > 1.0)
            throw Error(fmt("the bus cannot carry %u channels at %g Hz: %u %s frame(s) per sample, %.0f frames/s, "
                            "need %.2f times the bus capacity at %g bit/s (worst-case bit stuffing); lower " MSID_OPT("rate") "%s",
                            C, rate, chunks, P.sf.fd ? "CAN FD" : "classic", rate * chunks, load, l.bitrate,
                            P.sf.fd ? "" : ", or use " MSID_OPT("fd")));
    }

    // the estimation job and its decoder, then the design upload as parameters
    auto cfg = config_from_design(*P.D, P.sf);
    const size_t nf = msid_params_frames(cfg.get(), nullptr, 0);
    std::vector<uint8_t> cf(nf * 8);
    msid_params_frames(cfg.get(), reinterpret_cast<uint8_t(*)[8]>(cf.data()), nf);
    acq.init(P.rq, nu, ny, m, P.sf.periods, l.base, *cfg, l.window, 4 * P.sf.periods + 8);
    if ((rc = msid_can_session_attach(s.get(), &acq.dec)) < 0) session_failed(acq, *s, rc);
    rc = msid_can_session_upload(s.get(), reinterpret_cast<const uint8_t(*)[8]>(cf.data()), nf);
    if (rc < 0) session_failed(acq, *s, rc);
    const uint32_t crc = s->crc;

    // run the experiments through the shared loop (progress, Ctrl-C)
    CanRunner runner(*s, acq);
    const LoopResult lr = run_experiments(runner, acq.job->meas(), P, ctl);
    msid_can_link_stats ls;
    msid_can_get_stats(&sc.tr, &ls);
    auto notes = can_loss_notes(acq.dec, ls);
    if (s->cnt.done_recovered)
        notes.push_back(fmt("%llu DONE frame(s) lost: the experiment(s) were closed by the device's answer to a QUERY",
                            (unsigned long long)s->cnt.done_recovered));
    if (s->cnt.early_dropped)
        notes.push_back(fmt("%llu frame(s) before the upload were not decoded (more than %u)",
                            (unsigned long long)s->cnt.early_dropped, MSID_CAN_SESSION_EARLY));
    MeasureResult R = finish_measure(*acq.job, P, lr, "can:" + iface, notes);
    Json aj = can_acquisition_json(acq, ls, "socketcan", l.base, *cfg, crc);
    aj["queries"] = s->cnt.queries;
    aj["done_recovered"] = s->cnt.done_recovered;
    R.o.tail()["acquisition"] = aj;
    acq.close_log();
    set_summary(R, P, ny, nu, lr.done, fmt("%s (%s)", iface.c_str(), can_format_name(*cfg).c_str()), acq.dec.cnt.samples,
                acq.dec.cnt.samples_lost);
    R.D = std::move(P.D);
    return R;
}

}  // namespace msidacq
