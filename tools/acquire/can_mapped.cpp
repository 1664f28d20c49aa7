// A CAN device described by msid-device/1 and its DBC (can://IFACE --map FILE): the DBC read and the
// description resolved against it (daq's msid_can_map), a raw SocketCAN socket that receives the status
// messages and error frames only, the wait for each tick's status frames, and the bus's counters for the
// `acquisition` block; `msid device check` on such a device. docs/devices.md.
#include "mapped_link.hpp"
#include "msid_candump_dbc.hpp"

extern "C" {
#include "msid_daq/msid_can_map.h"
#include "msid_daq/msid_socketcan.h"
}

#include <algorithm>
#include <cmath>
#include <cstring>

namespace msidacq {

using msidutil::fmt;

namespace {

// The DBC of a description: relative to the description's folder (msid_devdesc_load resolved it).
std::unique_ptr<msidrec::DbcFile> read_dbc(const msid_devdesc &d)
{
    if (!d.dbc[0]) throw UsageError(fmt("%s: a CAN description names its DBC file: dbc = \"FILE\"", d.source));
    try {
        return std::make_unique<msidrec::DbcFile>(d.dbc);
    } catch (const std::exception &e) {
        throw UsageError(fmt("%s: dbc: %s", d.source, e.what()));
    }
}

class CanMapped : public MappedLink {
public:
    CanMapped(const DeviceUri &dev, const msid_devdesc &d) : desc_(d), dev_(dev), dbc_(read_dbc(d))
    {
        if (msid_can_map_init(&m_, &d, &dbc_->db(), &sc_.tr) < 0) throw UsageError(m_.err);
        open_socket();
    }
    ~CanMapped() override { msid_can_close(&sc_.tr); }
    msid_devio &io() override { return m_.io; }
    std::string name() const override { return "can:" + dev_.iface; }
    std::string source() const override { return "can:" + dev_.iface; }
    // a tick waits for its status frames for most of the tick, and sends into a full queue for a fifth of it
    void tick_timeouts(double T) override
    {
        m_.wait_ns = (int64_t)std::llround(std::min(0.6 * T, 1.0) * 1e9);
        m_.send_timeout_ms = std::max(1, (int)std::floor(0.2 * T * 1000.0));
    }
    void probe_timeouts() override
    {
        m_.wait_ns = 1000000000;
        m_.send_timeout_ms = 100;
    }
    void exit_timeouts() override
    {
        m_.send_timeout_ms = 200;
        m_.wait_ns = 0;
    }
    std::string error() const override { return m_.err; }
    bool probe_writes_only() const override { return true; }
    // a status message the DBC says comes less often than the ticks: most ticks would have no fresh frame
    void check_rate(double rate_hz) const override
    {
        for (uint32_t k = 0; k < m_.n_st; ++k) {
            const msid_dbc_message *msg = m_.st[k].m;
            if (msg->cycle_ms && 1000.0 / msg->cycle_ms < 0.99 * rate_hz)
                throw UsageError(fmt("%s cannot carry %g ticks per second: the device sends %s every %u ms "
                                     "(GenMsgCycleTime in %s), a fresh sample at most %.4g times a second",
                                     name().c_str(), rate_hz, msg->name, msg->cycle_ms, desc_.dbc,
                                     1000.0 / msg->cycle_ms));
        }
    }
    double counter_modulus(uint32_t i) const override { return msid_can_map_modulus(&m_, i); }
    void acquisition(Json &acq, const DeviceUri &dev) const override
    {
        msid_can_link_stats ls{};
        msid_can_get_stats(&const_cast<msid_socketcan &>(sc_).tr, &ls);
        acq["transport"] = "can";
        acq["device"] = dev.text;
        acq["endpoint"] = dev.iface;
        acq["dbc"] = desc_.dbc;
        acq["frames_sent"] = m_.cnt.frames_sent;
        acq["send_failures"] = m_.cnt.send_failures;
        acq["status_frames"] = m_.cnt.status_frames;
        acq["stale_ticks"] = m_.cnt.stale;
        acq["superseded_frames"] = m_.cnt.superseded;
        acq["short_frames"] = m_.cnt.short_frames;
        acq["bus_errors"] = m_.cnt.bus_errors;
        acq["other_frames"] = m_.cnt.other_frames;
        acq["kernel_drops"] = ls.kernel_drops;
        acq["send_retries_enobufs"] = ls.send_retries;
    }
    msid_can_map &map() { return m_; }

private:
    // the status messages only (a filter per message while the socket has enough), and the error frames
    void open_socket()
    {
        msid_socketcan_cfg c{};
        c.iface = dev_.iface.c_str();
        bool fd = dev_.fd;
        for (uint32_t k = 0; k < m_.n_cmd; ++k) fd = fd || m_.cmd[k].m->dlc > 8;
        for (uint32_t k = 0; k < m_.n_st; ++k) fd = fd || m_.st[k].m->dlc > 8;
        c.fd_frames = fd ? 1 : 0;
        if (m_.n_st <= MSID_SOCKETCAN_MAX_FILTERS) {
            for (uint32_t k = 0; k < m_.n_st; ++k) {
                const uint32_t id = m_.st[k].m->id;
                c.filter_id[k] = id;
                c.filter_mask[k] = (id & MSID_CAN_EFF_FLAG ? 0x1FFFFFFFu : 0x7FFu) | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
            }
            c.n_filters = (int)m_.n_st;
        }
        c.err_frames = 1;
        if (msid_socketcan_open(&sc_, &c) < 0) throw Error(sc_.err);
    }

