// msid-device/1 (TOML) -> msid_devdesc (msid_devdesc_file.h). toml++ parses; this file walks the tables with
// the file's line numbers, refuses unknown keys and values of the wrong type, and resolves the DBC path
// against the description's folder. The checks of the description as a whole are msid_devdesc_check's.
#define TOML_HEADER_ONLY 1
#include <toml++/toml.h>

extern "C" {
#include "msid_daq/msid_devdesc_file.h"
#include "msid_daq/msid_mb_proto.h"
}

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <string>
#include <sys/stat.h>

namespace {

struct Fail {
    std::string msg;
};

struct Ctx {
    std::string src;
    [[noreturn]] void fail(const toml::node *n, const std::string &what) const
    {
        std::string at = src;
        if (n && n->source().begin.line) at += " line " + std::to_string(n->source().begin.line);
        throw Fail{at + ": " + what};
    }
};

uint32_t line_of(const toml::node &n) { return (uint32_t)n.source().begin.line; }

void copy(char *dst, size_t cap, const std::string &s, const Ctx &c, const toml::node *n, const char *key)
{
    if (s.size() + 1 > cap) c.fail(n, std::string(key) + " is longer than " + std::to_string(cap - 1) + " bytes");
    std::memcpy(dst, s.c_str(), s.size() + 1);
}

std::string get_string(const toml::node &n, const Ctx &c, const char *key)
{
    if (!n.is_string()) c.fail(&n, std::string(key) + " must be a string");
    return std::string(*n.value<std::string_view>());
}

double get_number(const toml::node &n, const Ctx &c, const char *key)
{
    if (n.is_integer()) return (double)*n.value<int64_t>();
    if (n.is_floating_point()) {
        const double v = *n.value<double>();
        if (!std::isfinite(v)) c.fail(&n, std::string(key) + " must be finite");
        return v;
    }
    c.fail(&n, std::string(key) + " must be a number");
}

uint32_t get_uint(const toml::node &n, const Ctx &c, const char *key, uint32_t lo, uint32_t hi)
{
    if (!n.is_integer()) c.fail(&n, std::string(key) + " must be an integer");
    const int64_t v = *n.value<int64_t>();
    if (v < lo || v > hi)
        c.fail(&n, std::string(key) + " must be " + std::to_string(lo) + ".." + std::to_string(hi) + " (got " +
                       std::to_string(v) + ")");
    return (uint32_t)v;
}

std::string known(std::initializer_list<const char *> keys)
{
    std::string s;
    for (const char *k : keys) s += (s.empty() ? "" : ", ") + std::string(k);
    return s;
}

// "holding:100" / "input:0": the table and the protocol's 0-based address.
void parse_register(const toml::node &n, const Ctx &c, msid_dev_chan &ch)
{
    const std::string s = get_string(n, c, "register");
    const size_t colon = s.find(':');
    const std::string t = colon == std::string::npos ? "" : s.substr(0, colon);
    if (t == "holding") ch.table = MSID_DEV_HOLDING;
    else if (t == "input") ch.table = MSID_DEV_INPUT;
    else {
        const bool modicon = s.size() == 5 && (s[0] == '3' || s[0] == '4') && s.find_first_not_of("0123456789") ==
                                                                               std::string::npos;
        c.fail(&n, "register = \"" + s + "\": write holding:N or input:N with N the protocol's 0-based address" +
                       (modicon ? std::string(" (\"") + s + "\" looks like a 1-based Modicon number: " +
                                      (s[0] == '4' ? "holding:" : "input:") + std::to_string(std::stoi(s.substr(1)) - 1) +
                                      ")"
                                : std::string()));
    }
    const std::string a = s.substr(colon + 1);
    char *e = nullptr;
    const unsigned long v = a.empty() ? 0 : std::strtoul(a.c_str(), &e, 0);
    if (a.empty() || *e || a[0] == '-' || v > 65535)
        c.fail(&n, "register = \"" + s + "\": the address must be 0..65535");
    ch.addr = (uint32_t)v;
}

uint32_t parse_type(const toml::node &n, const Ctx &c)
{
    const std::string s = get_string(n, c, "type");
    for (uint32_t t = MSID_DEV_INT16; t <= MSID_DEV_FLOAT64; ++t)
        if (s == msid_dev_type_name(t)) return t;
    c.fail(&n, "type = \"" + s + "\": must be int16, uint16, int32, uint32, float32 or float64");
}

uint32_t parse_word_order(const toml::node &n, const Ctx &c)
{
    const std::string s = get_string(n, c, "word_order");
    for (uint32_t w = 0; w < 4; ++w)
        if (s == msid_mb_word_order_name(w)) return w;
    c.fail(&n, "word_order = \"" + s + "\": must be ABCD, CDAB, BADC or DCBA");
}

uint32_t parse_role(const toml::node &n, const Ctx &c)
{
    const std::string s = get_string(n, c, "role");
    if (s == "input") return MSID_DEV_ROLE_INPUT;
    if (s == "output") return MSID_DEV_ROLE_OUTPUT;
    if (s == "reference") return MSID_DEV_ROLE_REFERENCE;
    if (s == "counter") return MSID_DEV_ROLE_COUNTER;
    c.fail(&n, "role = \"" + s + "\": must be input, output, reference or counter");
}

// "0x6071:00": a CANopen object dictionary entry, index and subindex in hex.
void parse_object(const toml::node &n, const Ctx &c, msid_dev_chan &ch)
{
    const std::string s = get_string(n, c, "object");
    const size_t colon = s.find(':');
    const std::string a = s.substr(0, colon), b = colon == std::string::npos ? "" : s.substr(colon + 1);
    char *ea = nullptr, *eb = nullptr;
    const unsigned long index = a.empty() ? 0 : std::strtoul(a.c_str(), &ea, 16);
    const unsigned long sub = b.empty() ? 0 : std::strtoul(b.c_str(), &eb, 16);
    if (a.empty() || b.empty() || *ea || *eb || a[0] == '-' || b[0] == '-' || index == 0 || index > 0xFFFF || sub > 0xFF)
        c.fail(&n, "object = \"" + s + "\": write INDEX:SUB in hex, e.g. \"0x6071:00\" (index 0x0001..0xFFFF, "
                   "subindex 0x00..0xFF)");
    ch.co_index = (uint16_t)index;
    ch.co_sub = (uint8_t)sub;
}

// One [[drive]] or [[measure]] table. reads_back names a drive channel: resolved after every table is read.
// named: a table without a name is refused (a preset's drive table may leave it to the preset).
void parse_channel(const toml::table &t, const Ctx &c, bool drive, msid_dev_chan &ch, std::string &reads_back,
                   bool named = true)
{
    msid_dev_chan_defaults(&ch);
    ch.line = line_of(t);
    bool has_type = false;
    for (const auto &[k, v] : t) {
        const std::string key(k.str());
        if (key == "name") copy(ch.name, sizeof ch.name, get_string(v, c, "name"), c, &v, "name");
        else if (key == "unit") copy(ch.unit, sizeof ch.unit, get_string(v, c, "unit"), c, &v, "unit");
        else if (key == "scale") ch.scale = get_number(v, c, "scale");
        else if (key == "offset") ch.offset = get_number(v, c, "offset");
        else if (key == "register") parse_register(v, c, ch);
        else if (key == "type") { ch.type = parse_type(v, c); has_type = true; }
        else if (key == "word_order") ch.word_order = parse_word_order(v, c);
        else if (key == "message") copy(ch.message, sizeof ch.message, get_string(v, c, "message"), c, &v, "message");
        else if (key == "signal") copy(ch.signal, sizeof ch.signal, get_string(v, c, "signal"), c, &v, "signal");
        else if (key == "object") parse_object(v, c, ch);
        else if (drive && key == "min") ch.min = get_number(v, c, "min");
        else if (drive && key == "max") ch.max = get_number(v, c, "max");
        else if (drive && key == "max_step") ch.max_step = get_number(v, c, "max_step");
        else if (drive && key == "safe") ch.safe = get_number(v, c, "safe");
        else if (drive && key == "operating_point") ch.op = get_number(v, c, "operating_point");
        else if (drive && key == "amplitude") ch.amplitude = get_number(v, c, "amplitude");
        else if (!drive && key == "role") ch.role = parse_role(v, c);
        else if (!drive && key == "reads_back") reads_back = get_string(v, c, "reads_back");
        else
            c.fail(&v, "unknown key '" + key + "' in a [[" + (drive ? "drive" : "measure") + "]] table (keys: " +
                           (drive ? known({"name", "unit", "register", "type", "word_order", "scale", "offset",
                                           "message", "signal", "object", "min", "max", "max_step", "safe",
                                           "operating_point", "amplitude"})
                                  : known({"name", "unit", "role", "register", "type", "word_order", "scale",
                                           "offset", "message", "signal", "object", "reads_back"})) +
                           ")");
    }
    if (!ch.name[0] && named)
        c.fail(&t, std::string("a [[") + (drive ? "drive" : "measure") + "]] table without a name");
    if (!drive && !ch.role) c.fail(&t, "measure channel '" + std::string(ch.name) + "' has no role");
    if (!has_type && (ch.table || ch.addr)) c.fail(&t, "channel '" + std::string(ch.name) + "' has a register but no type");
}

// A CiA 402 preset: the mode it runs and the objects it maps (docs/devices.md, CANopen drives).
struct PresetChan {
    const char *name;
    uint16_t index;
    uint32_t type, quantity, role;
};
struct Preset {
    const char *key;
    uint32_t mode;
    PresetChan drive;
    uint32_t closed_loop;   // msid_devdesc.co_closed_loop: 0 none, 1 the velocity loop, 2 the torque loop
};
const Preset PRESETS[] = {
    {"cst", 10, {"Target torque", 0x6071, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, 0}, 0},
    {"csv", 9, {"Target velocity", 0x60FF, MSID_DEV_INT32, MSID_DEV_CO_VELOCITY, 0}, 0},
    {"csp", 8, {"Target position", 0x607A, MSID_DEV_INT32, MSID_DEV_CO_POSITION, 0}, 0},
    {"csv-loop", 9, {"Target velocity", 0x60FF, MSID_DEV_INT32, MSID_DEV_CO_VELOCITY, 0}, 1},
    {"csv-torque-loop", 9, {"Torque offset", 0x60B2, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, 0}, 2},
};
// What every preset reads each SYNC: the demand the drive applied (the FRF's input) and the actual values,
// packed as TPDO1 (8 bytes: 0x6074, 0x6077, 0x606C) and TPDO2 (0x6064).
const PresetChan PRESET_MEASURE[] = {
    {"Torque demand", 0x6074, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, MSID_DEV_ROLE_INPUT},
    {"Torque actual", 0x6077, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, MSID_DEV_ROLE_OUTPUT},
    {"Velocity actual", 0x606C, MSID_DEV_INT32, MSID_DEV_CO_VELOCITY, MSID_DEV_ROLE_OUTPUT},
    {"Position actual", 0x6064, MSID_DEV_INT32, MSID_DEV_CO_POSITION, MSID_DEV_ROLE_OUTPUT},
};
// The closed-loop preset reads the velocity target the drive applied on that SYNC beside them (the reference:
// the FRF's input) and the demand as an output: TPDO1 (0x60FF, 0x6074, 0x6077), TPDO2 (0x606C, 0x6064).
const PresetChan PRESET_LOOP_MEASURE[] = {
    {"Velocity reference", 0x60FF, MSID_DEV_INT32, MSID_DEV_CO_VELOCITY, MSID_DEV_ROLE_INPUT},
    {"Torque demand", 0x6074, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, MSID_DEV_ROLE_OUTPUT},
    {"Torque actual", 0x6077, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, MSID_DEV_ROLE_OUTPUT},
    {"Velocity actual", 0x606C, MSID_DEV_INT32, MSID_DEV_CO_VELOCITY, MSID_DEV_ROLE_OUTPUT},
    {"Position actual", 0x6064, MSID_DEV_INT32, MSID_DEV_CO_POSITION, MSID_DEV_ROLE_OUTPUT},
};
// The torque-loop preset reads the torque offset the drive added on that SYNC (the reference) and the demand as
// an output: TPDO1 (0x60B2, 0x6074, 0x6077: 6 bytes), TPDO2 (0x606C, 0x6064).
const PresetChan PRESET_TORQUE_LOOP_MEASURE[] = {
    {"Torque reference", 0x60B2, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, MSID_DEV_ROLE_INPUT},
    {"Torque demand", 0x6074, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, MSID_DEV_ROLE_OUTPUT},
    {"Torque actual", 0x6077, MSID_DEV_INT16, MSID_DEV_CO_TORQUE, MSID_DEV_ROLE_OUTPUT},
    {"Velocity actual", 0x606C, MSID_DEV_INT32, MSID_DEV_CO_VELOCITY, MSID_DEV_ROLE_OUTPUT},
    {"Position actual", 0x6064, MSID_DEV_INT32, MSID_DEV_CO_POSITION, MSID_DEV_ROLE_OUTPUT},
};

// The preset's measure channels and their count.
const PresetChan *preset_measure(const Preset &p, uint32_t &n)
{
    if (p.closed_loop == 1) {
        n = sizeof PRESET_LOOP_MEASURE / sizeof PRESET_LOOP_MEASURE[0];
        return PRESET_LOOP_MEASURE;
    }
    if (p.closed_loop == 2) {
        n = sizeof PRESET_TORQUE_LOOP_MEASURE / sizeof PRESET_TORQUE_LOOP_MEASURE[0];
        return PRESET_TORQUE_LOOP_MEASURE;
    }
    n = sizeof PRESET_MEASURE / sizeof PRESET_MEASURE[0];
    return PRESET_MEASURE;
}

void fill_preset_chan(msid_dev_chan &ch, const PresetChan &p)
{
    if (!ch.name[0]) std::snprintf(ch.name, sizeof ch.name, "%s", p.name);
    ch.co_index = p.index;
    ch.co_sub = 0;
    ch.type = p.type;
    ch.co_quantity = (uint8_t)p.quantity;
    if (p.role) ch.role = p.role;
}

// The preset's channels: the description's one [[drive]] table gives the target's limits, its measure channels
// come first and the description's own [[measure]] tables after them.
void apply_preset(const Preset &p, const Ctx &c, msid_devdesc &d, const toml::node *at)
{
    if (d.n_drive != 1)
        c.fail(at, std::string("preset = \"") + p.key + "\" takes one [[drive]] table: the limits of " + p.drive.name +
                       " (safe, min, max, max_step, amplitude, operating_point); got " + std::to_string(d.n_drive));
    msid_dev_chan &dr = d.drive[0];
    if (dr.co_index || dr.type || dr.scale != 1.0 || dr.offset != 0.0)
        c.fail(at, std::string("preset = \"") + p.key + "\": the [[drive]] table (line " + std::to_string(dr.line) +
                       ") gives the limits only; object, type, scale and offset are the preset's (" + p.drive.name +
                       ", 0x" + [&] { char b[8]; std::snprintf(b, sizeof b, "%04X", p.drive.index); return std::string(b); }() +
                       ":00); leave out preset to map the objects yourself");
    fill_preset_chan(dr, p.drive);
    uint32_t n_pre = 0;
    const PresetChan *pm = preset_measure(p, n_pre);
    const uint32_t n_own = d.n_measure;
    if (n_own + n_pre > MSID_DEV_MAX_MEASURE) c.fail(at, "too many [[measure]] channels beside the preset's");
    for (uint32_t i = n_own; i-- > 0;) d.measure[i + n_pre] = d.measure[i];
    for (uint32_t i = 0; i < n_pre; ++i) {
        msid_dev_chan &m = d.measure[i];
        msid_dev_chan_defaults(&m);
        m.line = dr.line;
        fill_preset_chan(m, pm[i]);
    }
    d.n_measure = n_own + n_pre;
    d.co_preset = d.co_mode = p.mode;
    d.co_closed_loop = p.closed_loop;
}

// The scale and unit of the channels whose raw value counts a quantity of CiA 402.
void resolve_quantities(msid_devdesc &d)
{
    for (uint32_t i = 0; i < d.n_drive + d.n_measure; ++i) {
        msid_dev_chan &ch = i < d.n_drive ? d.drive[i] : d.measure[i - d.n_drive];
        const char *unit = nullptr;
        switch (ch.co_quantity) {
        case MSID_DEV_CO_TORQUE:
            ch.scale = (std::isnan(d.rated_torque) ? 1.0 : d.rated_torque) * 1e-3;   // again by the link from 0x6076
            unit = "N m";
            break;
        case MSID_DEV_CO_VELOCITY: ch.scale = d.velocity_scale; unit = d.velocity_unit; break;
        case MSID_DEV_CO_POSITION: ch.scale = d.position_scale; unit = d.position_unit; break;
        default: continue;
        }
        if (!ch.unit[0]) std::snprintf(ch.unit, sizeof ch.unit, "%s", unit);
    }
}

// The folder of the description, for a relative DBC path.
std::string folder_of(const std::string &path)
{
    const size_t s = path.rfind('/');
    return s == std::string::npos ? std::string() : path.substr(0, s + 1);
}

void parse_top(const toml::table &root, const Ctx &c, msid_devdesc &d)
{
    const toml::node *fmt = root.get("format");
    if (!fmt) c.fail(nullptr, "no format key: the first line of a description is format = \"msid-device/1\"");
    if (get_string(*fmt, c, "format") != "msid-device/1")
        c.fail(fmt, "format = \"" + get_string(*fmt, c, "format") + "\": msid reads msid-device/1");
    const toml::node *tr = root.get("transport");
    if (!tr) c.fail(nullptr, "no transport key (\"modbus\", \"can\" or \"canopen\")");
    const std::string t = get_string(*tr, c, "transport");
    if (t == "modbus") d.transport = MSID_DEV_MODBUS;
    else if (t == "can") d.transport = MSID_DEV_CAN;
    else if (t == "canopen") d.transport = MSID_DEV_CANOPEN;
    else c.fail(tr, "transport = \"" + t + "\": must be \"modbus\", \"can\" or \"canopen\"");
    const bool co = d.transport == MSID_DEV_CANOPEN;
    const toml::node *preset_at = root.get("preset");
    const Preset *preset = nullptr;
    if (preset_at) {
        if (!co) c.fail(preset_at, "preset goes with transport = \"canopen\" (a CiA 402 drive)");
        const std::string ps = get_string(*preset_at, c, "preset");
        for (const Preset &p : PRESETS)
            if (ps == p.key) preset = &p;
        if (!preset)
            c.fail(preset_at, "preset = \"" + ps + "\": must be \"cst\", \"csv\", \"csp\", \"csv-loop\" or "
                              "\"csv-torque-loop\"");
    }
    std::string drive_refs[MSID_DEV_MAX_MEASURE];
    for (const auto &[k, v] : root) {
        const std::string key(k.str());
        if (key == "format" || key == "transport" || key == "preset") continue;
        // the CANopen keys
        if (co && key == "mode") {
            const std::string m = get_string(v, c, "mode");
            d.co_mode = m == "cst" ? 10 : m == "csv" ? 9 : m == "csp" ? 8 : 0;
            if (!d.co_mode) c.fail(&v, "mode = \"" + m + "\": must be \"cst\", \"csv\" or \"csp\"");
            if (preset && preset->mode != d.co_mode)
                c.fail(&v, "mode = \"" + m + "\" contradicts preset = \"" + preset->key + "\" (the preset sets the mode)");
            continue;
        }
        if (co && key == "rated_torque") {
            d.rated_torque = get_number(v, c, "rated_torque");
            if (!(d.rated_torque > 0)) c.fail(&v, "rated_torque must be positive (N m)");
            continue;
        }
        if (co && (key == "velocity_scale" || key == "position_scale")) {
            const double x = get_number(v, c, key.c_str());
            if (x == 0) c.fail(&v, key + " must be non-zero (physical units per count)");
            (key[0] == 'v' ? d.velocity_scale : d.position_scale) = x;
            continue;
        }
        if (co && (key == "velocity_unit" || key == "position_unit")) {
            char *dst = key[0] == 'v' ? d.velocity_unit : d.position_unit;
            copy(dst, MSID_DEV_UNIT_CAP, get_string(v, c, key.c_str()), c, &v, key.c_str());
            continue;
        }
        if (co && key == "hold_velocity") {
            if (!preset || preset->closed_loop != 2)
                c.fail(&v, "hold_velocity goes with preset = \"csv-torque-loop\" (the velocity the drive holds while "
                           "its torque loop is excited)");
            d.co_hold_velocity = get_number(v, c, "hold_velocity");
            continue;
        }
        if (co && key == "restore_pdo") {
            if (!v.is_boolean()) c.fail(&v, "restore_pdo must be true or false");
            d.restore_pdo = *v.value<bool>() ? 1 : 0;
            continue;
        }
        if (co && key == "eds") {
            std::string p = get_string(v, c, "eds");
            if (p.empty()) c.fail(&v, "eds must name the node's EDS or DCF file");
            if (p[0] != '/') p = folder_of(c.src) + p;
            copy(d.co_eds, sizeof d.co_eds, p, c, &v, "eds");
            continue;
        }
        if (co && key == "sync") {
            const std::string s = get_string(v, c, "sync");
            if (s == "tick") d.co_sync = MSID_DEV_SYNC_TICK;
            else if (s == "kernel") d.co_sync = MSID_DEV_SYNC_KERNEL;
            else c.fail(&v, "sync = \"" + s + "\": must be \"tick\" (msid's tick sends each SYNC after its RPDO) or "
                            "\"kernel\" (the kernel's timer sends the SYNC)");
            continue;
        }
        if (co && key == "heartbeat_ms") {
            d.heartbeat_ms = get_uint(v, c, "heartbeat_ms", 0, 65535);
            continue;
        }
        if (co && (key == "unit" || key == "fc23" || key == "clock" || key == "cycle_hz" || key == "dbc"))
            c.fail(&v, "key '" + key + "' is not for transport = \"canopen\" (the node id is the URI's ?node=N; "
                           "msid's SYNC is the node's clock)");
        if (key == "name") copy(d.name, sizeof d.name, get_string(v, c, "name"), c, &v, "name");
        else if (key == "unit") d.unit = get_uint(v, c, "unit", 0, 247);
        else if (key == "fade_periods") d.fade_periods = get_uint(v, c, "fade_periods", 0, 8);
        else if (key == "cycle_hz") {
            d.cycle_hz = get_number(v, c, "cycle_hz");
            if (!(d.cycle_hz > 0)) c.fail(&v, "cycle_hz must be positive");
        } else if (key == "fc23") {
            if (v.is_boolean()) d.fc23 = *v.value<bool>() ? 1 : 0;
            else if (v.is_string() && get_string(v, c, "fc23") == "auto") d.fc23 = -1;
            else c.fail(&v, "fc23 must be true, false or \"auto\"");
        } else if (key == "clock") {
            const std::string s = get_string(v, c, "clock");
            if (s == "host") d.clock = MSID_DEV_CLOCK_HOST;
            else if (s == "device") d.clock = MSID_DEV_CLOCK_DEVICE;
            else c.fail(&v, "clock = \"" + s + "\": must be \"host\" or \"device\"");
        } else if (key == "dbc") {
            std::string p = get_string(v, c, "dbc");
            if (!p.empty() && p[0] != '/') p = folder_of(c.src) + p;
            copy(d.dbc, sizeof d.dbc, p, c, &v, "dbc");
        } else if (key == "drive" || key == "measure") {
            const toml::array *a = v.as_array();
            if (!a || !a->is_array_of_tables()) c.fail(&v, key + " must be an array of tables: [[" + key + "]]");
            const bool drive = key == "drive";
            for (const toml::node &e : *a) {
                uint32_t &n = drive ? d.n_drive : d.n_measure;
                if (n >= (drive ? MSID_DEV_MAX_DRIVE : MSID_DEV_MAX_MEASURE))
                    c.fail(&e, "more than " + std::to_string(drive ? MSID_DEV_MAX_DRIVE : MSID_DEV_MAX_MEASURE) +
                                   " [[" + key + "]] channels");
                std::string ref;
                parse_channel(*e.as_table(), c, drive, drive ? d.drive[n] : d.measure[n], ref, !(drive && preset));
                if (!drive) drive_refs[n] = ref;
                ++n;
            }
        } else {
            c.fail(&v, "unknown key '" + key + "' (keys: " +
                           (co ? known({"format", "transport", "name", "preset", "mode", "rated_torque",
                                        "velocity_scale", "velocity_unit", "position_scale", "position_unit",
                                        "hold_velocity", "restore_pdo", "heartbeat_ms", "sync", "eds", "fade_periods", "[[drive]]", "[[measure]]"})
                               : known({"format", "transport", "name", "unit", "fc23", "fade_periods", "clock",
                                        "cycle_hz", "dbc", "[[drive]]", "[[measure]]"})) +
                           ")");
        }
    }
    if (preset) {
        apply_preset(*preset, c, d, preset_at);
        // the description's own measure channels moved behind the preset's, and their reads_back with them
        uint32_t n_pre = 0;
        preset_measure(*preset, n_pre);
        for (uint32_t i = d.n_measure; i-- > n_pre;) drive_refs[i] = drive_refs[i - n_pre];
        for (uint32_t i = 0; i < n_pre; ++i) drive_refs[i].clear();
    }
    if (co) resolve_quantities(d);
    for (uint32_t i = 0; i < d.n_measure; ++i) {
        if (drive_refs[i].empty()) continue;
        msid_dev_chan &m = d.measure[i];
        if (m.role != MSID_DEV_ROLE_INPUT)
            throw Fail{c.src + " line " + std::to_string(m.line) + ": reads_back goes with role = \"input\" ('" +
                       m.name + "')"};
        for (uint32_t j = 0; j < d.n_drive; ++j)
            if (drive_refs[i] == d.drive[j].name) m.reads_back = (int32_t)j;
        if (m.reads_back < 0)
            throw Fail{c.src + " line " + std::to_string(m.line) + ": reads_back = \"" + drive_refs[i] +
                       "\" names no drive channel"};
    }
}

void put_err(char *err, size_t cap, const std::string &m)
{
    if (err && cap) std::snprintf(err, cap, "%s", m.c_str());
}

}  // namespace

