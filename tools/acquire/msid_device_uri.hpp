// Device addresses (docs/measure.md), as `msid measure --device` and msid.measure take them:
//   modbus-tcp://HOST[:PORT][?unit=N]                      Modbus TCP, port 502 by default
//   modbus-rtu:///dev/ttyX[?baud=N&parity=N|E|O&unit=N&data-bits=7|8&stop-bits=1|2]   Modbus RTU
//   can://IFACE[?fd=0|1&base=ID]                           SocketCAN (msid-can/1)
//   canopen://IFACE?node=N[&timeout=MS&bitrate=BPS]        a CANopen node (msid_canopen.hpp), with --map only
#pragma once
#include <cstdint>
#include <string>

namespace msidacq {

struct DeviceUri {
    enum Kind { MODBUS_TCP, MODBUS_RTU, CAN, CANOPEN } kind = MODBUS_TCP;
    std::string text;          // as given
    std::string host;          // TCP: address (IPv6 without brackets)
    uint32_t port = 502;       // TCP
    std::string device;        // RTU: serial device path
    uint32_t baud = 115200;    // RTU
    char parity = 'N';         // RTU
    uint32_t data_bits = 8, stop_bits = 1;
    uint32_t unit = 1;         // Modbus unit (slave) id
    std::string iface;         // CAN interface
    bool fd = false;           // CAN FD sample frames
    uint32_t base = 0x200;     // CAN base identifier
    uint32_t node = 0;         // CANopen node id, 1..127
    int co_timeout_ms = 500;   // CANopen: each SDO response awaited this long
    uint32_t co_bitrate = 0;   // CANopen: the bus's bit rate (bit/s) for the SYNC rate's budget (0: not given)
    bool is_modbus() const { return kind == MODBUS_TCP || kind == MODBUS_RTU; }
    // "tcp:HOST:PORT", "rtu:/dev/ttyX", "can:IFACE": the short name used in messages and sources
    std::string name() const;
};

// Parse and check a device URI; every problem is one msidutil::UsageError naming the URI and the part at fault.
DeviceUri parse_device_uri(const std::string &uri);

}  // namespace msidacq
