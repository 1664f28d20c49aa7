// `msid device check` of a CANopen node (msid_canopen.hpp): what the node says it is and how its PDOs
// are mapped, read by SDO; nothing is written.
#include "msid_canopen.hpp"
#include "msid_host_util.hpp"

#include <cstdlib>
#include <memory>
#include <vector>

#include "msid_daq/msid_co_eds.h"
#include "msid_daq/msid_co_emcy.h"
#include "msid_daq/msid_co_pdo.h"

namespace msidacq {

using msidutil::fmt;
using msidutil::IoError;
using msidutil::UsageError;

EdsFile::EdsFile(const std::string &path)
{
    const int rc = msid_co_eds_load(path.c_str(), &eds, mem.data(), (uint32_t)mem.size());
    if (rc == -MSID_DAQ_E_IO) throw IoError(eds.err);
    if (rc) throw UsageError(eds.err);
}

// `device check --eds FILE`: every entry the check read, against the node's EDS/DCF: in the file, readable
// there, and of the size msid read it with (the node answered that size). One line per mismatch, each a problem.
class EdsAudit {
public:
    explicit EdsAudit(const std::string &path) : path_(path)
    {
        if (!path.empty()) f_.reset(new EdsFile(path));
    }
    void read(uint16_t index, uint8_t sub, unsigned bytes)
    {
        if (!f_) return;
        const msid_co_od_entry *e = msid_co_eds_find(&f_->eds, index, sub);
        std::string why;
        if (!e)
            why = "the node has it, the EDS does not";
        else if (e->access == MSID_CO_WO)
            why = fmt("write only in the EDS (line %u), yet the node answered a read", (unsigned)e->line);
        else {
            const unsigned bits = msid_co_type_bits(e->type);
            if (bits && (bits + 7u) / 8u != bytes)
                why = fmt("the EDS (line %u) gives %s (%u bytes), the node answered %u bytes", (unsigned)e->line,
                          msid_co_type_name(e->type), (bits + 7u) / 8u, bytes);
        }
        if (why.empty()) return;
        lines.push_back(fmt("EDS 0x%04X:%02X: %s   <- against %s", (unsigned)index, (unsigned)sub, why.c_str(), path_.c_str()));
    }
    // an object the node does not have (its SDO aborted) that the EDS lists
    void absent(uint16_t index, uint8_t sub)
    {
        if (!f_) return;
        const msid_co_od_entry *e = msid_co_eds_find(&f_->eds, index, sub);
        if (e)
            lines.push_back(fmt("EDS 0x%04X:%02X: in the EDS (line %u), the node does not have it   <- against %s",
                                (unsigned)index, (unsigned)sub, (unsigned)e->line, path_.c_str()));
    }
    std::vector<std::string> lines;

private:
    std::string path_;
    std::unique_ptr<EdsFile> f_;
};

static uint32_t read_u32(CanopenLink &l, uint16_t index, uint8_t sub, unsigned size, EdsAudit *audit = nullptr)
{
    uint32_t v = 0;
    if (msid_co_sdo_read_uint(&l.sdo(), index, sub, size, &v)) throw IoError(l.err());
    if (audit) audit->read(index, sub, size);
    return v;
}

static std::string identity(CanopenLink &l, EdsAudit *audit)
{
    static const char *const NAMES[4] = {"vendor", "product", "revision", "serial"};
    const uint32_t n = read_u32(l, 0x1018, 0, 1, audit);
    std::string line = "identity 0x1018:";
    for (uint32_t i = 1; i <= n && i <= 4; i++)
        line += fmt(" %s 0x%08X", NAMES[i - 1], (unsigned)read_u32(l, 0x1018, (uint8_t)i, 4, audit));
    return line;
}

static std::string error_register(CanopenLink &l, unsigned &problems, EdsAudit *audit)
{
    const uint32_t reg = read_u32(l, 0x1001, 0, 1, audit);
    if (!reg) return "error register 0x1001: 0x00 (no error)";
    char bits[96];
    msid_co_erreg_describe((uint8_t)reg, bits, sizeof bits);
    problems++;
    return fmt("error register 0x1001: 0x%02X (%s)   <- the node reports an error", (unsigned)reg, bits);
}

static std::string pdo_line(CanopenLink &l, unsigned tx, unsigned num, EdsAudit *audit = nullptr)
{
    msid_co_pdo_cfg c;
    const char *kind = tx ? "TPDO" : "RPDO";
    const int rc = msid_co_pdo_save(&l.sdo(), tx, num, &c);
    const uint16_t comm = msid_co_pdo_comm_index(tx, num), map = (uint16_t)(comm + 0x200u);
    if (rc == -MSID_DAQ_E_DEVICE && l.sdo().abort_by_node &&
        (l.sdo().abort_code == 0x06020000u || l.sdo().abort_code == 0x06090011u)) {
        if (audit) audit->absent(comm, 1);
        return fmt("%s%u: not present", kind, num);
    }
    if (rc) throw IoError(l.err());
    if (audit) {
        /* what msid_co_pdo_save read, with its sizes (a TPDO without an inhibit time answered none) */
        audit->read(comm, 1, 4);
        audit->read(comm, 2, 1);
        audit->read(map, 0, 1);
        for (unsigned i = 1; i <= c.n; i++) audit->read(map, (uint8_t)i, 4);
    }
    std::string line = fmt("%s%u: COB-ID 0x%03X (%s), transmission type %u", kind, num, (unsigned)(c.cob_id & 0x7FFu),
                           (c.cob_id & MSID_CO_PDO_COB_INVALID) ? "not valid" : "valid", (unsigned)c.trans_type);
    if (tx) line += fmt(", inhibit %u x 100 us", (unsigned)c.inhibit_100us);
    line += fmt(", %u bits:", msid_co_pdo_bits(&c));
    if (!c.n) line += " nothing mapped";
    for (unsigned i = 0; i < c.n; i++)
        line += fmt(" 0x%04X:%02X/%u", (unsigned)c.e[i].index, (unsigned)c.e[i].sub, (unsigned)c.e[i].bits);
    return line;
}

// The bus's bit rate as a measurement takes it for its budget (canopen_bitrate): the URI's, the interface's,
// or, when the interface reports none (vcan has none), said plainly with the rate a run would assume.
static std::string bitrate_line(const CanopenUri &uri)
{
    const CanopenBitrate b = canopen_bitrate(uri.text, uri.iface, uri.bitrate);
    const std::string fd = b.data_bitrate ? fmt(", CAN FD data phase %u bit/s", (unsigned)b.data_bitrate) : "";
    if (b.source == "interface")
        return fmt("bus bit rate: %u bit/s%s (what %s is set to, as the kernel reports it)", (unsigned)b.bitrate,
                   fd.c_str(), uri.iface.c_str());
    if (b.source == "uri") return fmt("bus bit rate: %u bit/s%s (the URI's bitrate=)", (unsigned)b.bitrate, fd.c_str());
    return fmt("bus bit rate: not reported: %s; a measurement's bus budget assumes %u bit/s unless the URI gives "
               "bitrate=BPS", b.why.c_str(), (unsigned)b.bitrate);
}

msid_co_pdo_entry parse_pdo_entry(const std::string &text)
{
    const size_t slash = text.find('/');
    const CoEntry e = parse_co_entry(text.substr(0, slash));
    const std::string b = slash == std::string::npos ? "" : text.substr(slash + 1);
    char *end = nullptr;
    const unsigned long bits = std::strtoul(b.c_str(), &end, 10);
    if (b.empty() || *end || bits < 1 || bits > 64)
        throw UsageError("'" + text + "' is not a mapped object: write INDEX:SUB/BITS, e.g. 0x606C:00/32 (1..64 bits)");
    return msid_co_pdo_entry{e.index, e.sub, (uint8_t)bits};
}

void parse_pdo_map(const std::string &list, msid_co_pdo_cfg &c)
{
    c.n = 0;
    std::string rest = list;
    while (!rest.empty()) {
        const size_t comma = rest.find(',');
        if (c.n >= MSID_CO_PDO_MAX_ENTRIES)
            throw UsageError(fmt(MSID_OPT("map") ": more than %u objects: a PDO of 8 bytes holds at most %u", MSID_CO_PDO_MAX_ENTRIES,
                                 MSID_CO_PDO_MAX_ENTRIES));
        c.e[c.n++] = parse_pdo_entry(rest.substr(0, comma));
        rest = comma == std::string::npos ? "" : rest.substr(comma + 1);
    }
}

void check_write_against_eds(const std::string &eds_path, CoEntry e, size_t bytes)
{
    const EdsFile f(eds_path);
    char err[240];
    if (msid_co_eds_check_write(&f.eds, e.index, e.sub, bytes, err, sizeof err)) throw UsageError(err);
}

std::string configure_pdo(const CanopenUri &uri, const msid_co_pdo_cfg &cfg, const std::string &eds)
{
    char err[240];
    if (msid_co_pdo_check(&cfg, uri.node, err, sizeof err)) throw UsageError(err);
    if (!eds.empty()) {
        const EdsFile f(eds);
        if (msid_co_eds_check_pdo(&f.eds, &cfg, err, sizeof err)) throw UsageError(err);
    }
    CanopenLink l(uri);
    msid_co_pdo_cfg saved;
    if (msid_co_pdo_save(&l.sdo(), cfg.tx, cfg.num, &saved)) throw IoError(l.err());
    if (msid_co_pdo_configure(&l.sdo(), &cfg, &saved)) throw IoError(l.err());
    return pdo_line(l, cfg.tx, cfg.num);
}

CanopenCheck check_canopen(const CanopenUri &uri, const std::string &eds)
{
    EdsAudit audit(eds);
    // before the socket: an interface that is not CAN (lo) is named as such; a missing one is the socket's message
    const std::string bus = bitrate_line(uri);
    CanopenLink l(uri);
    CanopenCheck r;
    const uint32_t type = read_u32(l, 0x1000, 0, 4, &audit);
    r.lines.push_back(fmt("node %u on %s: device type 0x1000: 0x%08X (profile CiA %u%s)", uri.node, uri.iface.c_str(),
                          (unsigned)type, (unsigned)(type & 0xFFFFu), (type & 0xFFFFu) == 402 ? ", a drive" : ""));
    r.lines.push_back(bus);
    r.lines.push_back(identity(l, &audit));
    r.lines.push_back(error_register(l, r.problems, &audit));
    for (unsigned tx : {1u, 0u})
        for (unsigned num = 1; num <= 4; num++) r.lines.push_back(pdo_line(l, tx, num, &audit));
    r.lines.insert(r.lines.end(), audit.lines.begin(), audit.lines.end());
    r.problems += (unsigned)audit.lines.size();
    if (!eds.empty() && audit.lines.empty()) r.lines.push_back("EDS " + eds + ": every entry read matches (present, readable, its size)");
    return r;
}

}  // namespace msidacq
