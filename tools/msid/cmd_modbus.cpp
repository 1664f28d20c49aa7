// msid modbus: measure an FRF over Modbus TCP or RTU from an msid-modbus/1 device
// (docs/modbus-registers.md) through the shared FRF job; msid bench modbus.
#include "commands.hpp"
#include "host_libs.hpp"
#include "measure.hpp"

extern "C" {
#include "msid_daq/msid_mb_proto.h"
}

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <unistd.h>

namespace msidcli {

static const char *MODBUS_HELP =
    "usage: msid modbus measure (--tcp HOST:PORT | --rtu DEVICE [--baud N]) --design design.json -o frf.json [options]\n"
    "\n"
    "Upload the design to an msid-modbus/1 device as parameters (holding registers), run every\n"
    "experiment, poll the device's ring buffer (input registers) and estimate the FRF with its\n"
    "covariance (msid-frf/1 with an `acquisition` block of counters). docs/modbus-registers.md.\n"
    "\n"
    "  --tcp HOST:PORT         Modbus TCP\n"
    "  --rtu DEVICE            Modbus RTU on a serial port (or pty); --baud N (115200), --parity N|E|O (N),\n"
    "                          --data-bits 8, --stop-bits 1\n"
    "  --unit N                unit (slave) id (default 1)\n"
    "  --design FILE           msid-design/1\n"
    "  --periods K             periods per experiment (default: the design's, else 8)\n"
    "  --rate HZ               device sample rate (default 0: the device writes as fast as the host reads);\n"
    "                          refused when the link cannot carry it; sets fs_hz\n"
    "  --encoding E            int16 (scaled, default), int32 (scaled) or float32\n"
    "  --word-order W          ABCD (default), CDAB, BADC or DCBA\n"
    "  --scale S               value of one int16/int32 step (default 0.001)\n"
    "  --response-timeout MS   wait for a reply (default 200)   --byte-timeout MS  between bytes (default 50)\n"
    "  --retries N             attempts after the first (default 5; backoff 20 ms doubling, reconnect on timeout)\n"
    "  --max-regs N            registers per read, 1..125 (default 125)\n"
    "  --timeout S             give up when no new sample arrives this long (default 10)\n"
    "  --skip-periods K, --transient flag|drop|off, --alpha A, --detect-lines B,.., --dft auto|stream|fft: as in msid frf\n"
    "  --quiet                 no progress (stderr: one rewritten line on a terminal, else one line per event)\n"
    "  Ctrl-C (SIGINT/SIGTERM) stops cleanly: OUTPUT is the FRF of the complete periods, marked \"complete\": false,\n"
    "  exit status 130. The same session as `msid measure --device modbus-tcp://...` (docs/measure.md).\n"
    "  --on-device             the device estimates (msid-modbus/1 extension estimate/1): no sample stream, the\n"
    "                          host reads each line's G, covariances and dof; --stream-check FILE: the device also\n"
    "                          streams, FILE gets the host's FRF and both must agree bit for bit\n";

// The link options of `msid modbus measure` and its --on-device form (checked before anything is opened).
ModbusLink modbus_link_options(const Args &a)
{
    ModbusLink l;
    l.response_ms = a.u32("response-timeout", 200);
    l.byte_ms = a.u32("byte-timeout", 50);
    if (l.response_ms < 1 || l.response_ms > 60000 || l.byte_ms < 1 || l.byte_ms > 60000)
        throw UsageError("--response-timeout and --byte-timeout must be 1..60000 ms");
    l.retries = a.u32("retries", 5);
    if (l.retries < 1 || l.retries > 100) throw UsageError("--retries must be 1..100");
    l.max_regs = a.u32("max-regs", MSID_MB_MAX_READ);
    if (l.max_regs < 1 || l.max_regs > MSID_MB_MAX_READ) throw UsageError(fmt("--max-regs must be 1..%u", MSID_MB_MAX_READ));
    l.encoding = a.enum_index("encoding", "int16", {"int16", "int32", "float32"});
    l.word_order = a.enum_index("word-order", "ABCD", {"ABCD", "CDAB", "BADC", "DCBA"});
    l.unit = a.has("unit") ? parse_u32(a.get("unit"), "--unit") : 1;
    if (a.has("tcp") == a.has("rtu")) throw UsageError("give one of --tcp HOST:PORT and --rtu DEVICE");
    if (a.has("tcp")) {
        const std::string v = a.get("tcp");
        const size_t colon = v.rfind(':');
        if (colon == std::string::npos || colon == 0) throw UsageError("--tcp wants HOST:PORT (got '" + v + "')");
        l.host = v.substr(0, colon);
        l.port = parse_u32(v.substr(colon + 1), "--tcp port");
        if (l.port == 0 || l.port > 65535) throw UsageError("--tcp port must be 1..65535");
        if (l.unit > 255) throw UsageError("--unit must be 0..255 on TCP");
        l.name = "tcp:" + v;
    } else {
        l.rtu = true;
        l.device = a.get("rtu");
        l.baud = a.u32("baud", 115200);
        if (l.baud < 300 || l.baud > 4000000) throw UsageError("--baud must be 300..4000000");
        l.parity = "NEO"[a.enum_index("parity", "N", {"N", "E", "O"})];
        l.data_bits = 8 - a.enum_index("data-bits", "8", {"8", "7"});
        l.stop_bits = 1 + a.enum_index("stop-bits", "1", {"1", "2"});
        if (l.unit < 1 || l.unit > 247) throw UsageError("--unit must be 1..247 on RTU");
        l.name = "rtu:" + l.device;
    }
    return l;
}

// Options -> link -> the Modbus session of `msid measure` (measure_modbus.cpp): the same code,
// the same progress and Ctrl-C handling (the FRF of the complete periods, exit 128 + signal).
static int cmd_measure(int argc, char **argv)
{
    for (int i = 3; i < argc; ++i) if (!std::strcmp(argv[i], "--on-device")) return cmd_modbus_ondevice(argc, argv);
    Args a(argc, argv, 3,
           {"tcp", "rtu", "baud", "parity", "data-bits", "stop-bits", "unit", "design", "periods", "rate", "encoding",
            "word-order", "scale", "response-timeout", "byte-timeout", "retries", "max-regs", "timeout",
            "skip-periods", "transient", "alpha", "detect-lines", "dft", "output"},
           {"quiet"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    const std::string out = a.require("output");
    MeasurePlan plan;
    plan.D = read_design_file(a.require("design"));
    parse_measure_options(a, *plan.D, plan.sf, plan.rq);
    plan.timeout = a.f64("timeout", 10.0);
    if (!(plan.timeout > 0 && plan.timeout <= 86400)) throw UsageError("--timeout must be positive (at most 86400 s)");
    const ModbusLink link = modbus_link_options(a);
    Progress pg(stderr, is_terminal(stderr), a.has("quiet"), "msid modbus");
    StopOnSignal guard;   // Ctrl-C ends the acquisition, the FRF of the complete periods is kept
    MeasureResult R = measure_modbus(link, [&](uint32_t, MeasurePlan &P) { P = std::move(plan); }, pg);
    return write_measure_result(R, out, "modbus");
}

// msid bench modbus: tests/modbus/bench_modbus.py with this build's binaries.
int cmd_bench_modbus(int argc, char **argv)
{
    static const char *BENCH_HELP =
        "usage: msid bench modbus [--quick]\n"
        "The highest sustained sample rate x channels with zero loss from msid-devsim to\n"
        "`msid modbus measure` over Modbus TCP on 127.0.0.1 and over RTU at 115200 baud on a\n"
        "socat pty pair (the simulator emulates the line's wire time), beside each link's\n"
        "theoretical register rate. See docs/benchmarks.md.\n";
    const Args a(argc, argv, 3, BENCH_HELP, {}, {"quick"});
    if (!a.positional().empty()) throw UsageError("msid bench modbus: unexpected argument " + a.positional()[0]);
    std::vector<std::string> pass;
    if (a.has("quick")) pass.push_back("--quick");
    std::vector<std::string> args = {"python3", std::string(MSID_SOURCE_DIR) + "/tests/modbus/bench_modbus.py"};
    args.insert(args.end(), pass.begin(), pass.end());
    return exec_with_build(args);
}

int exec_with_build(std::vector<std::string> args)
{
    char self[4096];
    const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) throw Error("cannot find the msid executable (/proc/self/exe)");
    self[n] = 0;
    std::string dir(self);
    dir = dir.substr(0, dir.rfind('/'));
    const std::string devsim = dir + "/../firmware_sim/msid-devsim";
    if (access(devsim.c_str(), X_OK) != 0) throw Error("msid-devsim not found next to the build (" + devsim + ")");
    setenv("MSID_BIN", self, 1);
    setenv("MSID_DEVSIM", devsim.c_str(), 1);
    std::vector<char *> av;
    for (auto &s : args) av.push_back(s.data());
    av.push_back(nullptr);
    std::fflush(stdout);
    execvp(av[0], av.data());
    throw Error(std::string("cannot run ") + args[0] + ": " + std::strerror(errno));
}

int cmd_modbus(int argc, char **argv)
{
    return dispatch_subcommand(argc, argv, "modbus", MODBUS_HELP, {{"measure", cmd_measure}});
}

}  // namespace msidcli
