// msid modbus: measure an FRF over Modbus TCP or RTU from an msid-modbus/1 device
// (docs/modbus-registers.md) through the shared FRF job; msid bench modbus.
#include "commands.hpp"
#include "frf_io.hpp"
#include "modbus_link.hpp"
#include "param_upload.hpp"
#include "pipeline.hpp"

extern "C" {
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_modbus.h"
#include "msid_daq/msid_params.h"
}

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <unistd.h>

namespace msidcli {

static const char *HELP =
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
    "  --on-device             the device estimates (msid-modbus/1 extension estimate/1): no sample stream, the\n"
    "                          host reads each line's G, covariances and dof; --stream-check FILE: the device also\n"
    "                          streams, FILE gets the host's FRF and both must agree bit for bit\n";

static double secs_since(const timespec &t0)
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec);
}

void open_modbus_link(const Args &a, ModbusLink &L, uint32_t resp_ms, uint32_t byte_ms)
{
    msid_modbus_cfg c{};
    c.response_timeout_ms = resp_ms;
    c.byte_timeout_ms = byte_ms;
    c.unit = a.has("unit") ? (int)parse_u32(a.get("unit"), "--unit") : 1;
    std::string host, device = a.get("rtu");
    if (a.has("tcp") == a.has("rtu")) throw UsageError("give one of --tcp HOST:PORT and --rtu DEVICE");
    if (a.has("tcp")) {
        const std::string v = a.get("tcp");
        const size_t colon = v.rfind(':');
        if (colon == std::string::npos || colon == 0) throw UsageError("--tcp wants HOST:PORT (got '" + v + "')");
        host = v.substr(0, colon);
        const uint32_t port = parse_u32(v.substr(colon + 1), "--tcp port");
        if (port == 0 || port > 65535) throw UsageError("--tcp port must be 1..65535");
        if (c.unit > 255) throw UsageError("--unit must be 0..255 on TCP");
        c.host = host.c_str();
        c.port = (int)port;
        L.name = "tcp:" + v;
    } else {
        c.rtu = 1;
        c.device = device.c_str();
        const uint32_t baud = a.u32("baud", 115200);
        if (baud < 300 || baud > 4000000) throw UsageError("--baud must be 300..4000000");
        c.baud = (int)baud;
        c.parity = "NEO"[a.enum_index("parity", "N", {"N", "E", "O"})];
        c.data_bits = 8 - (int)a.enum_index("data-bits", "8", {"8", "7"});
        c.stop_bits = 1 + (int)a.enum_index("stop-bits", "1", {"1", "2"});
        if (c.unit < 1 || c.unit > 247) throw UsageError("--unit must be 1..247 on RTU");
        L.name = "rtu:" + a.get("rtu");
    }
    if (msid_modbus_open(&L.m, &c) < 0) throw Error(L.m.err);
    L.open = true;
}

// Register rate of the link: RTU from baud and framing, TCP measured with full reads.
static double link_reg_rate(const Args &a, const ModbusLink &L, msid_mb_client &cl, uint32_t max_regs, bool &measured)
{
    measured = !a.has("rtu");
    if (!measured) {
        const msid_modbus &m = L.m;
        const uint32_t bits = 1u + (uint32_t)m.cfg.data_bits + (m.cfg.parity != 'N') + (uint32_t)m.cfg.stop_bits;
        return msid_mb_rtu_reg_rate(m.cfg.baud, bits, max_regs);
    }
    std::vector<uint16_t> buf(max_regs);
    timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    uint64_t regs = 0;
    double el = 0;
    while ((el = secs_since(t0)) < 0.25) {
        if (msid_mb_call(&cl, MSID_MB_READ_INPUT, MSID_MB_RING_ADDR, max_regs, buf.data()) < 0)
            throw Error(std::string("measuring the link: ") + cl.err);
        regs += max_regs;
    }
    return (double)regs / el;
}

static Json acquisition_json(const ModbusLink &L, const msid_mb_client &cl, const msid_mb_acq &q, uint32_t unit,
                             uint32_t enc, uint32_t wo, double scale, uint32_t rate, uint32_t crc, double lrate,
                             bool measured, double stream_s)
{
    const msid_mb_link_counters &k = cl.cnt;
    const msid_mb_counters &c = q.cnt;
    const msid_stream_counters &s = q.st.cnt;
    Json j;
    j["transport"] = std::string("modbus-") + msid_mb_backend_name(cl.tr);
    j["endpoint"] = L.name.substr(4);
    j["unit"] = unit;
    j["protocol"] = fmt("msid-modbus/%u", MSID_MB_PROTO_VERSION);
    j["encoding"] = msid_mb_encoding_name(enc);
    j["word_order"] = msid_mb_word_order_name(wo);
    j["scale"] = scale;
    j["rate_hz"] = rate;
    j["config_crc"] = crc;
    j["ring_samples"] = cl.h.ring_samples;
    j["sample_regs"] = q.W;
    j["link_reg_rate"] = lrate;
    j["link_reg_rate_from"] = measured ? "measured" : "baud and framing";
    j["samples"] = s.samples;
    j["samples_lost"] = s.samples_lost;
    j["gap_events"] = s.gap_events;
    j["overrun_samples"] = c.overrun_samples;
    j["overrun_events"] = c.overrun_events;
    j["device_overruns"] = c.device_overruns;
    j["stale_replies"] = c.stale_replies;
    j["device_restarts"] = c.restarts;
    j["polls"] = c.polls;
    j["requests"] = k.requests;
    j["registers_read"] = k.registers_read;
    j["registers_written"] = k.registers_written;
    j["retries"] = k.retries;
    j["timeouts"] = k.timeouts;
    j["crc_errors"] = k.crc_errors;
    j["exceptions"] = k.exceptions;
    j["bad_replies"] = k.bad_replies;
    j["io_errors"] = k.io_errors;
    j["reconnects"] = k.reconnects;
    j["stream_seconds"] = stream_s;
    return j;
}

