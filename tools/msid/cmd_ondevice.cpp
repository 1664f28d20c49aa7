// `msid modbus measure --on-device` and `msid can measure --on-device`: options -> the acquisition
// library's estimation on the device (tools/acquire/msid_ondevice.hpp) -> files.
//  - Modbus: float64 registers (docs/modbus-registers.md "On-device estimation");
//  - CAN: EST frames through the CAN session (docs/can-protocol.md "On-device estimation").
// --stream-check FILE: the device also streams its samples; FILE gets the host's FRF from them and
// both must agree bit for bit.
#include "commands.hpp"
#include "host_libs.hpp"
#include "measure.hpp"
#include "msid_ondevice.hpp"

extern "C" {
#include "msid_daq/msid_can_decoder.h"
}

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>

namespace msidcli {

namespace {

// The options both links share: --stream-check FILE apart from -o; the request's on-device checks.
std::string stream_check_option(const Args &a, const std::string &out, FrfRequest &rq)
{
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    msidacq::check_ondevice_request(rq);
    if (a.has("stream-check") && a.get("stream-check") == out) throw UsageError("--stream-check and -o must name different files");
    return a.has("stream-check") ? a.get("stream-check") : "";
}

// The device's FRF to OUTPUT, after the host's (--stream-check) and the verdict on both.
int write_ondevice(msidacq::OnDeviceResult &R, const std::string &out)
{
    if (!R.mismatch.empty()) throw Error(R.mismatch);
    write_json_file(out, R.doc);
    std::printf("wrote %s: %s\n", out.c_str(), R.summary.c_str());
    return 0;
}

// --base: a multiple of 0x80 up to 0x780, decimal or 0x hex (as `msid can measure`).
uint32_t can_base(const Args &a)
{
    const std::string v = a.get("base", "0x200");
    char *end = nullptr;
    const unsigned long b = std::strtoul(v.c_str(), &end, 0);
    if (v.empty() || *end || v[0] == '-' || b % 0x80 || b > 0x780)
        throw UsageError("--base must be a multiple of 0x80 up to 0x780 (got '" + v + "')");
    return (uint32_t)b;
}

}  // namespace

int cmd_modbus_ondevice(int argc, char **argv)
{
    Args a(argc, argv, 3,
           {"tcp", "rtu", "baud", "parity", "data-bits", "stop-bits", "unit", "design", "periods", "rate", "encoding",
            "word-order", "scale", "response-timeout", "byte-timeout", "retries", "timeout", "skip-periods",
            "transient", "alpha", "detect-lines", "stream-check", "output"},
           {"on-device"});
    const std::string out = a.require("output");
    MeasurePlan P;
    P.D = read_design_file(a.require("design"));
    parse_measure_options(a, *P.D, P.sf, P.rq);
    const std::string host_file = stream_check_option(a, out, P.rq);
    const ModbusLink link = modbus_link_options(a);
    P.timeout = a.f64("timeout", 10.0);
    if (!(P.timeout > 0)) throw UsageError("--timeout must be positive");
    Progress pg(stderr, is_terminal(stderr), false, "msid modbus");
    std::optional<StopOnSignal> guard;   // Ctrl-C during the stream check's host session keeps its complete periods
    if (!host_file.empty()) guard.emplace();
    msidacq::Control quiet;   // estimating only: no progress line (the device counts its own periods)
    msidacq::Control &ctl = host_file.empty() ? quiet : static_cast<msidacq::Control &>(pg);
    msidacq::OnDeviceResult R = msidacq::measure_modbus_ondevice(link, P, host_file, ctl);
    if (R.checked) {
        const int rc = write_measure_result(R.host, host_file, "modbus");
        if (rc != 0) return rc;
    }
    return write_ondevice(R, out);
}

int cmd_can_ondevice(int argc, char **argv)
{
    Args a(argc, argv, 3,
           {"iface", "base", "design", "periods", "rate", "encoding", "scale", "bitrate", "data-bitrate", "window",
            "rcvbuf", "timeout", "skip-periods", "transient", "alpha", "detect-lines", "stream-check", "output"},
           {"fd", "on-device"});
    const std::string out = a.require("output");
    CanLink link;
    link.iface = a.require("iface");
    link.base = can_base(a);
    link.window = a.u32("window", 16, 1, MSID_CAN_MAX_WINDOW);
    MeasurePlan P;
    P.D = read_design_file(a.require("design"));
    P.sf.fd = a.has("fd") ? 1 : 0;
    P.sf.encoding = a.enum_index("encoding", "int16", {"int16", "float32"}) ? MSID_CAN_ENC_F32 : MSID_CAN_ENC_S16;
    parse_measure_options(a, *P.D, P.sf, P.rq);
    const std::string host_file = stream_check_option(a, out, P.rq);
    link.bitrate = a.f64("bitrate", 0);
    link.data_bitrate = a.f64("data-bitrate", 0);
    if (!host_file.empty() && (a.has("bitrate") || a.has("data-bitrate")))
        throw UsageError("--stream-check streams every sample: run it on a virtual bus (without --bitrate)");
    if (link.bitrate < 0 || link.data_bitrate < 0) throw UsageError("--bitrate must be >= 0");
    P.timeout = a.f64("timeout", 10.0);
    if (!(P.timeout > 0 && P.timeout <= 86400)) throw UsageError("--timeout must be positive (at most 86400 s)");
    link.rcvbuf = a.has("rcvbuf") ? (int)parse_u32(a.get("rcvbuf"), "--rcvbuf") : 0;
    msidacq::OnDeviceResult R = msidacq::measure_can_ondevice(link, P, host_file);
    if (R.checked) msidjob::write_outcome(host_file, R.host.o);
    return write_ondevice(R, out);
}

}  // namespace msidcli
