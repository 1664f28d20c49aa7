// A CiA 402 drive described by msid-device/1 (transport "canopen", canopen://IFACE?node=N --map FILE): msid
// as the node's CANopen master. Before any frame goes out: the bus budget of the SYNC cycle at the rate (the
// URI's bitrate=, else the interface's as the kernel reports it, else 1 Mbit/s assumed: canopen_bitrate) and,
// with the description's eds, every entry the run uses checked
// against the node's EDS/DCF. Then, by SDO: every mapped object read once (the node has it, of
// the size its type says), the safe target written (a read-only target is refused by the node), the rated
// torque 0x6076 read when the description does not give it, NMT pre-operational, RPDO1 and TPDO1(/2) mapped
// with transmission type 1 (what was there read first), the cycle period 0x1006, the mode 0x6060, NMT start
// and the CiA 402 walk to "operation enabled". Each tick is daq/'s msid_co_map (RPDO + SYNC, the TPDOs of
// that SYNC; with sync = "kernel" the RPDO alone, the SYNC from the kernel's timer started here). On every way
// out: the safe target by SDO, quick stop then disable voltage, no SYNC after it (the tick's SYNC ends with the
// ticks, the kernel's is stopped), NMT pre-operational, and the mapping restored when the description sets
// restore_pdo. docs/devices.md, CANopen drives.
#include "mapped_link.hpp"
#include "msid_canopen.hpp"

