// The Modbus link of `msid modbus measure` (cmd_modbus.cpp) and of its on-device readout
// (cmd_ondevice.cpp): --tcp HOST:PORT, or --rtu DEVICE with --baud, --parity, --data-bits and
// --stop-bits; --unit. One function opens it for both.
#pragma once
#include "cli_util.hpp"

extern "C" {
#include "msid_daq/msid_modbus.h"
}

#include <string>

namespace msidcli {

struct ModbusLink {
    msid_modbus m{};
    bool open = false;
    std::string name;       // "tcp:127.0.0.1:1502" / "rtu:/dev/pts/3"
    ~ModbusLink() { close(); }
    void close()
    {
        if (open) msid_mb_close(&m.tr);
        open = false;
    }
};

// Open L from the options (timeouts in ms). Throws UsageError for bad options, Error when it cannot connect.
void open_modbus_link(const Args &a, ModbusLink &L, uint32_t resp_ms, uint32_t byte_ms);

}  // namespace msidcli
