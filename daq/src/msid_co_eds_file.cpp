// EDS/DCF files (CiA 306, INI) -> msid_co_eds (msid_co_eds.h). Sections are gathered with their keys and
// lines first; then each object section becomes its entries: a variable or domain one entry (subindex 0),
// a record or array its [XXXXsubY] sections, or an array's CompactSubObj entries.
extern "C" {
#include "msid_daq/msid_co_eds.h"
}

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace {

struct Fail {
    int rc;
    std::string msg;
};

struct Section {
    std::string name;  // as written
    uint32_t line = 0;
    std::map<std::string, std::string> keys;  // lower-case key -> value
};

std::string trim(const std::string &s)
{
    size_t a = 0, b = s.size();
    while (a < b && std::isspace((unsigned char)s[a])) a++;
    while (b > a && std::isspace((unsigned char)s[b - 1])) b--;
    return s.substr(a, b - a);
}

std::string lower(std::string s)
{
    for (char &c : s) c = (char)std::tolower((unsigned char)c);
    return s;
}

std::vector<Section> read_sections(const std::string &path)
{
    std::ifstream in(path);
    if (!in) throw Fail{-MSID_DAQ_E_IO, path + ": cannot be read: " + std::strerror(errno)};
    std::vector<Section> out;
    std::string line;
    uint32_t n = 0;
    while (std::getline(in, line)) {
        n++;
        const std::string t = trim(line);
        if (t.empty() || t[0] == ';' || t[0] == '#') continue;
        if (t[0] == '[') {
            if (t.back() != ']') throw Fail{-MSID_DAQ_E_FORMAT, path + " line " + std::to_string(n) + ": unclosed section name"};
            out.push_back(Section{trim(t.substr(1, t.size() - 2)), n, {}});
            continue;
        }
        const size_t eq = t.find('=');
        if (eq == std::string::npos || out.empty()) continue;  // outside sections or not a key: skipped
        out.back().keys[lower(trim(t.substr(0, eq)))] = trim(t.substr(eq + 1));
    }
    return out;
}

bool hex4(const std::string &s, size_t at) { return s.size() >= at + 4 && std::all_of(s.begin() + (long)at, s.begin() + (long)at + 4, ::isxdigit); }

unsigned long number(const Section &s, const std::string &key, const std::string &path)
{
    const auto it = s.keys.find(key);
    char *end = nullptr;
    const unsigned long v = it == s.keys.end() ? 0 : std::strtoul(it->second.c_str(), &end, 0);
    if (it == s.keys.end() || it->second.empty() || *end)
        throw Fail{-MSID_DAQ_E_FORMAT, path + " line " + std::to_string(s.line) + ": [" + s.name + "] " +
                                           (it == s.keys.end() ? "has no " + key : key + " '" + it->second + "' is not a number")};
    return v;
}

uint8_t access_of(const Section &s, const std::string &path)
{
    static const std::pair<const char *, msid_co_access> A[] = {{"ro", MSID_CO_RO},   {"wo", MSID_CO_WO},
                                                               {"rw", MSID_CO_RW},   {"rwr", MSID_CO_RWR},
                                                               {"rww", MSID_CO_RWW}, {"const", MSID_CO_CONST}};
    const auto it = s.keys.find("accesstype");
    if (it == s.keys.end()) throw Fail{-MSID_DAQ_E_FORMAT, path + " line " + std::to_string(s.line) + ": [" + s.name + "] has no AccessType"};
    for (const auto &a : A)
        if (lower(it->second) == a.first) return (uint8_t)a.second;
    throw Fail{-MSID_DAQ_E_FORMAT, path + " line " + std::to_string(s.line) + ": [" + s.name + "] AccessType '" + it->second +
                                       "' is none of ro, wo, rw, rwr, rww, const"};
}

void put(char *dst, size_t cap, const std::string &s)
{
    std::snprintf(dst, cap, "%s", s.c_str());
}

msid_co_od_entry entry_of(const Section &s, uint16_t index, uint8_t sub, const std::string &path)
{
    msid_co_od_entry e{};
    e.index = index;
    e.sub = sub;
    e.type = (uint16_t)number(s, "datatype", path);
    e.access = access_of(s, path);
    const auto m = s.keys.find("pdomapping");
    e.pdo_mappable = m != s.keys.end() && std::strtoul(m->second.c_str(), nullptr, 0) != 0;
    const auto n = s.keys.find("parametername");
    put(e.name, sizeof e.name, n == s.keys.end() ? "" : n->second);
    const auto pv = s.keys.find("parametervalue"), dv = s.keys.find("defaultvalue");
    put(e.value, sizeof e.value, pv != s.keys.end() ? pv->second : dv != s.keys.end() ? dv->second : "");
    e.line = s.line;
    return e;
}

// an array's CompactSubObj=N: subindex 0 the count, 1..N of the array's type and access
void compact_entries(const Section &s, uint16_t index, const std::string &path, std::vector<msid_co_od_entry> &out)
{
    const unsigned long n = number(s, "compactsubobj", path);
    msid_co_od_entry count{};
    count.index = index;
    count.type = 0x0005;
    count.access = MSID_CO_RO;
    put(count.name, sizeof count.name, "Number of entries");
    put(count.value, sizeof count.value, std::to_string(n));
    count.line = s.line;
    out.push_back(count);
    for (unsigned long k = 1; k <= n && k <= 0xFE; k++) out.push_back(entry_of(s, index, (uint8_t)k, path));
}

std::vector<msid_co_od_entry> entries_of(const std::vector<Section> &sections, const std::string &path)
{
    std::map<uint16_t, unsigned long> object_type;  // index -> ObjectType of its [XXXX]
    std::vector<msid_co_od_entry> out;
    for (const Section &s : sections) {
        if (s.name.size() != 4 || !hex4(s.name, 0)) continue;
        const uint16_t index = (uint16_t)std::strtoul(s.name.c_str(), nullptr, 16);
        const auto ot = s.keys.find("objecttype");
        const unsigned long t = ot == s.keys.end() ? 0x7 : number(s, "objecttype", path);
        object_type[index] = t;
        if (t == 0x7 || t == 0x2) out.push_back(entry_of(s, index, 0, path));
        else if (t == 0x8 && s.keys.count("compactsubobj")) compact_entries(s, index, path, out);
        else if (t != 0x8 && t != 0x9)
            throw Fail{-MSID_DAQ_E_FORMAT, path + " line " + std::to_string(s.line) + ": [" + s.name + "] ObjectType " +
                                               ot->second + " is none of 0x2 (domain), 0x7 (var), 0x8 (array), 0x9 (record)"};
    }
    for (const Section &s : sections) {
        const std::string l = lower(s.name);
        if (l.size() < 8 || !hex4(l, 0) || l.compare(4, 3, "sub") != 0) continue;
        const uint16_t index = (uint16_t)std::strtoul(l.substr(0, 4).c_str(), nullptr, 16);
        char *end = nullptr;
        const unsigned long sub = std::strtoul(l.c_str() + 7, &end, 16);
        if (*end || sub > 0xFF)
            throw Fail{-MSID_DAQ_E_FORMAT, path + " line " + std::to_string(s.line) + ": [" + s.name + "] has no subindex 0..FF"};
        const auto it = object_type.find(index);
        if (it == object_type.end() || (it->second != 0x8 && it->second != 0x9)) continue;  // a variable's sub: skipped
        out.push_back(entry_of(s, index, (uint8_t)sub, path));
    }
    std::sort(out.begin(), out.end(), [](const msid_co_od_entry &a, const msid_co_od_entry &b) {
        return a.index != b.index ? a.index < b.index : a.sub < b.sub;
    });
    for (size_t i = 1; i < out.size(); i++)
        if (out[i].index == out[i - 1].index && out[i].sub == out[i - 1].sub) {
            char at[64];
            std::snprintf(at, sizeof at, " line %u: 0x%04X:%02X is described twice (also line %u)", (unsigned)out[i].line,
                          (unsigned)out[i].index, (unsigned)out[i].sub, (unsigned)out[i - 1].line);
            throw Fail{-MSID_DAQ_E_FORMAT, path + at};
        }
    return out;
}

}  // namespace

extern "C" int msid_co_eds_load(const char *path, msid_co_eds *eds, msid_co_od_entry *entries, uint32_t cap)
{
    if (!eds) return -MSID_DAQ_E_ARG;
    std::memset(eds, 0, sizeof *eds);
    if (!path || (!entries && cap)) {
        put(eds->err, sizeof eds->err, "no file or no memory for its entries");
        return -MSID_DAQ_E_ARG;
    }
    put(eds->source, sizeof eds->source, path);
    try {
        const std::vector<msid_co_od_entry> e = entries_of(read_sections(path), path);
        if (e.size() > cap) {
            std::snprintf(eds->err, sizeof eds->err, "%s has %zu entries: room for %u", path, e.size(), (unsigned)cap);
            return -MSID_DAQ_E_RANGE;
        }
        std::copy(e.begin(), e.end(), entries);
        eds->e = entries;
        eds->n = (uint32_t)e.size();
        return 0;
    } catch (const Fail &f) {
        put(eds->err, sizeof eds->err, f.msg);
        return f.rc;
    }
}