extern "C" {
#include "msid_daq/msid_co_402.h"
#include "msid_daq/msid_co_can.h"
#include "msid_daq/msid_co_map.h"
#include "msid_daq/msid_co_nmt.h"
#include "msid_daq/msid_co_sync.h"
#include "msid_daq/msid_socketcan.h"
}

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace msidacq {

using msidutil::fmt;

namespace {

std::string co_object(const msid_dev_chan &c) { return fmt("0x%04X:%02X", (unsigned)c.co_index, (unsigned)c.co_sub); }

class CanopenMapped : public MappedLink {
public:
    CanopenMapped(const DeviceUri &dev, const msid_devdesc &d) : dev_(dev), d_(d)
    {
        if (dev.kind != DeviceUri::CANOPEN)
            throw UsageError(fmt("%s describes a CANopen drive, but the device URI is %s: use canopen://IFACE?node=N",
                                 d.source, dev.text.c_str()));
        bitrate_ = canopen_bitrate(dev.text, dev.iface, dev.co_bitrate);   // refuses an interface that is not CAN
        open_socket();
        msid_co_io io;
        msid_co_can_io(&hook_.can, &sock_.tr, 100, &io);
        io.other = &CanopenMapped::on_other;
        io.ctx = &hook_;   // hook_.can first: the adapter's own calls see their msid_co_can
        hook_.self = this;
        io_ = io;
        if (msid_co_sdo_init(&sdo_, &io_, dev.node, dev.co_timeout_ms) < 0) throw UsageError(sdo_.err);
    }
    ~CanopenMapped() override
    {
        if (!closed_) {
            // the way out of an error: what failed of it is said (the error itself is the caller's message)
            std::vector<std::string> notes, problems;
            finish(notes, problems);
            for (const auto &n : problems) std::fprintf(stderr, "msid: %s\n", n.c_str());
        }
        msid_co_sync_stop(&sync_);
        msid_can_close(&sock_.tr);
    }

    // Everything before the first tick (see the file's head). Any failure throws; the destructor then takes
    // the way out, which undoes what was done.
    void configure(double rate_hz)
    {
        precheck(rate_hz);
        // the node answers at all (its statusword), before anything is written
        uint32_t sw = 0;
        if (msid_co_sdo_read_uint(&sdo_, MSID_CO402_STATUSWORD, 0, 2, &sw))
            throw Error(fmt("%s: node %u does not answer as a CiA 402 drive: %s", dev_.text.c_str(), dev_.node,
                            sdo_.err));
        resolve_torque();
        check_objects();
        if (msid_co_map_init(&m_, &d_, dev_.node, d_.heartbeat_ms, &sock_.tr) < 0) throw UsageError(m_.err);
        write_safe_by_sdo(true);
        touched_ = true;   // from here on the way out takes the node back
        nmt(MSID_CO_NMT_PREOPERATIONAL);
        msid_co_pdo_cfg rp, tp[MSID_DEV_CO_TPDOS];
        msid_co_map_pdos(&m_, &rp, tp);
        char err[240];
        if (msid_co_pdo_check(&rp, dev_.node, err, sizeof err)) throw UsageError(err);
        for (uint32_t k = 0; k < m_.n_tpdo; ++k)
            if (msid_co_pdo_check(&tp[k], dev_.node, err, sizeof err)) throw UsageError(err);
        // what the node holds, read before anything of it is written (restore_pdo puts it back)
        sdo_or_throw(msid_co_pdo_save(&sdo_, 0, 1, &saved_[0]), "reading RPDO1");
        for (uint32_t k = 0; k < m_.n_tpdo; ++k)
            sdo_or_throw(msid_co_pdo_save(&sdo_, 1, k + 1, &saved_[1 + k]), fmt("reading TPDO%u", k + 1));
        n_saved_ = 1 + m_.n_tpdo;
        sdo_or_throw(msid_co_pdo_configure(&sdo_, &rp, &saved_[0]), "mapping RPDO1");
        mapped_ = true;
        for (uint32_t k = 0; k < m_.n_tpdo; ++k)
            sdo_or_throw(msid_co_pdo_configure(&sdo_, &tp[k], &saved_[1 + k]), fmt("mapping TPDO%u", k + 1));
        period_us_ = (uint32_t)std::lround(1e6 / rate_hz);
        if (d_.co_sync == MSID_DEV_SYNC_KERNEL) msid_co_map_kernel_sync(&m_, period_us_);
        sdo_or_throw(msid_co_cycle_write(&sdo_, period_us_), "writing the cycle period 0x1006");
        if (d_.heartbeat_ms) {
            // the node's producer time well inside the consumer time msid watches it with
            const uint32_t prod = std::max(1u, d_.heartbeat_ms / 2);
            sdo_or_throw(msid_co_sdo_write_uint(&sdo_, 0x1017, 0, 2, prod), "writing the heartbeat time 0x1017");
        }
        sdo_or_throw(msid_co402_set_mode(&sdo_, (msid_co402_mode)d_.co_mode, 1000), "setting the mode of operation");
        if (d_.co_closed_loop == 2) {
            // the torque-loop preset: the velocity the drive's loop holds while the torque offset is excited
            // (msid_devdesc_check: its counts fit INTEGER32; 0 again on every way out, write_safe_by_sdo)
            const int32_t hold = (int32_t)std::lround(d_.co_hold_velocity / d_.velocity_scale);
            sdo_or_throw(msid_co_sdo_write_uint(&sdo_, 0x60FF, 0, 4, (uint32_t)hold),
                         fmt("writing the held velocity %g %s to the target velocity 0x60FF", d_.co_hold_velocity,
                             d_.velocity_unit));
        }
        nmt(MSID_CO_NMT_START);
        msid_co402_state st;
        if (msid_co402_goto(&sdo_, 1, 0, 2000, &st))
            throw Error(fmt("%s: on the way to \"operation enabled\": %s", dev_.text.c_str(), sdo_.err));
        // watched from here: a heartbeat the node sent before it took the NMT start came before the walk's
        // SDO answers (a node answers in order), so it was seen while not yet watched
        m_.operational = 1;
        if (m_.kernel_sync) start_kernel_sync();
    }

    // The way out, once: safe target, quick stop and disable voltage, pre-operational, the mapping restored.
    // notes: what was done; problems: what failed of it (both go into the FRF file's notes at a normal end).
    void finish(std::vector<std::string> &notes, std::vector<std::string> &problems)
    {
        if (closed_) return;
        closed_ = true;
        if (!touched_) return;
        m_.operational = 0;
        if (!write_safe_by_sdo(false)) problems.push_back("at the end, the safe target by SDO: " + std::string(sdo_.err));
        msid_co402_state st = MSID_CO402_NOT_READY;
        if (msid_co402_goto(&sdo_, 0, 0, 2000, &st))
            problems.push_back("at the end, quick stop and disable voltage: " + std::string(sdo_.err));
        else
            notes.push_back(fmt("node %u at the end: \"%s\", the safe target written, no SYNC after the last tick",
                                dev_.node, msid_co402_state_name(st)));
        // the kernel's SYNC stops once the node is out of "operation enabled" (a drive that loses its SYNC while
        // enabled may fault); the tick sends no more SYNC
        msid_co_sync_stop(&sync_);
        if (msid_co_nmt_send(&io_, MSID_CO_NMT_PREOPERATIONAL, dev_.node))
            problems.push_back("at the end, NMT pre-operational: " + std::string(hook_.can.err));
        if (d_.restore_pdo && mapped_) {
            bool ok = true;
            for (uint32_t k = n_saved_; k-- > 0;)
                if (msid_co_pdo_restore(&sdo_, &saved_[k])) {
                    problems.push_back("restoring the PDO mapping: " + std::string(sdo_.err));
                    ok = false;
                }
            if (ok) notes.push_back("the PDO mapping read before the run was restored (restore_pdo)");
        }
    }

    msid_devio &io() override { return m_.io; }
    std::string name() const override { return fmt("canopen:%s node %u", dev_.iface.c_str(), dev_.node); }
    std::string source() const override { return fmt("canopen:%s:%u", dev_.iface.c_str(), dev_.node); }
    void prepare(const std::vector<double> &, std::vector<std::string> &notes) override
    {
        if (m_.kernel_sync)
            notes.push_back(fmt("node %u in %s, SYNC every %u us from the kernel's timer (CAN_BCM; 0x1006), %s; each "
                                "sample is placed at the SYNC whose answers it is (by SYNC count), each tick's RPDO is "
                                "taken by the next SYNC", dev_.node, msid_co402_mode_name((int)d_.co_mode), period_us_,
                                m_.describe));
        else
            notes.push_back(fmt("node %u in %s, SYNC every %u us from msid's tick (0x1006), %s; each tick's TPDOs are "
                                "read at the next tick (input and output alike)", dev_.node,
                                msid_co402_mode_name((int)d_.co_mode), period_us_, m_.describe));
    }
    // a tick's TPDOs are read at the next tick, which waits a quarter of a tick more for answers not yet in
    // (a node that answers within 1.25 ticks loses no sample); the probe waits for each answer (its round
    // trip is then the cost of the sends alone: the node's latency is in tpdo_latency_s)
    // On the kernel's SYNC a tick runs mid-cycle and waits up to 0.4 of a tick more: the node has 0.9 of a tick
    // after its SYNC, and the next tick still has its RPDO out half a tick before the next SYNC.
    void tick_timeouts(double T) override
    {
        m_.wait_ns = (int64_t)std::llround(std::min((m_.kernel_sync ? 0.4 : 0.25) * T, 1.0) * 1e9);
        m_.send_timeout_ms = std::max(1, (int)std::floor(0.2 * T * 1000.0));
    }
    void probe_timeouts() override
    {
        m_.wait_ns = 1000000000;
        m_.send_timeout_ms = 100;
    }
    void exit_timeouts() override
    {
        m_.wait_ns = 0;
        m_.send_timeout_ms = 200;
    }
    std::string error() const override { return m_.err; }
    std::string fatal() const override { return m_.fatal; }
    const msid_devdesc *resolved() const override { return &d_; }
    void close(std::vector<std::string> &notes) override
    {
        std::vector<std::string> problems;
        finish(notes, problems);
        notes.insert(notes.end(), problems.begin(), problems.end());
    }
    double counter_modulus(uint32_t i) const override
    {
        if (i >= d_.n_measure) return 4294967296.0;   // the SYNC count (uint32)
        return msid_dev_co_bytes(&d_.measure[i]) == 2 ? 65536.0 : 4294967296.0;
    }
    int own_counter() const override { return m_.kernel_sync ? m_.sync_ch : -1; }
    void acquisition(Json &acq, const DeviceUri &dev) const override
    {
        msid_can_link_stats ls{};
        msid_can_get_stats(&const_cast<msid_socketcan &>(sock_).tr, &ls);
        acq["transport"] = "canopen";
        acq["device"] = dev.text;
        acq["endpoint"] = dev.iface;
        acq["node"] = dev.node;
        acq["mode"] = msid_co402_mode_name((int)d_.co_mode);
        acq["cycle_period_us"] = period_us_;
        acq["rated_torque_nm"] = d_.rated_torque;
        acq["pdos"] = m_.describe;
        acq["syncs"] = m_.cnt.syncs;
        acq["sync_source"] = m_.kernel_sync ? "kernel" : "tick";
        acq["rpdos"] = m_.cnt.rpdos;
        acq["tpdos"] = m_.cnt.tpdos;
        acq["lost_ticks"] = m_.cnt.lost;
        acq["late_tpdos"] = m_.cnt.late;
        acq["bad_tpdos"] = m_.cnt.bad_tpdos;
        acq["emcy"] = m_.cnt.emcy;
        acq["heartbeats"] = m_.cnt.heartbeats;
        acq["send_failures"] = m_.cnt.send_failures;
        if (m_.cnt.latency_n)
            acq["tpdo_latency_s"] = {{"mean", m_.cnt.latency_sum_s / (double)m_.cnt.latency_n},
                                     {"max", m_.cnt.latency_max_s}, {"count", m_.cnt.latency_n}};
        acq["kernel_drops"] = ls.kernel_drops;
        acq["restore_pdo"] = d_.restore_pdo != 0;
        acq["bus_bitrate"] = bitrate_.bitrate;
        acq["bus_bitrate_assumed"] = bitrate_.assumed();
        acq["bus_bitrate_source"] = bitrate_.source;
        if (bitrate_.data_bitrate) acq["bus_data_bitrate"] = bitrate_.data_bitrate;
        acq["bus_max_rate_hz"] = max_rate_;
        if (d_.co_eds[0]) acq["eds"] = d_.co_eds;
    }

private:
    // the node's SDO responses, its TPDO1/2, EMCY and heartbeat, and msid's own SYNC back (the tick's marker)
    void open_socket()
    {
        msid_socketcan_cfg c{};
        c.iface = dev_.iface.c_str();
        const unsigned n = dev_.node;
        const uint32_t ids[] = {MSID_CO_COB_SDO_TX + n, MSID_CO_COB_TPDO1 + n, MSID_CO_COB_TPDO1 + 0x100u + n,
                                MSID_CO_COB_EMCY + n, MSID_CO_COB_HEARTBEAT + n, MSID_CO_COB_SYNC};
        for (unsigned i = 0; i < sizeof ids / sizeof ids[0]; ++i) {
            c.filter_id[i] = ids[i];
            c.filter_mask[i] = 0x7FFu | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
        }
        c.n_filters = (int)(sizeof ids / sizeof ids[0]);
        c.recv_own = 1;
        if (msid_socketcan_open(&sock_, &c) < 0) throw Error(fmt("%s: %s", dev_.text.c_str(), sock_.err));
    }

    // frames the SDO client did not await: EMCY and heartbeat watched, TPDOs counted late
    static void on_other(void *ctx, const msid_can_frame *f)
    {
        CanopenMapped *self = static_cast<Hook *>(ctx)->self;
        if (self->m_.d) msid_co_map_offer(&self->m_, f, msid_co_now_ms(&self->io_));
    }

    void sdo_or_throw(int rc, const std::string &what)
    {
        if (rc == -MSID_DAQ_E_ARG) throw UsageError(fmt("%s: %s: %s", dev_.text.c_str(), what.c_str(), sdo_.err));
        if (rc) throw Error(fmt("%s: %s: %s", dev_.text.c_str(), what.c_str(), sdo_.err));
    }

    // the kernel's SYNC from now on (the node is operational, in "operation enabled", holding the safe target)
    void start_kernel_sync()
    {
        const int rc = msid_co_sync_start(&sync_, dev_.iface.c_str(), period_us_, 0);
        if (rc == -MSID_DAQ_E_NOSUPPORT)
            throw Error(fmt("%s: sync = \"kernel\": %s (or use sync = \"tick\")", dev_.text.c_str(), sync_.err));
        if (rc) throw Error(fmt("%s: sync = \"kernel\": %s", dev_.text.c_str(), sync_.err));
    }

    void nmt(msid_co_nmt_cmd cmd)
    {
        if (msid_co_nmt_send(&io_, cmd, dev_.node))
            throw Error(fmt("%s: NMT %s: %s", dev_.text.c_str(), msid_co_nmt_cmd_name(cmd), hook_.can.err));
    }

    // Before any frame goes to the node: the bus budget of the SYNC cycle at rate_hz, and with `eds` every
    // entry the run uses against the node's EDS/DCF (on a map of its own: the run's map is set up after the
    // node's answers, so that no frame before them is counted in it).
    void precheck(double rate_hz)
    {
        msid_co_map pre;
        if (msid_co_map_init(&pre, &d_, dev_.node, d_.heartbeat_ms, &sock_.tr) < 0) throw UsageError(pre.err);
        char err[2 * MSID_DEV_PATH_CAP];
        if (msid_co_map_check_bus(&pre, bitrate_.bitrate, rate_hz, &max_rate_, err, sizeof err))
            throw UsageError(fmt("%s: --rate %g: %s%s", dev_.text.c_str(), rate_hz, err, bus_said().c_str()));
        if (!d_.co_eds[0]) return;
        std::unique_ptr<EdsFile> f;
        try {
            f = std::make_unique<EdsFile>(d_.co_eds);
        } catch (const msidutil::IoError &e) {   // the description names a file that is not there
            throw UsageError(fmt("%s (key eds): %s", d_.source, e.what()));
        }
        if (msid_co_map_check_eds(&pre, &f->eds, err, sizeof err)) throw UsageError(err);
    }

    // where the budget's bit rate came from, for the message that refuses a rate (the URI's: nothing to add)
    std::string bus_said() const
    {
        if (bitrate_.source == "interface")
            return fmt(" (the %u kbit/s %s is set to)", bitrate_.bitrate / 1000, dev_.iface.c_str());
        if (bitrate_.assumed())
            return fmt(" (a bus of %u kbit/s assumed: %s, and the URI gives no bitrate=BPS)", bitrate_.bitrate / 1000,
                       bitrate_.why.c_str());
        return "";
    }

    // the torque channels' scale from the node's rated torque 0x6076 (mN m) when the description gives none
    void resolve_torque()
    {
        bool torque = false;
        for (uint32_t i = 0; i < d_.n_drive + d_.n_measure; ++i)
            torque = torque || chan(i).co_quantity == MSID_DEV_CO_TORQUE;
        if (!torque || !std::isnan(d_.rated_torque)) return;
        uint32_t mnm = 0;
        if (msid_co_sdo_read_uint(&sdo_, 0x6076, 0, 4, &mnm))
            throw Error(fmt("%s: reading the rated torque 0x6076 (or give rated_torque in %s): %s", dev_.text.c_str(),
                            d_.source, sdo_.err));
        if (!mnm) throw Error(fmt("%s: the node's rated torque 0x6076 is 0: give rated_torque (N m) in %s",
                                  dev_.text.c_str(), d_.source));
        d_.rated_torque = mnm * 1e-3;
        for (uint32_t i = 0; i < d_.n_drive + d_.n_measure; ++i)
            if (chan(i).co_quantity == MSID_DEV_CO_TORQUE) chan(i).scale = d_.rated_torque * 1e-3;
        char err[512];
        if (msid_devdesc_check(&d_, err, sizeof err))
            throw UsageError(fmt("%s with the node's rated torque %g N m (0x6076): %s", d_.source, d_.rated_torque, err));
    }

    msid_dev_chan &chan(uint32_t i) { return i < d_.n_drive ? d_.drive[i] : d_.measure[i - d_.n_drive]; }

    // every mapped object read once: the node has it, of its type's size; nothing written
    void check_objects()
    {
        for (uint32_t i = 0; i < d_.n_drive + d_.n_measure; ++i) {
            const msid_dev_chan &c = chan(i);
            uint8_t buf[16];
            size_t len = 0;
            const int rc = msid_co_sdo_upload(&sdo_, c.co_index, c.co_sub, buf, sizeof buf, &len);
            if (rc == -MSID_DAQ_E_DEVICE && sdo_.abort_by_node)
                throw UsageError(fmt("%s line %u: channel '%s' (object = \"%s\"): node %u refuses to read it: %s",
                                     d_.source, c.line, c.name, co_object(c).c_str(), dev_.node,
                                     msid_co_abort_name(sdo_.abort_code)));
            if (rc) throw Error(fmt("%s: reading %s ('%s'): %s", dev_.text.c_str(), co_object(c).c_str(), c.name, sdo_.err));
            if (len != msid_dev_co_bytes(&c))
                throw UsageError(fmt("%s line %u: channel '%s' (object = \"%s\"): the node answers %zu byte(s), type "
                                     "%s has %u (key type)", d_.source, c.line, c.name, co_object(c).c_str(), len,
                                     msid_dev_type_name(c.type), (unsigned)msid_dev_co_bytes(&c)));
        }
    }

    // the safe target of every drive channel by SDO (it acts at once, PDOs or not); `first`: a refusal is the
    // description's fault (a read-only object named as a target)
    bool write_safe_by_sdo(bool first)
    {
        bool ok = true;
        for (uint32_t i = 0; i < d_.n_drive; ++i) {
            const msid_dev_chan &c = d_.drive[i];
            uint8_t b[4];
            if (msid_co_map_encode(&c, c.safe, b) != 0)
                throw UsageError(fmt("%s line %u: drive channel '%s': the safe value %g does not fit %s (key safe)",
                                     d_.source, c.line, c.name, c.safe, msid_dev_type_name(c.type)));
            const int rc = msid_co_sdo_download(&sdo_, c.co_index, c.co_sub, b, msid_dev_co_bytes(&c));
            if (rc && first) {
                if (rc == -MSID_DAQ_E_DEVICE && sdo_.abort_by_node)
                    throw UsageError(fmt("%s line %u: drive channel '%s' (object = \"%s\"): node %u refuses a write "
                                         "of it (%s): a drive channel is a target the node takes",
                                         d_.source, c.line, c.name, co_object(c).c_str(), dev_.node,
                                         msid_co_abort_name(sdo_.abort_code)));
                throw Error(fmt("%s: writing the safe target of '%s': %s", dev_.text.c_str(), c.name, sdo_.err));
            }
            ok = ok && rc == 0;
        }
        if (d_.co_closed_loop == 2) {
            // the torque-loop preset holds a velocity target beside its drive channel: 0 is its safe value
            const int rc = msid_co_sdo_write_uint(&sdo_, 0x60FF, 0, 4, 0);
            if (rc && first) throw Error(fmt("%s: writing 0 to the target velocity 0x60FF: %s", dev_.text.c_str(), sdo_.err));
            ok = ok && rc == 0;
        }
        return ok;
    }

    // the io's context: the CAN adapter (first, as its own calls take it) and the link for the other-frame hook
    struct Hook {
        msid_co_can can;
        CanopenMapped *self;
    };
    DeviceUri dev_;
    msid_devdesc d_;
    msid_socketcan sock_{};
    bool touched_ = false, mapped_ = false, closed_ = false;
    Hook hook_{};
    msid_co_io io_{};
    msid_co_sdo sdo_{};
    msid_co_map m_{};
    msid_co_sync sync_{-1, 0, 0, {0}};   // the kernel's SYNC (sync = "kernel"; fd -1: not running)
    msid_co_pdo_cfg saved_[1 + MSID_DEV_CO_TPDOS]{};
    uint32_t n_saved_ = 0, period_us_ = 0;
    CanopenBitrate bitrate_;
    double max_rate_ = 0;   // the highest SYNC rate the bus carries for the mapping (Hz)
};

}  // namespace

std::unique_ptr<MappedLink> open_canopen_mapped(const DeviceUri &dev, const msid_devdesc &desc, double rate_hz)
{
    auto link = std::make_unique<CanopenMapped>(dev, desc);
    link->configure(rate_hz);   // a throw destroys link: its way out undoes what was done
    return link;
}

}  // namespace msidacq
