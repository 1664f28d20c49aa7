// Estimation on the device (extension estimate/1 of msid-modbus/1 and msid-can/1): the device runs
// msid_meas + msid_frf on its own samples and publishes each line's G, covariances and dof bit for bit
// (the result block of daq/include/msid_daq/msid_mb_est.h, as doubles); the host uploads the design and
// the estimator settings, runs the experiments, asks for the block and builds msid-frf/1. With a stream
// check the device also streams its samples and the host estimates from them on the same (streaming)
// DFT path: both must agree bit for bit. `msid modbus|can measure --on-device` and msid.measure(...,
// on_device=True) call it. docs/modbus-registers.md, docs/can-protocol.md "On-device estimation".
#pragma once
#include "msid_acquire.hpp"

namespace msidacq {

// What an on-device measurement gives.
struct OnDeviceResult {
    Json doc;                  // the device's msid-frf/1 with its `acquisition` block
    std::string summary;       // "N lines, ny x nu, m experiment(s) estimated on the device on ..."
    // The stream check (asked for with a non-empty `check_name`): the host's measurement from the
    // streamed samples (Modbus: the whole host session, with its summary and completeness; CAN: the
    // samples decoded beside the session) and why the device's FRF differs from it ("" : bit for bit
    // equal). A stopped host session (host.complete false) ends the run there: `doc` is null.
    bool checked = false;
    MeasureResult host;
    std::string mismatch;
};

// The request's checks for estimation on the device: no detection lines (the device solves the
// excited lines only), skip below 65536; sets the streaming DFT path (the device's). Throws UsageError.
void check_ondevice_request(FrfRequest &rq);

// Over Modbus: `link` (its encoding and word order are the samples' when streaming), the plan of
// `msid modbus measure` (design, stream format, request); `check_name` names the host's estimate in the
// document ("bit-identical to NAME") and asks for the stream check ("" : estimate only). `ctl` sees the
// host session of the stream check. Throws Error for the device, the link or a failed estimate.
OnDeviceResult measure_modbus_ondevice(const ModbusLink &link, const MeasurePlan &P, const std::string &check_name,
                                       Control &ctl);
// Without a stream check `ctl` sees each experiment's start and is asked to stop while the device runs:
// a stop leaves no FRF (the device estimates whole runs) and throws Error with code 128 + the reason.
// Over SocketCAN, as above (the stream check streams every sample: a virtual bus, no bitrate); the
// session runs to its end.
OnDeviceResult measure_can_ondevice(const CanLink &link, const MeasurePlan &P, const std::string &check_name);
// The link of the URI's protocol.
OnDeviceResult measure_device_ondevice(const DeviceUri &dev, const MeasurePlan &P, const std::string &check_name,
                                       Control &ctl);

}  // namespace msidacq
