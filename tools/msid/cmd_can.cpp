// msid can: measure an FRF over SocketCAN from an msid-can/1 device, and
// replay a candump log through the same decoder (bit-identical FRF).
#include "commands.hpp"
#include "host_libs.hpp"
#include "measure.hpp"
#include "msid_can_acq.hpp"
#include "msid_can_replay.hpp"

extern "C" {
#include "msid_daq/msid_can_session.h"
#include "msid_daq/msid_params.h"
#include "msid_daq/msid_candump.h"
#include "msid_daq/msid_socketcan.h"
}

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <unistd.h>

namespace msidcli {

static const char *CAN_HELP =
    "usage: msid can measure --iface IF --design design.json -o frf.json [options]\n"
    "       msid can replay --log run.log [--design design.json] [--session N | --since T --until T] -o frf.json\n"
    "       msid can replay --log run.log --list\n"
    "       msid can decode --dbc FILE.dbc run.log -o signals.csv\n"
    "\n"
    "measure: upload the design to an msid-can/1 device (as parameters), run every experiment,\n"
    "decode the sample stream and estimate the FRF with its covariance (msid-frf/1, with an\n"
    "`acquisition` block of counters). replay: the same from a candump .log file (candump -l,\n"
    "or --log of measure); same frames give a bit-identical FRF.\n"
    "\n"
    "  --iface IF          SocketCAN interface (vcan0, can0)\n"
    "  --base ID           device base identifier, a multiple of 0x80 (default 0x200)\n"
    "  --design FILE       msid-design/1 (replay: checked against the design in the log)\n"
    "  --periods K         periods per experiment (default: the design's, else 8)\n"
    "  --rate HZ           device sample rate (default 0: as fast as possible); sets fs_hz\n"
    "  --fd                CAN FD 64-byte sample frames (interface MTU 72)\n"
    "  --encoding E        int16 (scaled, default) or float32 channel values\n"
    "  --scale S           value of one int16 step (default 0.001)\n"
    "  --bitrate BPS       nominal bit rate: refuse a --rate the bus cannot carry (0: virtual bus)\n"
    "  --data-bitrate BPS  CAN FD data-phase bit rate (default: --bitrate)\n"
    "  --window N          reorder window in samples (default 16)\n"
    "  --rcvbuf BYTES      socket receive buffer (above net.core.rmem_max needs CAP_NET_ADMIN)\n"
    "  --timeout S         give up when the device is silent this long (default 10)\n"
    "  --log FILE          also record every frame as a candump .log\n"
    "  --quiet             no progress (stderr: one rewritten line on a terminal, else one line per event)\n"
    "  --skip-periods K, --transient flag|drop|off, --alpha A, --detect-lines B,..: as in msid frf\n"
    "  --on-device         the device estimates (msid-can/1 extension estimate/1): no sample frames, the host\n"
    "                      reads each line's G, covariances and dof; --stream-check FILE: the device also\n"
    "                      streams, FILE gets the host's FRF and both must agree bit for bit\n"
    "\n"
    "measure runs the CAN session of `msid measure --device can://IF` (docs/measure.md): Ctrl-C (SIGINT or\n"
    "SIGTERM) stops cleanly, -o gets the FRF of the complete periods marked \"complete\": false, exit 130.\n"
    "\n"
    "replay: a session is one design upload (CFG BEGIN..COMMIT) and the experiments run with it\n"
    "(RUNNING .. DONE) up to the next upload; the summary says how many the log holds. Sessions of one\n"
    "design are pooled; a log of several designs needs a selection:\n"
    "  --list              one line per session (times, design CRC, runs, sample frames), nothing written\n"
    "  --session N         replay session N only (1 = the first)\n"
    "  --since T, --until T  the sessions that start at or after T and end at or before T (timestamps\n"
    "                      as the log writes them, seconds since the epoch: 1700000000.123456)\n"
    "\n"
    "decode: every frame of a candump .log that the DBC file describes, one CSV row per signal it carries\n"
    "(time,message,signal,value: the log's timestamp in seconds, physical values that read back bit for\n"
    "bit; multiplexed signals only where present). Frames of identifiers not in the DBC, error frames and\n"
    "frames shorter than their message are counted on stderr; the file is written whole or not at all.\n";

static std::string hex(uint32_t v) { return fmt("0x%X", v); }

static uint32_t parse_base(const Args &a)
{
    uint64_t b = MSID_CAN_DEFAULT_BASE;
    if (a.has("base")) {
        const std::string v = a.get("base");
        char *end = nullptr;
        errno = 0;
        b = std::strtoull(v.c_str(), &end, 0);   // decimal or 0x hex
        if (v.empty() || *end || errno || v[0] == '-') throw UsageError("--base: '" + v + "' is not an identifier");
    }
    if (b % 0x80 || b > 0x780) throw UsageError("--base must be a multiple of 0x80 up to 0x780 (got " + hex((uint32_t)b) + ")");
    return (uint32_t)b;
}

static uint32_t parse_window(const Args &a)
{
    const uint32_t w = a.u32("window", 16);
    if (w < 1 || w > MSID_CAN_MAX_WINDOW) throw UsageError(fmt("--window must be 1..%u", MSID_CAN_MAX_WINDOW));
    return w;
}


// ---- measure: parse options -> open transport -> session -> estimation job ----

static int cmd_measure(int argc, char **argv)
{
    for (int i = 3; i < argc; ++i) if (!std::strcmp(argv[i], "--on-device")) return cmd_can_ondevice(argc, argv);
    Args a(argc, argv, 3,
           {"iface", "base", "design", "periods", "rate", "encoding", "scale", "bitrate", "data-bitrate", "window",
            "rcvbuf", "timeout", "log", "skip-periods", "transient", "alpha", "detect-lines", "output"},
           {"fd", "quiet"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    const std::string out = a.require("output");
    CanLink l;
    l.iface = a.require("iface");
    l.base = parse_base(a);
    l.window = parse_window(a);
    MeasurePlan plan;
    plan.D = read_design_file(a.require("design"));
    l.fd = a.has("fd");
    plan.sf.fd = l.fd ? 1 : 0;
    const std::string enc = a.get("encoding", "int16");
    if (enc == "int16") l.encoding = MSID_CAN_ENC_S16;
    else if (enc == "float32") l.encoding = MSID_CAN_ENC_F32;
    else throw UsageError("--encoding must be int16 or float32 (got '" + enc + "')");
    plan.sf.encoding = l.encoding;
    parse_measure_options(a, *plan.D, plan.sf, plan.rq);
    l.bitrate = a.f64("bitrate", 0);
    l.data_bitrate = a.f64("data-bitrate", l.bitrate);
    if (l.bitrate < 0 || l.data_bitrate < 0) throw UsageError("--bitrate must be >= 0");
    l.rcvbuf = a.has("rcvbuf") ? (int)parse_u32(a.get("rcvbuf"), "--rcvbuf") : 0;
    plan.timeout = a.f64("timeout", 10.0);
    if (!(plan.timeout > 0 && plan.timeout <= 86400)) throw UsageError("--timeout must be positive (at most 86400 s)");
    l.log = a.get("log");
    Progress pg(stderr, is_terminal(stderr), a.has("quiet"), "msid can");
    StopOnSignal guard;   // Ctrl-C ends the acquisition, the FRF of the complete periods is kept
    MeasureResult R = measure_can(l, [&](uint32_t, MeasurePlan &P) { P = std::move(plan); }, pg);
    return write_measure_result(R, out, "can");
}

// ---- replay: options -> msidacq::replay_can_log (tools/acquire/msid_can_replay.hpp) -> file ----

static int cmd_replay(int argc, char **argv)
{
    Args a(argc, argv, 3,
           {"log", "design", "base", "window", "skip-periods", "transient", "alpha", "detect-lines", "output",
            "session", "since", "until"},
           {"list"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    const bool list = a.has("list");
    const std::string out = list ? a.get("output") : a.require("output");
    msidacq::ReplayRequest r;
    r.log = a.require("log");
    r.base = parse_base(a);
    r.window = parse_window(a);
    if (a.has("session") && (a.has("since") || a.has("until")))
        throw UsageError("--session and --since/--until select in different ways: give one of them");
    r.session = a.has("session") ? parse_u32(a.get("session"), "--session") : 0;
    if (a.has("session") && r.session == 0) throw UsageError("--session counts from 1");
    r.since = a.has("since") ? msidacq::parse_log_time(a.get("since"), "--since") : 0;
    r.until = a.has("until") ? msidacq::parse_log_time(a.get("until"), "--until") : UINT64_MAX;
    if (r.since > r.until) throw UsageError("--since is after --until");
    if (list) {
        const msidacq::LogScan sc = msidacq::scan_can_log(r.log, r.base);
        std::printf("%s: %zu session(s) at base %s, %llu frames\n", r.log.c_str(), sc.sessions.size(), hex(r.base).c_str(),
                    (unsigned long long)sc.frames);
        for (size_t i = 0; i < sc.sessions.size(); ++i)
            std::printf("  %s\n", msidacq::session_line(sc.sessions[i], i).c_str());
        return 0;
    }
    if (a.has("design")) {
        r.design = read_design_file(a.get("design"));
        r.design_name = a.get("design");
    }
    r.options = [&](FrfRequest &rq) { parse_estimate_options(a, rq); };
    msidacq::ReplayResult R = msidacq::replay_can_log(r);
    msidjob::write_outcome(out, R.o);
    for (const auto &n : R.o.notes) std::fprintf(stderr, "msid can: note: %s\n", n.c_str());
    std::printf("wrote %s: %s\n", out.c_str(), R.summary.c_str());
    return 0;
}

// msid bench can: boot the vcan VM and run tests/vcan/bench_can.py in it.
int cmd_bench_can(int argc, char **argv)
{
    static const char *BENCH_HELP =
        "usage: msid bench can [--quick] [--results DIR]\n"
        "Boots Debian's kernel under qemu with vcan (tests/vcan/vm.py) and measures the highest\n"
        "sustained sample rate with zero loss for 4 channels on classic CAN and 16 on CAN FD,\n"
        "beside cangen -> candump frames/s on the same vcan. See docs/benchmarks.md.\n";
    const Args a(argc, argv, 3, BENCH_HELP, {"results"}, {"quick"});
    if (!a.positional().empty()) throw UsageError("msid bench can: unexpected argument " + a.positional()[0]);
    const bool quick = a.has("quick");
    const std::string results = a.get("results");
    const std::string src = MSID_SOURCE_DIR;
    std::vector<std::string> args = {"python3", src + "/tests/vcan/vm.py"};
    if (!results.empty()) { args.push_back("--results"); args.push_back(results); }
    args.insert(args.end(), {"--", "python3", src + "/tests/vcan/bench_can.py"});
    if (quick) args.push_back("--quick");
    return exec_with_build(args);
}

int cmd_can(int argc, char **argv)
{
    return dispatch_subcommand(argc, argv, "can", CAN_HELP, {{"measure", cmd_measure}, {"replay", cmd_replay}, {"decode", cmd_can_decode}});
}

}  // namespace msidcli
