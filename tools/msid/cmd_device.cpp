// msid device check: what a user runs first on a real machine. Read every channel of a described device
// (msid-device/1) once, write nothing but the safe values, and report what the device answered against the
// description. docs/devices.md.
#include "commands.hpp"
#include "host_libs.hpp"
#include "measure.hpp"

#include <cstdio>

#include "msid_canopen.hpp"

namespace msidcli {

static const char *DEVICE_HELP =
    "usage: msid device check --map DEVICE.toml --device URI\n"
    "       msid device check --device canopen://IFACE?node=N [--eds FILE]\n"
    "\n"
    "Read the description (every key, type, range and register checked), connect, write the drive\n"
    "channels' safe values (nothing else is written), read every measure channel once and the drive\n"
    "registers back, and print one line per channel. Exit status 0 when every value is in place,\n"
    "1 when a channel is out of place or the device refused a request, 2 for a bad description.\n"
    "\n"
    "  --map FILE     msid-device/1 (docs/devices.md)\n"
    "  --device URI   modbus-tcp://HOST[:PORT][?unit=N] or modbus-rtu:///dev/ttyX?baud=N\n"
    "\n"
    "A CANopen node (canopen://IFACE?node=N[&timeout=MS]) is read by SDO without a description: its\n"
    "device type, identity 0x1018, error register 0x1001 and the mapping of TPDO1-4 and RPDO1-4, and\n"
    "the bus's bit rate (the URI's bitrate=, else the interface's; one that reports none, as vcan, is said).\n"
    "Nothing is written. Exit status 1 when the node does not answer or reports an error.\n"
    "  --eds FILE     the node's EDS or DCF: each entry read is checked against it (in the file, readable,\n"
    "                 of the size the node answered); a mismatch is a line and exit status 1\n";

// Print a check's lines; exit status 1 with `problems` named when there are any, else the ok line.
static int report_check(const std::vector<std::string> &lines, unsigned problems, const char *what, const char *ok)
{
    for (const std::string &l : lines) std::printf("%s\n", l.c_str());
    if (problems) {
        std::fprintf(stderr, "msid device: error: %u %s (marked above)\n", problems, what);
        return 1;
    }
    std::printf("ok: %s\n", ok);
    return 0;
}

static int cmd_check(int argc, char **argv)
{
    Args a(argc, argv, 3, DEVICE_HELP, {"map", "device", "eds"}, {});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    if (msidacq::is_canopen_uri(a.require("device"))) {
        if (a.has("map")) throw UsageError("--map: a CANopen node is checked without a description (for now)");
        const msidacq::CanopenCheck r = msidacq::check_canopen(msidacq::parse_canopen_uri(a.get("device")), a.get("eds"));
        return report_check(r.lines, r.problems, "problem(s) the node reports or the EDS check found",
                            "the node answered; nothing was written");
    }
    if (a.has("eds")) throw UsageError("--eds: only a CANopen node (canopen://) is checked against an EDS");
    const msid_devdesc desc = msidacq::load_description(a.require("map"));
    const DeviceUri dev = parse_device_uri(a.require("device"));
    const msidacq::CheckResult r = msidacq::check_device(dev, desc);
    return report_check(r.lines, r.problems, "channel(s) out of place", "every channel answered as described");
}

static const char *SDO_HELP =
    "usage: msid device sdo --device canopen://IFACE?node=N --read INDEX:SUB\n"
    "       msid device sdo --device canopen://IFACE?node=N --write INDEX:SUB --data HEX [--eds FILE]\n"
    "\n"
    "Read one object dictionary entry of a CANopen node by SDO and print its bytes in hex, or write\n"
    "the bytes HEX (two digits a byte, '' for none) to it. An abort from the node is named with its\n"
    "CiA 301 code (exit status 1). With --eds (the node's EDS or DCF), a write to an entry the file does\n"
    "not have, a read-only entry or a size other than the entry's type is refused before it is sent.\n";

static int cmd_sdo(int argc, char **argv)
{
    Args a(argc, argv, 3, SDO_HELP, {"device", "read", "write", "data", "eds"}, {});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    if (a.has("read") == a.has("write")) throw UsageError("give one of --read and --write");
    if (a.has("write") && !a.has("data")) throw UsageError("--write needs --data HEX");
    const msidacq::CanopenUri uri = msidacq::parse_canopen_uri(a.require("device"));
    const msidacq::CoEntry e = msidacq::parse_co_entry(a.has("read") ? a.get("read") : a.get("write"));
    const std::vector<uint8_t> data = a.has("write") ? msidacq::parse_hex_bytes(a.get("data"), "--data") : std::vector<uint8_t>{};
    if (a.has("write") && a.has("eds")) msidacq::check_write_against_eds(a.get("eds"), e, data.size());
    msidacq::CanopenLink link(uri);
    if (a.has("write")) {
        link.write(e, data);
        std::printf("wrote %zu bytes\n", data.size());
        return 0;
    }
    std::printf("%s\n", msidacq::hex_bytes(link.read(e)).c_str());
    return 0;
}

static const char *PDO_HELP =
    "usage: msid device pdo --device canopen://IFACE?node=N --tpdo K | --rpdo K --map LIST\n"
    "                       [--transmission T] [--inhibit-us U] [--cob-id ID] [--eds FILE]\n"
    "\n"
    "Configure one PDO of a CANopen node by SDO in CiA 301's order (not valid, transmission type,\n"
    "inhibit time, count 0, entries, count, valid) and print it as the node then holds it. A mapping\n"
    "longer than 8 bytes, a restricted COB-ID or a transmission type the PDO cannot take is refused\n"
    "before anything is written; when the node refuses part of it, what it held is written back.\n"
    "\n"
    "  --tpdo K / --rpdo K  PDO number 1..512 (node to msid / msid to node)\n"
    "  --map LIST           mapped objects INDEX:SUB/BITS, comma separated (e.g. 0x6041:00/16,0x606C:00/32)\n"
    "  --transmission T     transmission type (default 1: every SYNC)\n"
    "  --inhibit-us U       TPDO inhibit time in us, a multiple of 100 (default 0)\n"
    "  --cob-id ID          COB-ID (default: the predefined connection set's, PDOs 1..4)\n"
    "  --eds FILE           the node's EDS or DCF: each mapped object checked first (in the file,\n"
    "                       PDO-mappable, of its type's bits; an RPDO's writable)\n";

static int cmd_pdo(int argc, char **argv)
{
    Args a(argc, argv, 3, PDO_HELP, {"device", "tpdo", "rpdo", "map", "transmission", "inhibit-us", "cob-id", "eds"}, {});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    if (a.has("tpdo") == a.has("rpdo")) throw UsageError("give one of --tpdo and --rpdo");
    const msidacq::CanopenUri uri = msidacq::parse_canopen_uri(a.require("device"));
    msid_co_pdo_cfg c{};
    c.tx = a.has("tpdo") ? 1 : 0;
    c.num = (uint16_t)a.u32(c.tx ? "tpdo" : "rpdo", 1, 1, 512);
    c.trans_type = (uint8_t)a.u32("transmission", MSID_CO_PDO_SYNC_EVERY, 0, 255);
    const uint32_t inhibit = a.u32("inhibit-us", 0, 0, 6553500);
    if (inhibit % 100) throw UsageError("--inhibit-us must be a multiple of 100 (CiA 301 counts it in 100 us)");
    if (inhibit && !c.tx) throw UsageError("--inhibit-us: an RPDO has no inhibit time");
    c.inhibit_100us = (uint16_t)(inhibit / 100);
    c.cob_id = a.u32("cob-id", 0, 0, 0x7FF);
    msidacq::parse_pdo_map(a.require("map"), c);
    std::printf("%s\n", msidacq::configure_pdo(uri, c, a.get("eds")).c_str());
    return 0;
}

static const char *GROUP_HELP =
    "usage: msid device check --map DEVICE.toml --device URI\n"
    "       msid device sdo --device canopen://IFACE?node=N --read INDEX:SUB | --write INDEX:SUB --data HEX\n"
    "       msid device pdo --device canopen://IFACE?node=N --tpdo K | --rpdo K --map LIST\n"
    "\n"
    "  check   read every channel of a described device once, write only the safe values (docs/devices.md)\n"
    "  sdo     read or write one object dictionary entry of a CANopen node\n"
    "  pdo     configure one PDO of a CANopen node\n";

int cmd_device(int argc, char **argv)
{
    return dispatch_subcommand(argc, argv, "device", GROUP_HELP, {{"check", cmd_check}, {"sdo", cmd_sdo}, {"pdo", cmd_pdo}}, true);
}

}  // namespace msidcli