    const msid_devdesc &desc_;
    DeviceUri dev_;
    std::unique_ptr<msidrec::DbcFile> dbc_;
    msid_socketcan sc_{};
    msid_can_map m_{};
};

}  // namespace

std::unique_ptr<MappedLink> open_can_mapped(const DeviceUri &dev, const msid_devdesc &desc)
{
    return std::make_unique<CanMapped>(dev, desc);
}

CheckResult check_can_device(const DeviceUri &dev, const msid_devdesc &desc)
{
    CanMapped link(dev, desc);
    msid_can_map &m = link.map();
    CheckResult r;
    r.lines.push_back(fmt("%s: %s, DBC %s: %u drive and %u measure channel(s) in %u command and %u status message(s)",
                          desc.source, link.name().c_str(), desc.dbc, desc.n_drive, desc.n_measure, m.n_cmd, m.n_st));
    std::vector<double> safe(desc.n_drive), v(desc.n_measure, NAN);
    for (uint32_t i = 0; i < desc.n_drive; ++i) safe[i] = desc.drive[i].safe;
    link.probe_timeouts();
    msid_devio_times t{};
    if (msid_devio_write(&link.io(), safe.data(), &t) < 0) {
        r.lines.push_back(fmt("writing the safe values: %s", m.err));
        ++r.problems;
    } else {
        std::string s;
        for (uint32_t i = 0; i < desc.n_drive; ++i)
            s += fmt("%s%s = %g%s%s", i ? ", " : "", desc.drive[i].name, desc.drive[i].safe,
                     desc.drive[i].unit[0] ? " " : "", desc.drive[i].unit);
        r.lines.push_back(fmt("sent the safe values once (%s)", s.c_str()));
    }
    // every status message within a second (its frames are cyclic, or answer the command just sent)
    const int rc = msid_devio_read(&link.io(), v.data(), &t);
    if (rc < 0) r.lines.push_back(fmt("reading: %s", m.err));
    for (uint32_t i = 0; i < desc.n_measure; ++i) {
        const msid_dev_chan &c = desc.measure[i];
        static const char *const roles[] = {"", "input", "output", "reference", "counter"};
        const double x = m.value[i];
        const bool got = m.st[m.st_of[i]].frames > 0;
        const bool ok = got && std::isfinite(x);
        if (!ok) ++r.problems;
        const msid_dbc_message *msg = m.st[m.st_of[i]].m;
        r.lines.push_back(fmt("  %-24s %-9s %s.%s (0x%X) = %.9g%s%s%s", c.name, roles[c.role], c.message, c.signal,
                              msg->id & 0x1FFFFFFFu, x, c.unit[0] ? " " : "", c.unit,
                              !got ? "  <- no frame within 1 s" : !std::isfinite(x) ? "  <- not a finite number" : ""));
    }
    return r;
}

}  // namespace msidacq
