// msid can decode: a candump .log decoded with a DBC file, as long-form CSV (time,message,signal,value).
#include "commands.hpp"
#include "host_libs.hpp"
#include "msid_candump_dbc.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>

namespace msidcli {

namespace {

// What the log held besides the values written.
struct DecodeCounts {
    uint64_t frames = 0, decoded = 0, values = 0;
    uint64_t unknown = 0;                  // frames of identifiers the DBC does not define
    std::map<uint32_t, uint64_t> unknown_ids;
    uint64_t error_frames = 0, remote = 0;
    uint64_t short_frames = 0, not_decoded = 0;   // frames shorter than their message, signals left out
    uint64_t nonfinite = 0;                // float values NaN or infinite (not written)
};

// "1700000000.123456": the log's timestamp in seconds, as candump writes it.
void put_time(std::string &out, uint64_t t_ns)
{
    char b[48];
    const int n = std::snprintf(b, sizeof b, "%llu.%06llu", (unsigned long long)(t_ns / 1000000000ull),
                                (unsigned long long)(t_ns % 1000000000ull / 1000ull));
    out.append(b, (size_t)n);
}

// One frame: a row per signal it carries (multiplexed signals only when present).
void decode_frame(const msid_dbc &db, const msid_can_frame &f, std::string &out, DecodeCounts &n)
{
    const msid_dbc_message *m = msid_dbc_message_by_id(&db, f.id & (MSID_CAN_EFF_FLAG | 0x1FFFFFFFu));
    if (!m) {
        ++n.unknown;
        ++n.unknown_ids[f.id & (MSID_CAN_EFF_FLAG | 0x1FFFFFFFu)];
        return;
    }
    ++n.decoded;
    if (f.len < m->dlc) ++n.short_frames;
    for (uint32_t k = 0; k < m->n_signals; ++k) {
        const msid_dbc_signal &s = db.signals[m->first_signal + k];
        const int pr = msid_dbc_present(&db, &s, f.data, f.len);
        double v;
        if (pr == 0) continue;
        if (pr < 0 || msid_dbc_decode(&s, f.data, f.len, &v) != 0) {
            ++n.not_decoded;   // the frame ends before the signal (or its multiplexer)
            continue;
        }
        if (!std::isfinite(v)) {
            ++n.nonfinite;
            continue;
        }
        put_time(out, f.t_ns);
        out += ',';
        out += m->name;
        out += ',';
        out += s.name;
        out += ',';
        char b[32];
        const auto r = std::to_chars(b, b + sizeof b, v);   // shortest text that reads back bit for bit
        out.append(b, r.ptr);
        out += '\n';
        ++n.values;
    }
}

// The stderr line of what was not written, "" when everything was.
std::string problems(const DecodeCounts &n, const std::string &dbc)
{
    std::vector<std::string> p;
    if (n.unknown) {
        std::string ids;
        size_t k = 0;
        for (const auto &x : n.unknown_ids) {
            if (k++ == 6) {
                ids += ", ...";
                break;
            }
            ids += fmt("%s%s0x%X", k > 1 ? ", " : "", (x.first & MSID_CAN_EFF_FLAG) ? "ext " : "",
                       (unsigned)(x.first & 0x1FFFFFFFu));
        }
        p.push_back(fmt("%llu frame(s) of %zu identifier(s) not in '%s' (%s)", (unsigned long long)n.unknown,
                        n.unknown_ids.size(), dbc.c_str(), ids.c_str()));
    }
    if (n.error_frames) p.push_back(fmt("%llu error frame(s)", (unsigned long long)n.error_frames));
    if (n.remote) p.push_back(fmt("%llu remote request(s)", (unsigned long long)n.remote));
    if (n.short_frames)
        p.push_back(fmt("%llu frame(s) shorter than their message's length, %llu signal value(s) in them not decoded",
                        (unsigned long long)n.short_frames, (unsigned long long)n.not_decoded));
    if (n.nonfinite) p.push_back(fmt("%llu NaN or infinite float value(s) not written", (unsigned long long)n.nonfinite));
    std::string s;
    for (size_t k = 0; k < p.size(); ++k) s += (k ? "; " : "") + p[k];
    return s;
}

}  // namespace

// options -> the DBC and the log -> one CSV file, written atomically
int cmd_can_decode(int argc, char **argv)
{
    Args a(argc, argv, 3, {"dbc", "output"}, {});
    if (a.positional().size() != 1)
        throw UsageError(a.positional().empty() ? "give the candump .log to decode (msid can decode --dbc FILE LOG -o out.csv)"
                                                : "one log at a time (unexpected argument '" + a.positional()[1] + "')");
    const std::string dbc_path = a.require("dbc"), log = a.positional()[0], out = a.require("output");
    const msidrec::DbcFile dbc(dbc_path);
    std::string csv = "time,message,signal,value\n";
    DecodeCounts n;
    msidrec::for_each_candump_frame(log, [&](const msid_can_frame &f, uint64_t) {
        ++n.frames;
        if (f.id & MSID_CAN_ERR_FLAG) ++n.error_frames;
        else if (f.id & MSID_CAN_RTR_FLAG) ++n.remote;
        else decode_frame(dbc.db(), f, csv, n);
        return true;
    });
    msidutil::write_file_atomic(out, csv, false);
    const std::string pr = problems(n, dbc_path);
    if (!pr.empty()) std::fprintf(stderr, "msid can: note: %s\n", pr.c_str());
    std::printf("wrote %s: %llu values from %llu of %llu frames\n", out.c_str(), (unsigned long long)n.values,
                (unsigned long long)n.decoded, (unsigned long long)n.frames);
    return 0;
}

}  // namespace msidcli