extern "C" int msid_devdesc_parse(const char *text, size_t len, const char *source, msid_devdesc *d, char *err,
                                  size_t cap)
{
    msid_devdesc_defaults(d);
    Ctx c{source ? source : "<description>"};
    try {
        if (c.src.size() + 1 > sizeof d->source) throw Fail{"the description's path is too long"};
        std::memcpy(d->source, c.src.c_str(), c.src.size() + 1);
        toml::table root;
        try {
            root = toml::parse(std::string_view(text, len), std::string_view(c.src));
        } catch (const toml::parse_error &e) {
            throw Fail{c.src + " line " + std::to_string(e.source().begin.line) + ", column " +
                       std::to_string(e.source().begin.column) + ": " + std::string(e.description())};
        }
        parse_top(root, c, *d);
    } catch (const Fail &f) {
        put_err(err, cap, f.msg);
        return -1;
    } catch (const std::exception &e) {
        put_err(err, cap, c.src + ": " + e.what());
        return -1;
    }
    return msid_devdesc_check(d, err, cap);
}

extern "C" int msid_devdesc_load(const char *path, msid_devdesc *d, char *err, size_t cap)
{
    struct stat st;
    if (::stat(path, &st) == 0 && !S_ISREG(st.st_mode)) {
        put_err(err, cap, std::string("the device description '") + path + "' is not a file");
        return -1;
    }
    std::ifstream f(path, std::ios::binary);
    if (!f) {
        put_err(err, cap, std::string("cannot read the device description '") + path + "': " + std::strerror(errno));
        return -1;
    }
    std::ostringstream ss;
    ss << f.rdbuf();
    if (f.bad()) {
        put_err(err, cap, std::string("cannot read the device description '") + path + "'");
        return -1;
    }
    const std::string text = ss.str();
    if (text.size() > (1u << 20)) {
        put_err(err, cap, std::string("'") + path + "' is larger than 1 MiB: not a device description");
        return -1;
    }
    return msid_devdesc_parse(text.data(), text.size(), path, d, err, cap);
}
