// The link of a described device as the host-timed measurement sees it (mapped_session.cpp): the device's
// tick-loop backend (msid_devio) and what differs between transports: how one exchange is settled before the
// probe, the timeouts of a tick and of the patient way out, and the transport's own counters for the
// `acquisition` block. One implementation per transport: Modbus (mapped_session.cpp), CAN with a DBC
// (can_mapped.cpp), a CANopen drive (canopen_mapped.cpp).
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "msid_mapped.hpp"

extern "C" {
#include "msid_daq/msid_devdesc.h"
#include "msid_daq/msid_devio.h"
}

namespace msidacq {

class MappedLink {
public:
    virtual ~MappedLink() = default;
    virtual msid_devio &io() = 0;
    // "tcp:HOST:PORT", "can:IFACE": for messages and the summary
    virtual std::string name() const = 0;
    // the FRF file's source
    virtual std::string source() const = 0;
    // after the safe values were written: settle how one exchange runs (notes say what was decided)
    virtual void prepare(const std::vector<double> &safe, std::vector<std::string> &notes) { (void)safe, (void)notes; }
    // the rate refused when the device cannot carry it by what it states (CAN: its status messages' cycle times)
    virtual void check_rate(double rate_hz) const { (void)rate_hz; }
    // the probe of what one tick costs runs the writes alone (a device that answers no request)
    virtual bool probe_writes_only() const { return false; }
    // timeouts for one tick of period T (s); generous ones for the round-trip probe and for the way out
    virtual void tick_timeouts(double T) = 0;
    virtual void probe_timeouts() = 0;
    virtual void exit_timeouts() = 0;
    // the detail of the last failure ("" if none)
    virtual std::string error() const = 0;
    // counts after which measure channel i (a counter) wraps
    virtual double counter_modulus(uint32_t i) const = 0;
    // the measure slot of a counter the link keeps itself, one past the description's channels (a CANopen run on
    // the kernel's SYNC: the SYNC's count), or -1: the exchanges then fill that many values plus one
    virtual int own_counter() const { return -1; }
    // the transport's part of the acquisition block (transport, device, endpoint, counters)
    virtual void acquisition(Json &acq, const DeviceUri &dev) const = 0;
    // why the run must end now ("" while it may go on): a CANopen node's EMCY, its heartbeat lost, the node
    // out of operational. The tick loop stops within ~20 ms of it and the run fails with it.
    virtual std::string fatal() const { return ""; }
    // the description as the link resolved it against the device (scales the node gave); NULL: as read
    virtual const msid_devdesc *resolved() const { return nullptr; }
    // the link's own way out after the safe values were written (CANopen: quick stop, disable, restore);
    // what it did or failed to do goes to notes. Also run, with the notes on stderr, when the link is
    // destroyed without it (an error).
    virtual void close(std::vector<std::string> &notes) { (void)notes; }
};

// The link of a CAN description (can://IFACE), its DBC read and resolved: UsageError naming what does not match.
std::unique_ptr<MappedLink> open_can_mapped(const DeviceUri &dev, const msid_devdesc &desc);

// The link of a CANopen drive (canopen://IFACE?node=N): configured by SDO for rate_hz and in "operation
// enabled" when it returns; UsageError for what the description or the node refuses, Error for the node's
// silence or failure (what was done is undone on the way out).
std::unique_ptr<MappedLink> open_canopen_mapped(const DeviceUri &dev, const msid_devdesc &desc, double rate_hz);

// `msid device check` on a CAN description.
CheckResult check_can_device(const DeviceUri &dev, const msid_devdesc &desc);

}  // namespace msidacq
