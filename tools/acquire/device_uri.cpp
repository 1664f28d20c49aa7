// Device URIs (msid_device_uri.hpp).
#include "msid_device_uri.hpp"
#include "msid_canopen.hpp"
#include "msid_host_util.hpp"

#include <cerrno>
#include <cstdlib>
#include <vector>

namespace msidacq {

using msidutil::fmt;
using msidutil::UsageError;

std::string DeviceUri::name() const
{
    switch (kind) {
    case MODBUS_TCP: return "tcp:" + (host.find(':') != std::string::npos ? "[" + host + "]" : host) + ":" +
                            std::to_string(port);
    case MODBUS_RTU: return "rtu:" + device;
    case CANOPEN: return "canopen:" + iface + ":" + std::to_string(node);
    default: return "can:" + iface;
    }
}

static uint32_t uri_uint(const std::string &uri, const std::string &what, const std::string &v, uint64_t lo, uint64_t hi)
{
    char *end = nullptr;
    errno = 0;
    const bool hex = v.size() > 2 && v[0] == '0' && (v[1] == 'x' || v[1] == 'X');
    const unsigned long long x = std::strtoull(v.c_str(), &end, hex ? 16 : 10);
    if (v.empty() || v[0] == '-' || v[0] == '+' || *end || errno || x < lo || x > hi)
        throw UsageError(fmt("device URI '%s': %s must be %llu..%llu (got '%s')", uri.c_str(), what.c_str(),
                             (unsigned long long)lo, (unsigned long long)hi, v.c_str()));
    return (uint32_t)x;
}

DeviceUri parse_device_uri(const std::string &uri)
{
    DeviceUri d;
    d.text = uri;
    const size_t sep = uri.find("://");
    if (sep == std::string::npos)
        throw UsageError("'" + uri + "' is not a device URI: use modbus-tcp://HOST[:PORT], "
                         "modbus-rtu:///dev/ttyX?baud=N or can://IFACE[?fd=1]");
    const std::string scheme = uri.substr(0, sep);
    std::string rest = uri.substr(sep + 3), query;
    const size_t q = rest.find('?');
    if (q != std::string::npos) { query = rest.substr(q + 1); rest = rest.substr(0, q); }
    if (scheme == "canopen") {
        // its own parser (node 1..127, timeout), shared with msid device check|sdo|pdo
        const CanopenUri co = parse_canopen_uri(uri);
        d.kind = DeviceUri::CANOPEN;
        d.iface = co.iface;
        d.node = co.node;
        d.co_timeout_ms = co.timeout_ms;
        d.co_bitrate = co.bitrate;
        return d;
    }
    if (scheme == "modbus-tcp") d.kind = DeviceUri::MODBUS_TCP;
    else if (scheme == "modbus-rtu") d.kind = DeviceUri::MODBUS_RTU;
    else if (scheme == "can") d.kind = DeviceUri::CAN;
    else
        throw UsageError("device URI '" + uri + "': unknown scheme '" + scheme +
                         "' (modbus-tcp, modbus-rtu, can or canopen)");

    if (d.kind == DeviceUri::MODBUS_TCP) {
        std::string port;
        if (!rest.empty() && rest[0] == '[') {   // [IPv6]:port
            const size_t close = rest.find(']');
            if (close == std::string::npos) throw UsageError("device URI '" + uri + "': unclosed '[' in the address");
            d.host = rest.substr(1, close - 1);
            const std::string after = rest.substr(close + 1);
            if (!after.empty() && after[0] != ':') throw UsageError("device URI '" + uri + "': text after ']' must be :PORT");
            if (!after.empty()) port = after.substr(1);
            else port = "502";
        } else {
            const size_t colon = rest.find(':');
            if (colon != std::string::npos && rest.find(':', colon + 1) != std::string::npos)
                throw UsageError("device URI '" + uri + "': write an IPv6 address in brackets, modbus-tcp://[::1]:502");
            d.host = rest.substr(0, colon);
            port = colon == std::string::npos ? "502" : rest.substr(colon + 1);
        }
        if (d.host.empty()) throw UsageError("device URI '" + uri + "': no host (modbus-tcp://HOST[:PORT])");
        if (d.host.find('/') != std::string::npos) throw UsageError("device URI '" + uri + "': a host has no path ('/')");
        d.port = uri_uint(uri, "the port", port, 1, 65535);
    } else if (d.kind == DeviceUri::MODBUS_RTU) {
        if (rest.empty() || rest[0] != '/')
            throw UsageError("device URI '" + uri + "': the serial device must be an absolute path "
                             "(modbus-rtu:///dev/ttyUSB0?baud=115200)");
        d.device = rest;
    } else {
        if (rest.empty()) throw UsageError("device URI '" + uri + "': no interface (can://can0)");
        if (rest.size() > 15 || rest.find_first_of("/:") != std::string::npos)
            throw UsageError("device URI '" + uri + "': '" + rest + "' is not a network interface name");
        d.iface = rest;
    }

    // key=value&key=value
    size_t at = 0;
    while (!query.empty() && at <= query.size()) {
        const size_t amp = query.find('&', at);
        const std::string kv = query.substr(at, amp == std::string::npos ? std::string::npos : amp - at);
        at = amp == std::string::npos ? query.size() + 1 : amp + 1;
        const size_t eq = kv.find('=');
        if (eq == std::string::npos || eq == 0)
            throw UsageError("device URI '" + uri + "': '" + kv + "' is not key=value");
        const std::string k = kv.substr(0, eq), v = kv.substr(eq + 1);
        const bool rtu = d.kind == DeviceUri::MODBUS_RTU;
        if (d.is_modbus() && k == "unit") d.unit = uri_uint(uri, "unit", v, rtu ? 1 : 0, rtu ? 247 : 255);
        else if (rtu && k == "baud") d.baud = uri_uint(uri, "baud", v, 300, 4000000);
        else if (rtu && k == "parity") {
            if (v != "N" && v != "E" && v != "O")
                throw UsageError("device URI '" + uri + "': parity must be N, E or O (got '" + v + "')");
            d.parity = v[0];
        } else if (rtu && k == "data-bits") d.data_bits = uri_uint(uri, "data-bits", v, 7, 8);
        else if (rtu && k == "stop-bits") d.stop_bits = uri_uint(uri, "stop-bits", v, 1, 2);
        else if (d.kind == DeviceUri::CAN && k == "fd") d.fd = uri_uint(uri, "fd", v, 0, 1) != 0;
        else if (d.kind == DeviceUri::CAN && k == "base") {
            d.base = uri_uint(uri, "base", v, 0, 0x780);
            if (d.base % 0x80) throw UsageError("device URI '" + uri + "': base must be a multiple of 0x80");
        } else {
            const char *known = rtu ? "baud, parity, data-bits, stop-bits, unit"
                                    : d.kind == DeviceUri::CAN ? "fd, base" : "unit";
            throw UsageError("device URI '" + uri + "': unknown parameter '" + k + "' (" + scheme + " takes " + known + ")");
        }
    }
    return d;
}

}  // namespace msidacq