static int cmd_measure(int argc, char **argv)
{
    for (int i = 3; i < argc; ++i) if (!std::strcmp(argv[i], "--on-device")) return cmd_modbus_ondevice(argc, argv);
    Args a(argc, argv, 3,
           {"tcp", "rtu", "baud", "parity", "data-bits", "stop-bits", "unit", "design", "periods", "rate", "encoding",
            "word-order", "scale", "response-timeout", "byte-timeout", "retries", "max-regs", "timeout",
            "skip-periods", "transient", "alpha", "detect-lines", "dft", "output"},
           {});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    const std::string out = a.require("output");
    auto D = read_design_file(a.require("design"));
    const uint32_t enc = a.enum_index("encoding", "int16", {"int16", "int32", "float32"});
    const uint32_t wo = a.enum_index("word-order", "ABCD", {"ABCD", "CDAB", "BADC", "DCBA"});
    StreamFmt sf;
    FrfRequest rq;
    parse_measure_options(a, *D, sf, rq);
    const uint32_t resp_ms = a.u32("response-timeout", 200);
    const uint32_t byte_ms = a.u32("byte-timeout", 50);
    if (resp_ms < 1 || resp_ms > 60000 || byte_ms < 1 || byte_ms > 60000)
        throw UsageError("--response-timeout and --byte-timeout must be 1..60000 ms");
    const uint32_t retries = a.u32("retries", 5);
    if (retries < 1 || retries > 100) throw UsageError("--retries must be 1..100");
    const uint32_t max_regs = a.u32("max-regs", MSID_MB_MAX_READ);
    if (max_regs < 1 || max_regs > MSID_MB_MAX_READ) throw UsageError(fmt("--max-regs must be 1..%u", MSID_MB_MAX_READ));
    const double timeout = a.f64("timeout", 10.0);
    if (!(timeout > 0 && timeout <= 86400)) throw UsageError("--timeout must be positive (at most 86400 s)");
    const msid_design &d = D->d;
    auto cfg = config_from_design(*D, sf);

    const size_t nf = msid_params_frames(cfg.get(), nullptr, 0);
    std::vector<uint8_t> rec(nf * 8);
    msid_params_frames(cfg.get(), reinterpret_cast<uint8_t(*)[8]>(rec.data()), nf);
    const uint32_t crc = msid_can_get_u32(&rec[(nf - 1) * 8 + 4]);

    // open the transport; the client session: who is there?
    ModbusLink L;
    open_modbus_link(a, L, resp_ms, byte_ms);
    msid_mb_client cl;
    msid_mb_client_init(&cl, &L.m.tr, retries, 20);
    int rc = msid_mb_identify(&cl);
    if (rc == -MSID_DAQ_E_PROTOCOL) throw Error(fmt("%s (on %s)", cl.err, L.name.c_str()));
    if (rc < 0) throw Error(fmt("no msid-modbus device answered on %s: %s", L.name.c_str(), cl.err));
    const msid_mb_header &h = cl.h;
    if (h.nu != d.n_inputs) throw Error(fmt("the device has %u input(s) but the design has %u", h.nu, d.n_inputs));
    const uint32_t nu = h.nu, ny = h.ny, m = d.n_experiments, C = nu + ny;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS || C > MSID_MAX_CHANNELS) throw Error(fmt("the device reports %u outputs", ny));
    const uint32_t W = msid_mb_sample_regs(enc, C);
    if (W > max_regs)
        throw Error(fmt("one sample of %u %s channels takes %u registers, more than --max-regs %u", C,
                        msid_mb_encoding_name(enc), W, max_regs));

    // 2. can the link carry it?
    bool measured = false;
    const double lrate = link_reg_rate(a, L, cl, max_regs, measured);
    if (sf.rate > 0 && (double)sf.rate * W > 0.8 * lrate)
        throw Error(fmt("the link cannot carry %u channels at %u Hz: %.0f registers/s (%u per sample: a tag and %u %s "
                        "value(s)) but %s carries about %.0f registers/s %s (80%% of it is usable beside header "
                        "polls and retries); lower --rate%s",
                        C, sf.rate, (double)sf.rate * W, W, C, msid_mb_encoding_name(enc), L.name.c_str(), lrate,
                        measured ? "(measured with 125-register reads)"
                                 : fmt("(%u-register reads at %d baud, from the framing)", max_regs, L.m.cfg.baud).c_str(),
                        enc != MSID_MB_ENC_S16 ? " or use int16" : ""));

    // 3. upload the design as parameters (the client decodes the device's verdict)
    rc = msid_mb_configure(&cl, enc, wo, reinterpret_cast<const uint8_t(*)[8]>(rec.data()), nf);
    if (rc == -MSID_DAQ_E_DEVICE || rc == -MSID_DAQ_E_PROTOCOL) throw Error(cl.err);
    if (rc < 0) throw Error(fmt("design upload to %s failed: %s", L.name.c_str(), cl.err));

    // 4. run the experiments into the one FRF job
    FrfJob job(rq, nu, ny, m, sf.periods, 4 * sf.periods + 8);
    msid_mb_acq_cfg qc{};
    qc.client = &cl;
    qc.max_regs = max_regs;
    // batches sized to the link: about 20 ms of link time per poll
    const double per_poll = lrate * 0.02 / max_regs;
    qc.batch = per_poll < 1 ? 1u : per_poll > 64 ? 64u : (uint32_t)per_poll;
    qc.n_inputs = nu;
    qc.n_outputs = ny;
    qc.encoding = enc;
    qc.word_order = wo;
    qc.scale = (double)sf.scale;
    qc.meas = job.meas();
    qc.period = d.period;   // the header's P and K P are checked against the design
    Mem mq(msid_mb_acq_mem_size(&qc));
    msid_mb_acq q;
    check(msid_daq_core_status(msid_mb_acq_init(&q, &qc, mq.p, mq.n)), "Modbus adapter setup");
    const uint32_t silence_ms = (uint32_t)std::ceil(timeout * 1000.0);
    for (uint32_t e = 0; e < m; ++e) {
        if ((rc = msid_mb_acq_run(&q, e, sf.periods, silence_ms, sf.rate ? 2000 : 200)) < 0) {
            if (msid_daq_core_status(rc) == MSID_E_CAPACITY) throw Error(cl.err);
            check(msid_daq_core_status(rc), "measurement");   // any other core refusal, as every command reports it
            throw Error(fmt("experiment %u on %s: %s", e + 1, L.name.c_str(), cl.err));
        }
    }
    const double stream_s = 1e-9 * (double)q.cnt.stream_ns;

    std::vector<ExpSource> src;
    const msid_meas *ms = job.meas();
    for (uint32_t e = 0; e < m; ++e) {
        const msid_pstats_counts c = msid_pstats_get_counts(msid_meas_stats(ms, e));
        src.push_back({fmt("modbus:%s experiment %u", L.name.c_str(), e + 1), ms->samples[e], c.offered,
                       msid_meas_leftover(ms, e)});
    }
    std::vector<std::string> notes;
    if (q.cnt.overrun_samples)
        notes.push_back(fmt("%llu sample(s) overwritten in the device's ring before they were read (%llu overrun(s)): "
                            "the periods they touch were rejected",
                            (unsigned long long)q.cnt.overrun_samples, (unsigned long long)q.cnt.overrun_events));
    if (q.cnt.done_missing)
        notes.push_back(fmt("%llu experiment(s) ended after the design's %u x %u samples without the device "
                            "reporting DONE", (unsigned long long)q.cnt.done_missing, sf.periods, d.period));
    if (q.cnt.restarts) notes.push_back(fmt("the device restarted %llu time(s)", (unsigned long long)q.cnt.restarts));
    if (cl.cnt.retries)
        notes.push_back(fmt("%llu request(s) retried (%llu timeout(s), %llu bad CRC, %llu exception(s), %llu reconnect(s))",
                            (unsigned long long)cl.cnt.retries, (unsigned long long)cl.cnt.timeouts,
                            (unsigned long long)cl.cnt.crc_errors, (unsigned long long)cl.cnt.exceptions,
                            (unsigned long long)cl.cnt.reconnects));
    FrfOutcome o = job.finish(src, notes);
    o.doc["acquisition"] = acquisition_json(L, cl, q, (uint32_t)L.m.cfg.unit, enc, wo, (double)sf.scale, sf.rate, crc,
                                            lrate, measured, stream_s);
    write_json_file(out, o.doc);
    for (const auto &n : o.notes) std::fprintf(stderr, "msid modbus: note: %s\n", n.c_str());
    std::printf("wrote %s: %zu lines, %u x %u, %u experiment(s) over %s (%s %s), %llu samples, %llu missing, "
                "%llu periods used, %llu rejected\n",
                out.c_str(), rq.bins.size(), ny, nu, m, L.name.c_str(), msid_mb_encoding_name(enc),
                msid_mb_word_order_name(wo), (unsigned long long)q.st.cnt.samples,
                (unsigned long long)q.st.cnt.samples_lost, (unsigned long long)o.doc["periods_used"].get<uint64_t>(),
                (unsigned long long)o.doc["periods_rejected"].get<uint64_t>());
    return 0;
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
    return dispatch_subcommand(argc, argv, "modbus", HELP, {{"measure", cmd_measure}});
}

}  // namespace msidcli
