// The CAN decoder feeding an FRF job (msid_can_acq.hpp).
#include "msid_can_acq.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <unistd.h>

extern "C" {
#include "msid_daq/msid_candump.h"
}

namespace msidacq {

using msidutil::check;
using msidutil::fmt;
using msidutil::Mem;
using msidjob::FrfJob;

CanAcq::~CanAcq()
{
    if (log) { std::fclose(log); ::unlink(log_tmp.c_str()); }
}

void CanAcq::open_log(const std::string &path)
{
    log_path = path;
    log_tmp = path + ".tmp." + std::to_string(getpid());
    log_partial = std::make_unique<msidutil::PartialFile>(log_tmp);
    log = std::fopen(log_tmp.c_str(), "w");
    if (!log) throw Error("cannot write '" + path + "': " + std::strerror(errno));
}

void CanAcq::log_frame(const msid_can_frame &f)
{
    if (!log) return;
    char buf[256];
    msid_can_frame g = f;
    if (!g.t_ns) {
        timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        g.t_ns = (uint64_t)ts.tv_sec * 1000000000ull + (uint64_t)ts.tv_nsec;
    }
    const int n = msid_candump_format(buf, sizeof buf, &g, iface.c_str());
    if (n < 0 || std::fwrite(buf, 1, (size_t)n, log) != (size_t)n) throw Error("cannot write '" + log_path + "'");
}

void CanAcq::close_log()
{
    if (!log) return;
    const bool ok = std::fflush(log) == 0 && fsync(fileno(log)) == 0;
    std::fclose(log);
    log = nullptr;
    if (!ok || std::rename(log_tmp.c_str(), log_path.c_str()) != 0) {
        ::unlink(log_tmp.c_str());
        throw Error("cannot write '" + log_path + "'");
    }
}

void CanAcq::init(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m, uint32_t periods, uint32_t base,
                  const msid_params &c, uint32_t window, uint32_t history)
{
    job = std::make_unique<FrfJob>(rq, nu, ny, m, periods, history);
    msid_can_decoder_cfg dc{};
    dc.base = base;
    dc.n_inputs = nu;
    dc.n_outputs = ny;
    dc.encoding = c.encoding;
    dc.fd = c.fd;
    dc.scale = (double)c.scale;
    dc.period = c.period;
    dc.window = window;
    dc.meas = job->meas();
    dc.samples_total = (uint64_t)periods * c.period;   // a DONE count beyond K P is not trusted
    const size_t n = msid_can_decoder_mem_size(&dc);
    if (!n) throw Error(fmt("%u inputs + %u outputs do not fit the %s %s sample frames", nu, ny,
                            c.fd ? "CAN FD" : "classic", c.encoding ? "float32" : "int16"));
    mdec = Mem(n);
    check(msid_can_decoder_init(&dec, &dc, mdec.p, mdec.n), "decoder setup");
}

void CanAcq::feed(const msid_can_frame &f)
{
    const msid_status st = msid_can_decoder_feed(&dec, &f);
    if (st == MSID_E_CAPACITY)
        throw Error("more periods arrived than the measurement holds (device restarted too often?)");
    check(st, "decoder");
}

std::string can_format_name(const msid_params &c)
{
    return std::string(c.fd ? "fd" : "classic") + "/" + (c.encoding ? "float32" : "int16");
}

Json can_acquisition_json(const CanAcq &a, const msid_can_link_stats &ls, const std::string &transport, uint32_t base,
                          const msid_params &cfg, uint32_t crc)
{
    const msid_can_decoder &d = a.dec;
    const msid_can_counters &c = d.cnt;
    Json j;
    j["transport"] = transport;
    j["interface"] = a.iface;
    j["protocol"] = fmt("msid-can/%u", MSID_CAN_PROTO_VERSION);
    j["base_id"] = base;
    j["frame_format"] = can_format_name(cfg);
    j["scale"] = (double)cfg.scale;
    j["rate_hz"] = cfg.rate_hz;
    j["config_crc"] = crc;
    j["frames"] = c.frames;
    j["sample_frames"] = c.sample_frames;
    j["samples"] = c.samples;
    j["samples_lost"] = c.samples_lost;
    j["frames_missing"] = c.frames_missing;
    j["gap_events"] = c.gap_events;
    j["duplicates"] = c.duplicates;
    j["reordered"] = c.reordered;
    j["late"] = c.late;
    j["malformed"] = c.malformed;
    j["foreign"] = c.foreign;
    j["status_frames"] = c.status_frames;
    j["error_frames"] = c.error_frames;
    j["errors_by_class"] = {{"warning", c.err_warning}, {"passive", c.err_passive}, {"bus_off", c.err_bus_off},
                            {"restarted", c.err_restarted}, {"protocol", c.err_protocol}, {"ack", c.err_ack},
                            {"controller_overflow", c.err_ctrl_overflow}, {"other", c.err_other}};
    j["bus_state"] = msid_can_bus_state_name(d.bus);
    j["device_restarts"] = c.restarts;
    j["periods_marked"] = c.periods_marked;
    j["kernel_drops"] = ls.kernel_drops;
    j["bad_length_reads"] = ls.bad_length;
    j["send_retries"] = ls.send_retries;
    j["timestamped_frames"] = ls.timestamps;
    j["stream_seconds"] = 1e-9 * (double)c.stream_ns;
    if (d.dev.have_counters) j["device_tx_dropped"] = d.dev.tx_dropped;
    return j;
}

std::vector<msidjob::ExpSource> can_sources(const CanAcq &a, uint32_t m)
{
    std::vector<msidjob::ExpSource> src;
    const msid_meas *ms = a.dec.cfg.meas;
    for (uint32_t e = 0; e < m; ++e) {
        const msid_pstats_counts c = msid_pstats_get_counts(msid_meas_stats(ms, e));
        src.push_back({fmt("can:%s experiment %u", a.iface.c_str(), e + 1), ms->samples[e], c.offered,
                       msid_meas_leftover(ms, e)});
    }
    return src;
}

std::vector<std::string> can_loss_notes(const msid_can_decoder &d, const msid_can_link_stats &ls)
{
    std::vector<std::string> n;
    const msid_can_counters &c = d.cnt;
    if (c.samples_lost)
        n.push_back(fmt("%llu sample(s) missing in %llu gap(s) (%llu frames): the periods they touch were rejected",
                        (unsigned long long)c.samples_lost, (unsigned long long)c.gap_events,
                        (unsigned long long)c.frames_missing));
    if (ls.kernel_drops)
        n.push_back(fmt("the kernel dropped %llu frame(s) for a full socket queue (raise --rcvbuf)",
                        (unsigned long long)ls.kernel_drops));
    if (c.done_beyond)
        n.push_back(fmt("%llu DONE frame(s) announced more samples than the design's periods x period: the "
                        "experiment was closed at the design's count", (unsigned long long)c.done_beyond));
    if (c.malformed) n.push_back(fmt("%llu malformed frame(s) ignored", (unsigned long long)c.malformed));
    if (c.duplicates) n.push_back(fmt("%llu duplicate frame(s) ignored", (unsigned long long)c.duplicates));
    if (c.restarts) n.push_back(fmt("the device restarted %llu time(s)", (unsigned long long)c.restarts));
    if (c.error_frames)
        n.push_back(fmt("%llu error frame(s); bus state now %s", (unsigned long long)c.error_frames,
                        msid_can_bus_state_name(d.bus)));
    return n;
}

}  // namespace msidacq
