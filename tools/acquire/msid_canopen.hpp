// CANopen nodes on SocketCAN, as msid's master reaches them (docs/devices.md, CANopen):
//   canopen://IFACE?node=N[&timeout=MS][&bitrate=BPS]   node 1..127 on interface IFACE, SDO responses awaited
//   MS ms; BPS the bus's bit rate (10000..1000000), for the bus budget of a measurement's SYNC rate (default:
//   the interface's, read from the kernel: canopen_bitrate)
// The link opens a raw CAN socket that receives only the node's SDO responses, heartbeat and EMCY, and
// holds daq/'s SDO client of that node. check_canopen reads what `msid device check` reports and writes
// nothing.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "msid_daq/msid_co_eds.h"
#include "msid_daq/msid_co_pdo.h"
#include "msid_daq/msid_co_sdo.h"

namespace msidacq {

struct CanopenUri {
    std::string text;            // as given
    std::string iface;
    unsigned node = 0;           // 1..127
    int timeout_ms = MSID_CO_SDO_TIMEOUT_MS;
    uint32_t bitrate = 0;        // bit/s; 0: not given (msid measure takes the interface's: canopen_bitrate)
};

// The bus's bit rate for the budget of a run's SYNC cycle (docs/devices.md, CANopen drives): the URI's
// bitrate= when it gives one, else the rate the kernel reports for the interface (ip -details link show
// IFACE), else MSID_CO_MAP_BITRATE_DEFAULT assumed: a virtual bus (vcan) has no rate, a controller may have
// none set, and the kernel may not answer.
struct CanopenBitrate {
    uint32_t bitrate = 0;        // bit/s for the budget
    uint32_t data_bitrate = 0;   // bit/s of the CAN FD data phase the interface reports (0: none)
    // "uri", "interface", "assumed (virtual interface)", "assumed (no bit rate set)", "assumed (interface not
    // read)": the FRF file's acquisition.bus_bitrate_source
    std::string source;
    std::string why;             // why assumed, for a message ("vcan0 is a virtual interface (vcan)"); "" otherwise
    bool assumed() const { return source.compare(0, 7, "assumed") == 0; }
};
// A UsageError naming the URI when iface is not a CAN interface (lo, a veth) or when the URI's bitrate= is
// not the rate the kernel reports for it; an interface that is not there is left to the socket's open.
CanopenBitrate canopen_bitrate(const std::string &uri_text, const std::string &iface, uint32_t uri_bitrate);

// True for a canopen:// URI (whether valid or not).
bool is_canopen_uri(const std::string &uri);
// Parse and check one; every problem is a msidutil::UsageError naming the URI and the part at fault.
CanopenUri parse_canopen_uri(const std::string &uri);

// An entry's address, "0x1018:01" as a user writes it (index hex, subindex hex or decimal).
struct CoEntry {
    uint16_t index = 0;
    uint8_t sub = 0;
};
CoEntry parse_co_entry(const std::string &text);  // UsageError naming the text

class CanopenLink {
public:
    explicit CanopenLink(const CanopenUri &uri);  // msidutil::IoError when the interface cannot be opened
    ~CanopenLink();
    CanopenLink(const CanopenLink &) = delete;
    CanopenLink &operator=(const CanopenLink &) = delete;

    // The entry's bytes, or msidutil::IoError with the SDO client's message (the node's abort named).
    std::vector<uint8_t> read(CoEntry e);
    void write(CoEntry e, const std::vector<uint8_t> &data);
    // The same without throwing: 0 or the daq code; err() names the failure.
    int try_read(CoEntry e, std::vector<uint8_t> &out);
    const char *err() const;
    msid_co_sdo &sdo();

private:
    struct Impl;
    std::unique_ptr<Impl> p_;
};

// A node's EDS/DCF read whole (a dictionary has some hundreds of entries; 4096 is room for any drive's): an
// IoError when the file cannot be read, a UsageError naming the line msid refuses.
struct EdsFile {
    std::vector<msid_co_od_entry> mem = std::vector<msid_co_od_entry>(4096);
    msid_co_eds eds{};
    explicit EdsFile(const std::string &path);
};

struct CanopenCheck {
    std::vector<std::string> lines;
    unsigned problems = 0;
};

// Identity 0x1018, device type 0x1000, error register 0x1001 and the first four TPDOs and RPDOs as the node
// holds them; nothing written. A node that does not answer is an IoError. eds (when not empty): the node's
// EDS/DCF, against which every entry read is checked (in the file, readable, of the size the node answered);
// each mismatch is a line and a problem.
CanopenCheck check_canopen(const CanopenUri &uri, const std::string &eds = "");

// Bytes written in hex, two digits a byte ("" for none); UsageError naming `what` (an option) and the text.
std::vector<uint8_t> parse_hex_bytes(const std::string &hex, const std::string &what);
// The same bytes as lower-case hex.
std::string hex_bytes(const std::vector<uint8_t> &b);

// One mapped object as a user writes it: INDEX:SUB/BITS (e.g. 0x606C:00/32).
msid_co_pdo_entry parse_pdo_entry(const std::string &text);  // UsageError naming the text
// A comma-separated list of them into c->e and c->n (at most MSID_CO_PDO_MAX_ENTRIES).
void parse_pdo_map(const std::string &list, msid_co_pdo_cfg &c);

// Configure one PDO (msid_co_pdo_configure: checked before anything is written, put back as it was when
// the node refuses part of it) and return its line as check_canopen prints it, read back from the node.
// A refusal is a UsageError; the node's is an IoError naming its abort.
// eds (when not empty): the node's EDS/DCF, against which the mapping is checked first.
std::string configure_pdo(const CanopenUri &uri, const msid_co_pdo_cfg &cfg, const std::string &eds = "");

// Check a write of `bytes` bytes to e against the EDS/DCF at eds_path: UsageError naming the entry and the
// problem (not in the file, read only, another size than its type's); IoError for a file msid cannot read.
void check_write_against_eds(const std::string &eds_path, CoEntry e, size_t bytes);

}  // namespace msidacq
