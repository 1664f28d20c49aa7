// canopen:// URIs, the bus's bit rate for a run (the URI's or the interface's)
// and the SDO link to one node (msid_canopen.hpp).
#include "msid_canopen.hpp"
#include "msid_host_util.hpp"

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include "msid_daq/msid_can_bitrate.h"
#include "msid_daq/msid_co_can.h"
#include "msid_daq/msid_co_map.h"
#include "msid_daq/msid_socketcan.h"

namespace msidacq {

using msidutil::fmt;
using msidutil::IoError;
using msidutil::UsageError;

static const char SCHEME[] = "canopen://";

bool is_canopen_uri(const std::string &uri) { return uri.compare(0, sizeof SCHEME - 1, SCHEME) == 0; }

static unsigned long query_number(const std::string &uri, const std::string &key, const std::string &v,
                                  unsigned long lo, unsigned long hi)
{
    char *end = nullptr;
    errno = 0;
    const unsigned long x = std::strtoul(v.c_str(), &end, 0);
    if (v.empty() || v[0] == '-' || v[0] == '+' || *end || errno || x < lo || x > hi)
        throw UsageError(fmt("device URI '%s': %s must be %lu..%lu (got '%s')", uri.c_str(), key.c_str(), lo, hi, v.c_str()));
    return x;
}

CanopenUri parse_canopen_uri(const std::string &uri)
{
    if (!is_canopen_uri(uri)) throw UsageError("'" + uri + "' is not a canopen:// URI: use canopen://IFACE?node=N");
    CanopenUri u;
    u.text = uri;
    const std::string rest = uri.substr(sizeof SCHEME - 1);
    const size_t q = rest.find('?');
    u.iface = rest.substr(0, q);
    if (u.iface.empty() || u.iface.size() >= 16 || u.iface.find('/') != std::string::npos)
        throw UsageError("device URI '" + uri + "': the interface name must be 1..15 characters without '/'");
    bool have_node = false;
    std::string query = q == std::string::npos ? "" : rest.substr(q + 1);
    while (!query.empty()) {
        const size_t amp = query.find('&');
        const std::string kv = query.substr(0, amp);
        query = amp == std::string::npos ? "" : query.substr(amp + 1);
        const size_t eq = kv.find('=');
        const std::string k = kv.substr(0, eq), v = eq == std::string::npos ? "" : kv.substr(eq + 1);
        if (k == "node") {
            u.node = (unsigned)query_number(uri, "node", v, MSID_CO_NODE_MIN, MSID_CO_NODE_MAX);
            have_node = true;
        } else if (k == "timeout") {
            u.timeout_ms = (int)query_number(uri, "timeout (ms)", v, 1, 60000);
        } else if (k == "bitrate") {
            u.bitrate = (uint32_t)query_number(uri, "bitrate (bit/s)", v, 10000, 1000000);
        } else {
            throw UsageError("device URI '" + uri + "': unknown parameter '" + k + "' (node, timeout, bitrate)");
        }
    }
    if (!have_node) throw UsageError("device URI '" + uri + "': give the node id: canopen://" + u.iface + "?node=N");
    return u;
}

CanopenBitrate canopen_bitrate(const std::string &uri_text, const std::string &iface, uint32_t uri_bitrate)
{
    msid_can_bitrate k{};
    msid_can_bitrate_query(iface.c_str(), &k);   // a failure is k.status FAILED, k.err saying why
    const char *u = uri_text.c_str(), *i = iface.c_str();
    if (k.status == MSID_CAN_BITRATE_NOT_CAN)
        throw UsageError(fmt("%s: %s is not a CAN interface (%s): give a SocketCAN interface (can0, vcan0)", u, i,
                             k.kind[0] ? fmt("its link kind is %s", k.kind).c_str() : "it has no link kind"));
    CanopenBitrate b;
    if (k.status == MSID_CAN_BITRATE_KNOWN) b.data_bitrate = k.data_bitrate;
    if (uri_bitrate) {
        if (k.status == MSID_CAN_BITRATE_KNOWN && k.bitrate != uri_bitrate)
            throw UsageError(fmt("%s: the URI's bitrate=%u is not the %u bit/s %s is set to (ip -details link show %s): "
                                 "leave bitrate= out, or give the interface the bus's rate (ip link set %s type can "
                                 "bitrate %u)", u, (unsigned)uri_bitrate, (unsigned)k.bitrate, i, i, i,
                                 (unsigned)uri_bitrate));
        b.bitrate = uri_bitrate;
        b.source = "uri";
        return b;
    }
    if (k.status == MSID_CAN_BITRATE_KNOWN) {
        b.bitrate = k.bitrate;
        b.source = "interface";
        return b;
    }
    b.bitrate = MSID_CO_MAP_BITRATE_DEFAULT;
    if (k.status == MSID_CAN_BITRATE_VIRTUAL) {
        b.source = "assumed (virtual interface)";
        b.why = fmt("%s is a virtual interface (%s)", i, k.kind);
    } else if (k.status == MSID_CAN_BITRATE_UNSET) {
        b.source = "assumed (no bit rate set)";
        b.why = fmt("%s has no bit rate set", i);
    } else {
        b.source = "assumed (interface not read)";
        b.why = fmt("the bit rate of %s could not be read: %s", i,
                    k.status == MSID_CAN_BITRATE_MISSING ? "no such interface" : k.err);
    }
    return b;
}

CoEntry parse_co_entry(const std::string &text)
{
    const size_t colon = text.find(':');
    char *end = nullptr;
    errno = 0;
    const std::string idx = text.substr(0, colon);   // named: strtoul's end points into it
    const unsigned long index = std::strtoul(idx.c_str(), &end, 16);
    const bool index_ok = colon != std::string::npos && colon > 0 && *end == '\0' && !errno && index <= 0xFFFF;
    const std::string s = colon == std::string::npos ? "" : text.substr(colon + 1);
    const unsigned long sub = std::strtoul(s.c_str(), &end, 16);
    if (!index_ok || s.empty() || *end || errno || sub > 0xFF || text[0] == '-' || (!s.empty() && s[0] == '-'))
        throw UsageError("'" + text + "' is not an object dictionary entry: write INDEX:SUB in hex, e.g. 0x1018:01");
    return CoEntry{(uint16_t)index, (uint8_t)sub};
}

std::vector<uint8_t> parse_hex_bytes(const std::string &h, const std::string &what)
{
    std::vector<uint8_t> out;
    auto digit = [&](char c) {
        if (c >= '0' && c <= '9') return c - '0';
        if (c >= 'a' && c <= 'f') return c - 'a' + 10;
        if (c >= 'A' && c <= 'F') return c - 'A' + 10;
        throw UsageError(what + ": '" + h + "' is not hex (two digits a byte)");
    };
    if (h.size() % 2) throw UsageError(what + ": '" + h + "' has an odd number of hex digits");
    for (size_t i = 0; i < h.size(); i += 2) out.push_back((uint8_t)(digit(h[i]) * 16 + digit(h[i + 1])));
    return out;
}

std::string hex_bytes(const std::vector<uint8_t> &b)
{
    static const char D[] = "0123456789abcdef";
    std::string s;
    for (uint8_t x : b) s += {D[x >> 4], D[x & 15]};
    return s;
}

struct CanopenLink::Impl {
    msid_socketcan sock{};
    msid_co_can adapter{};
    msid_co_sdo sdo{};
    bool open = false;
};

CanopenLink::CanopenLink(const CanopenUri &uri) : p_(new Impl)
{
    msid_socketcan_cfg cfg{};
    cfg.iface = uri.iface.c_str();
    /* only the node's SDO responses, EMCY and heartbeat, standard frames without RTR */
    const uint32_t ids[3] = {MSID_CO_COB_SDO_TX + uri.node, MSID_CO_COB_EMCY + uri.node, MSID_CO_COB_HEARTBEAT + uri.node};
    for (int i = 0; i < 3; i++) {
        cfg.filter_id[i] = ids[i];
        cfg.filter_mask[i] = 0x7FFu | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
    }
    cfg.n_filters = 3;
    if (msid_socketcan_open(&p_->sock, &cfg) < 0)
        throw IoError(fmt("%s: %s", uri.text.c_str(), p_->sock.err));
    p_->open = true;
    msid_co_io io;
    msid_co_can_io(&p_->adapter, &p_->sock.tr, uri.timeout_ms, &io);
    if (msid_co_sdo_init(&p_->sdo, &io, uri.node, uri.timeout_ms) < 0) throw UsageError(p_->sdo.err);
}

CanopenLink::~CanopenLink()
{
    if (p_->open) msid_can_close(&p_->sock.tr);
}

msid_co_sdo &CanopenLink::sdo() { return p_->sdo; }

const char *CanopenLink::err() const { return p_->sdo.err; }

int CanopenLink::try_read(CoEntry e, std::vector<uint8_t> &out)
{
    /* the largest entry msid reads is a string of identity or a domain of a test; 4 KiB holds them */
    out.assign(4096, 0);
    size_t n = 0;
    const int rc = msid_co_sdo_upload(&p_->sdo, e.index, e.sub, out.data(), out.size(), &n);
    out.resize(rc ? 0 : n);
    return rc;
}

std::vector<uint8_t> CanopenLink::read(CoEntry e)
{
    std::vector<uint8_t> out;
    if (try_read(e, out)) throw IoError(p_->sdo.err);
    return out;
}

void CanopenLink::write(CoEntry e, const std::vector<uint8_t> &data)
{
    if (msid_co_sdo_download(&p_->sdo, e.index, e.sub, data.data(), data.size())) throw IoError(p_->sdo.err);
}

}  // namespace msidacq
