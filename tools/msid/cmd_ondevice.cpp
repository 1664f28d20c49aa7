// msid modbus measure --on-device: the device estimates (msid-modbus/1 extension estimate/1,
// daq/include/msid_daq/msid_mb_est.h, docs/modbus-registers.md "On-device estimation"); the host
// uploads the design and the estimator settings, runs the experiments, sends SOLVE, reads each
// line's G, covariances and dof bit for bit (float64 registers) and writes msid-frf/1.
// --stream-check FILE: the device also streams its samples; the host estimates from them with the
// ordinary `msid modbus measure` (FILE) and checks that both FRFs agree bit for bit.
#include "commands.hpp"
#include "frf_io.hpp"
#include "param_upload.hpp"
#include "pipeline.hpp"

extern "C" {
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_mb_est.h"
#include "msid_daq/msid_modbus.h"
}

#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <unistd.h>

namespace msidcli {

namespace {

double secs_since(const timespec &t0)
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec);
}

// One device connection (TCP or RTU 8N1) with a retrying client.
struct Device {
    msid_modbus mb{};
    msid_mb_client cl{};
    bool open = false;
    std::string name;
    ~Device() { close(); }
    void close()
    {
        if (open) msid_mb_close(&mb.tr);
        open = false;
    }
    void connect(const Args &a, uint32_t resp_ms, uint32_t retries)
    {
        msid_modbus_cfg c{};
        c.response_timeout_ms = resp_ms;
        c.byte_timeout_ms = 50;
        c.unit = a.has("unit") ? (int)parse_u32(a.get("unit"), "--unit") : 1;
        std::string host;
        const std::string dev = a.get("rtu");
        if (a.has("tcp") == a.has("rtu")) throw UsageError("give one of --tcp HOST:PORT and --rtu DEVICE");
        if (a.has("tcp")) {
            const std::string v = a.get("tcp");
            const size_t colon = v.rfind(':');
            if (colon == std::string::npos || colon == 0) throw UsageError("--tcp wants HOST:PORT (got '" + v + "')");
            host = v.substr(0, colon);
            const uint32_t port = parse_u32(v.substr(colon + 1), "--tcp port");
            if (port == 0 || port > 65535) throw UsageError("--tcp port must be 1..65535");
            c.host = host.c_str();
            c.port = (int)port;
            name = "tcp:" + v;
        } else {
            c.rtu = 1;
            c.device = dev.c_str();
            c.baud = a.has("baud") ? (int)parse_u32(a.get("baud"), "--baud") : 115200;
            c.parity = 'N';
            c.data_bits = 8;
            c.stop_bits = 1;
            name = "rtu:" + dev;
        }
        if (msid_modbus_open(&mb, &c) < 0) throw Error(mb.err);
        open = true;
        msid_mb_client_init(&cl, &mb.tr, retries, 20);
    }
    // The extension's header (input registers 40..55).
    std::vector<uint16_t> ext()
    {
        std::vector<uint16_t> x(MSID_MB_IR_EXT_END);
        if (msid_mb_call(&cl, MSID_MB_READ_INPUT, MSID_MB_IR_EXT, MSID_MB_IR_EXT_END - MSID_MB_IR_EXT,
                         x.data() + MSID_MB_IR_EXT) < 0)
            throw Error(fmt("reading the estimation header of %s: %s", name.c_str(), cl.err));
        return x;
    }
};

// "the device cannot estimate on board: ..." from the extension's header.
std::string est_failure(const std::vector<uint16_t> &x, const FrfRequest &rq)
{
    const auto st = (msid_status)x[MSID_MB_IR_EST_STATUS];
    std::string s = fmt("%s (msid_status %u)", msid_strerror(st), (unsigned)st);
    if (st == MSID_E_MEM_SIZE && msid_mb_get_u32(&x[MSID_MB_IR_EST_NEED]))
        s += fmt(": its estimator needs %u bytes of working memory, it has %u", msid_mb_get_u32(&x[MSID_MB_IR_EST_NEED]),
                 msid_mb_get_u32(&x[MSID_MB_IR_EST_HAVE]));
    else if (st == MSID_E_DIMS)
        s += ": the result block of this design does not fit the device's register map";
    const uint32_t bad = x[MSID_MB_IR_EST_BAD];
    if (bad && (st == MSID_E_SINGULAR || st == MSID_E_RANGE) && bad <= rq.bins.size())
        s += fmt(" at line %u (bin %u)", bad, rq.bins[bad - 1]);
    else if (bad && st == MSID_E_FEW_PERIODS)
        s += fmt(" in experiment %u", bad);
    return s;
}

// A value of the device's block that must be finite (a device is never trusted: nothing
// non-finite reaches the file, no count sizes anything unchecked).
double finite(const uint16_t *regs, uint32_t k)
{
    const double v = msid_mb_est_value(regs, k);
    if (!std::isfinite(v)) throw Error(fmt("the device's result block holds a non-finite value at double %u", k));
    return v;
}

uint64_t count(const uint16_t *regs, uint32_t k)
{
    const double v = msid_mb_est_value(regs, k);
    if (!(v >= 0 && v <= 9007199254740992.0 && v == std::floor(v)))   // 2^53: exact in a double
        throw Error(fmt("the device's result block holds %g at double %u where a count belongs", v, k));
    return (uint64_t)v;
}

Json cplx_matrix(const uint16_t *regs, uint32_t k, size_t rows, size_t cols)
{
    std::vector<msid_cplx> v(rows * cols);
    for (size_t i = 0; i < v.size(); ++i) {
        v[i].re = finite(regs, k + 2 * (uint32_t)i);
        v[i].im = finite(regs, k + 2 * (uint32_t)i + 1);
    }
    return cmat_json(v.data(), rows, cols);
}

Json finite_or_null(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

// The msid-frf/1 document from the device's result block (fields as FrfJob::finish writes them).
Json device_doc(const FrfRequest &rq, const msid_mb_est_layout &lo, const uint16_t *r, const std::string &name)
{
    const uint32_t nu = lo.nu, ny = lo.ny, m = lo.m;
    const size_t g = (size_t)nu * ny;
    Json doc = frf_header(rq, nu, ny, m);
    Json exps = Json::array();
    uint64_t used = 0, rejected = 0;
    for (uint32_t e = 0; e < m; ++e) {
        auto X = [&](uint32_t k) { return (double)count(r, e * MSID_MB_EST_X_COUNT + k); };
        Json je;
        je["source"] = fmt("modbus:%s experiment %u (on device)", name.c_str(), e + 1);
        je["samples"] = (uint64_t)X(MSID_MB_EST_X_SAMPLES);
        je["periods_total"] = (uint64_t)X(MSID_MB_EST_X_OFFERED);
        je["periods_skipped"] = (uint64_t)X(MSID_MB_EST_X_SKIPPED);
        je["periods_used"] = (uint64_t)X(MSID_MB_EST_X_USED);
        je["periods_gap"] = (uint64_t)X(MSID_MB_EST_X_GAP);
        je["periods_nonfinite"] = (uint64_t)X(MSID_MB_EST_X_NONFINITE);
        je["transient_tested"] = X(MSID_MB_EST_X_TESTED) != 0;
        Json flagged = Json::array(), dropped = Json::array();
        for (uint32_t k = 0; k < MSID_MB_EST_FLAG_MAX; ++k) {
            const double v = X(MSID_MB_EST_X_PERIODS + k);
            if (v < 4) continue;
            const auto num = (uint64_t)(v / 4), st = (uint64_t)v % 4;
            flagged.push_back(num);
            if (st == 2) dropped.push_back(num);
        }
        je["transient_flagged"] = flagged;
        je["transient_dropped"] = dropped;
        if (X(MSID_MB_EST_X_FLAGGED) > MSID_MB_EST_FLAG_MAX)
            je["transient_flagged_count"] = (uint64_t)X(MSID_MB_EST_X_FLAGGED);   // the lists hold the first ones
        je["drift_tested"] = X(MSID_MB_EST_X_DRIFT_TESTED) != 0;
        je["drift"] = X(MSID_MB_EST_X_DRIFT) != 0;
        je["drift_p_value"] = finite_or_null(msid_mb_est_value(r, e * MSID_MB_EST_X_COUNT + MSID_MB_EST_X_DRIFT_P));
        je["leftover_samples"] = (uint64_t)X(MSID_MB_EST_X_LEFTOVER);
        exps.push_back(je);
        used += (uint64_t)X(MSID_MB_EST_X_USED);
        rejected += (uint64_t)(X(MSID_MB_EST_X_GAP) + X(MSID_MB_EST_X_NONFINITE) + X(MSID_MB_EST_X_DROPPED));
    }
    doc["periods_used"] = used;
    doc["periods_rejected"] = rejected;
    doc["dft_path"] = "stream";
    doc["vec_convention"] = "vec stacks columns: G[i][j] has index i + n_outputs*j";
    doc["noise_cov"] = cplx_matrix(r, lo.noise, ny, ny);
    doc["experiments"] = exps;
    Json lines = Json::array();
    for (uint32_t l = 0; l < lo.L; ++l) {
        const uint32_t b = lo.lines + l * lo.line;
        Json e = line_position(rq, l);
        e["G"] = cplx_matrix(r, b + lo.G, ny, nu);
        e["cov"] = cplx_matrix(r, b + lo.cov, g, g);
        e["dof"] = finite(r, b + lo.dof);
        e["cov_known_input"] = cplx_matrix(r, b + lo.cov_ki, g, g);
        e["dof_known_input"] = finite(r, b + lo.dof_ki);
        e["noise_cov"] = cplx_matrix(r, b + lo.lnoise, ny, ny);
        Json snr = Json::array();
        for (uint32_t i = 0; i < ny; ++i) snr.push_back(finite_or_null(msid_mb_est_value(r, b + lo.snr + i)));
        e["snr"] = snr;
        e["cond"] = finite(r, b + lo.cond);
        e["input_snr"] = finite_or_null(msid_mb_est_value(r, b + lo.usnr));
        lines.push_back(e);
    }
    doc["lines"] = lines;
    return doc;
}

// argv of the ordinary `msid modbus measure` for --stream-check: ours removed, -o FILE.
std::vector<std::string> stream_argv(int argc, char **argv, const std::string &file)
{
    std::vector<std::string> v;
    for (int i = 0; i < argc; ++i) {
        const std::string s = argv[i];
        if (s == "--on-device") continue;
        if (s == "--stream-check" || s == "-o" || s == "--output" || s == "--dft") { ++i; continue; }
        if (s.rfind("--stream-check=", 0) == 0 || s.rfind("--output=", 0) == 0 || s.rfind("--dft=", 0) == 0) continue;
        v.push_back(s);
    }
    v.push_back("--dft");      // the device's line DFT path
    v.push_back("stream");
    v.push_back("-o");
    v.push_back(file);
    return v;
}

// First difference between the device's and the host's estimates (empty: bit for bit equal).
std::string first_difference(const Json &dev, const Json &host)
{
    static const char *keys[] = {"G", "cov", "dof", "cov_known_input", "dof_known_input", "noise_cov"};
    if (!host.contains("lines") || host["lines"].size() != dev["lines"].size()) return "the number of lines differs";
    for (size_t l = 0; l < dev["lines"].size(); ++l)
        for (const char *k : keys)
            if (dev["lines"][l][k] != host["lines"][l][k])
                return fmt("line %zu (bin %u): %s differs (device %s, host %s)", l + 1,
                           dev["lines"][l]["bin"].get<uint32_t>(), k, dev["lines"][l][k].dump().substr(0, 120).c_str(),
                           host["lines"][l][k].dump().substr(0, 120).c_str());
    if (dev["noise_cov"] != host["noise_cov"]) return "noise_cov differs";
    return "";
}

}  // namespace

int cmd_modbus_ondevice(int argc, char **argv)
{
    Args a(argc, argv, 3,
           {"tcp", "rtu", "baud", "unit", "design", "periods", "rate", "encoding", "word-order", "scale",
            "response-timeout", "retries", "timeout", "skip-periods", "transient", "alpha", "detect-lines",
            "stream-check", "output"},
           {"on-device"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    if (a.has("detect-lines")) throw UsageError("--detect-lines is not available with --on-device (the device solves the excited lines only)");
    const std::string out = a.require("output");
    auto D = read_design_file(a.require("design"));
    static const std::vector<std::string> encs = {"int16", "int32", "float32"}, orders = {"ABCD", "CDAB", "BADC", "DCBA"};
    auto pick = [&](const char *key, const char *def, const std::vector<std::string> &names) {
        const std::string v = a.get(key, def);
        for (size_t i = 0; i < names.size(); ++i)
            if (v == names[i]) return (uint32_t)i;
        throw UsageError(fmt("--%s: unknown value '%s'", key, v.c_str()));
    };
    const uint32_t enc = pick("encoding", "int16", encs), wo = pick("word-order", "ABCD", orders);
    StreamFmt sf;
    FrfRequest rq;
    parse_measure_options(a, *D, sf, rq);
    const uint32_t resp_ms = a.u32("response-timeout", 200);
    if (resp_ms < 1 || resp_ms > 60000) throw UsageError("--response-timeout must be 1..60000 ms");
    const uint32_t retries = a.u32("retries", 5);
    if (retries < 1 || retries > 100) throw UsageError("--retries must be 1..100");
    const double timeout = a.f64("timeout", 10.0);
    if (!(timeout > 0)) throw UsageError("--timeout must be positive");
    const bool check_stream = a.has("stream-check");
    const std::string host_file = a.get("stream-check");
    if (check_stream && host_file == out) throw UsageError("--stream-check and -o must name different files");
    const msid_design &d = D->d;
    const uint32_t m = d.n_experiments;

    // 1. an msid-modbus/1 device with the estimate/1 extension?
    Device dev;
    dev.connect(a, resp_ms, retries);
    if (msid_mb_read_header(&dev.cl) < 0)
        throw Error(fmt("no msid-modbus device answered on %s: %s", dev.name.c_str(), dev.cl.err));
    const msid_mb_header &h = dev.cl.h;
    if (h.version != MSID_MB_PROTO_VERSION)
        throw Error(fmt("register map version mismatch: the device on %s serves msid-modbus/%u, this host msid-modbus/%u",
                        dev.name.c_str(), h.version, MSID_MB_PROTO_VERSION));
    if (h.nu != d.n_inputs) throw Error(fmt("the device has %u input(s) but the design has %u", h.nu, d.n_inputs));
    const uint32_t nu = h.nu, ny = h.ny;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS || nu + ny > MSID_MAX_CHANNELS) throw Error(fmt("the device reports %u outputs", ny));
    std::vector<uint16_t> x = dev.ext();
    if (!(x[MSID_MB_IR_EXT] & MSID_MB_EXT_ESTIMATE) || x[MSID_MB_IR_EST_VERSION] != MSID_MB_EST_VERSION)
        throw Error(fmt("the device on %s does not estimate on board (msid-modbus/1 without the estimate/%u extension: "
                        "input register 40 is %u); measure without --on-device",
                        dev.name.c_str(), MSID_MB_EST_VERSION, x[MSID_MB_IR_EXT]));

    // 2. the estimator's settings (latched at the COMMIT of the upload)
    uint16_t hr[MSID_MB_HR_EXT_COUNT - MSID_MB_HR_EST_MODE] = {};
    hr[0] = check_stream ? MSID_MB_EST_STREAM : MSID_MB_EST_ONLY;
    hr[MSID_MB_HR_EST_SKIP - MSID_MB_HR_EST_MODE] = (uint16_t)rq.skip;
    hr[MSID_MB_HR_EST_TRANSIENT - MSID_MB_HR_EST_MODE] = (uint16_t)rq.transient;
    msid_mb_put_f64(hr + (MSID_MB_HR_EST_ALPHA - MSID_MB_HR_EST_MODE), rq.alpha);
    if (rq.skip > 0xFFFFu) throw UsageError("--skip-periods must be below 65536 with --on-device");
    if (msid_mb_call(&dev.cl, MSID_MB_WRITE_HOLDING, MSID_MB_HR_EST_MODE, MSID_MB_HR_EXT_COUNT - MSID_MB_HR_EST_MODE, hr) < 0)
        throw Error(fmt("writing the estimator settings to %s: %s", dev.name.c_str(), dev.cl.err));

    timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    uint64_t samples = 0;
    uint32_t crc = 0;
    if (check_stream) {
        // 3a. the ordinary host measurement from the streamed samples (it uploads and runs every experiment)
        dev.close();
        std::vector<std::string> args = stream_argv(argc, argv, host_file);
        std::vector<char *> av;
        for (auto &s : args) av.push_back(s.data());
        const int rc = cmd_modbus((int)av.size(), av.data());
        if (rc != 0) return rc;
        dev.connect(a, resp_ms, retries);
        if (msid_mb_read_header(&dev.cl) < 0) throw Error(fmt("%s: %s", dev.name.c_str(), dev.cl.err));
        crc = h.crc;
    } else {
        // 3b. upload the design, then run the experiments: the device produces and estimates at its own pace
        auto cfg = config_from_design(*D, sf);
        const size_t nf = msid_params_frames(cfg.get(), nullptr, 0);
        std::vector<uint8_t> rec(nf * 8);
        msid_params_frames(cfg.get(), reinterpret_cast<uint8_t(*)[8]>(rec.data()), nf);
        crc = msid_can_get_u32(&rec[(nf - 1) * 8 + 4]);
        if (msid_mb_upload(&dev.cl, enc, wo, reinterpret_cast<const uint8_t(*)[8]>(rec.data()), nf) < 0)
            throw Error(fmt("design upload to %s failed: %s", dev.name.c_str(), dev.cl.err));
        if (h.state == MSID_MB_STATE_ERROR)
            throw Error(fmt("the device refused the configuration: %s%s", msid_can_device_error_name(h.error),
                            h.error == MSID_CAN_ERR_DESIGN ? (std::string(" (") + msid_strerror((msid_status)h.detail) + ")").c_str() : ""));
        if (h.state != MSID_MB_STATE_CONFIGURED) throw Error(fmt("the device did not confirm the configuration (state %u)", h.state));
        if (h.crc != crc) throw Error(fmt("the device confirmed configuration CRC %08X, the host sent %08X", h.crc, crc));
        x = dev.ext();
        if (x[MSID_MB_IR_EST_STATE] != MSID_MB_EST_STATE_ACCUMULATING)
            throw Error("the device cannot estimate on board: " + est_failure(x, rq));
        for (uint32_t e = 0; e < m; ++e) {
            if (msid_mb_command(&dev.cl, MSID_MB_CMD_START, e, sf.periods) < 0)
                throw Error(fmt("experiment %u on %s: %s", e + 1, dev.name.c_str(), dev.cl.err));
            if (h.state == MSID_MB_STATE_ERROR)
                throw Error(fmt("experiment %u on %s: the device refused START: %s", e + 1, dev.name.c_str(), msid_can_device_error_name(h.error)));
            timespec last;
            clock_gettime(CLOCK_MONOTONIC, &last);
            uint32_t wi = h.write_index;
            while (!(h.state == MSID_MB_STATE_DONE && h.experiment == e)) {
                usleep(20000);
                if (msid_mb_read_header(&dev.cl) < 0)
                    throw Error(fmt("experiment %u on %s: %s", e + 1, dev.name.c_str(), dev.cl.err));
                if (h.state == MSID_MB_STATE_ERROR)
                    throw Error(fmt("experiment %u on %s: %s", e + 1, dev.name.c_str(), msid_can_device_error_name(h.error)));
                if (h.state != MSID_MB_STATE_RUNNING && h.state != MSID_MB_STATE_DONE)
                    throw Error(fmt("experiment %u on %s: the device left the run (state %u)", e + 1, dev.name.c_str(), h.state));
                if (h.write_index != wi) {
                    wi = h.write_index;
                    clock_gettime(CLOCK_MONOTONIC, &last);
                } else if (secs_since(last) > timeout) {
                    throw Error(fmt("the device on %s produced no new sample for %g s during experiment %u",
                                    dev.name.c_str(), timeout, e + 1));
                }
            }
            samples += h.write_index;
        }
    }

    // 4. SOLVE, then read the result block
    if (msid_mb_command(&dev.cl, MSID_MB_CMD_SOLVE, 0, 0) < 0)
        throw Error(fmt("SOLVE on %s: %s", dev.name.c_str(), dev.cl.err));
    x = dev.ext();
    if (x[MSID_MB_IR_EST_STATE] != MSID_MB_EST_STATE_READY)
        throw Error("the device's estimate failed: " + est_failure(x, rq));
    msid_mb_est_layout lo;
    if (msid_mb_est_layout_init(&lo, nu, ny, m, (uint32_t)rq.bins.size()) != 0) throw Error("FRF dimensions out of range");
    const uint32_t addr = x[MSID_MB_IR_EST_ADDR], regs = msid_mb_get_u32(&x[MSID_MB_IR_EST_REGS]);
    if (regs != msid_mb_est_regs(&lo) || (uint64_t)addr + regs > 65536u || addr < MSID_MB_RING_ADDR)
        throw Error(fmt("the device's result block (%u registers at %u) does not match the design (%u registers)", regs,
                        addr, msid_mb_est_regs(&lo)));
    std::vector<uint16_t> block(regs);
    for (uint32_t k = 0; k < regs; k += MSID_MB_MAX_READ) {
        const uint32_t n = std::min<uint32_t>(MSID_MB_MAX_READ, regs - k);
        if (msid_mb_call(&dev.cl, MSID_MB_READ_INPUT, addr + k, n, block.data() + k) < 0)
            throw Error(fmt("reading the result block from %s: %s", dev.name.c_str(), dev.cl.err));
    }
    const double secs = secs_since(t0);
    Json doc = device_doc(rq, lo, block.data(), dev.name);
    if (check_stream) {
        samples = 0;
        for (const auto &e : doc["experiments"]) samples += e["samples"].get<uint64_t>();
    }
    for (const auto &e : doc["experiments"])
        if (e["periods_used"].get<uint64_t>() < 2)
            throw Error(fmt("'%s': only %llu usable period(s): at least 2 are needed", e["source"].get<std::string>().c_str(),
                            (unsigned long long)e["periods_used"].get<uint64_t>()));
    Json acq;
    acq["transport"] = std::string("modbus-") + dev.cl.tr->be->name;
    acq["endpoint"] = dev.name.substr(4);
    acq["protocol"] = fmt("msid-modbus/%u", MSID_MB_PROTO_VERSION);
    acq["extension"] = fmt("estimate/%u", MSID_MB_EST_VERSION);
    acq["on_device"] = true;
    acq["estimate_mode"] = check_stream ? "estimate+stream" : "estimate";
    acq["encoding"] = msid_mb_encoding_name(enc);
    acq["word_order"] = msid_mb_word_order_name(wo);
    acq["scale"] = (double)sf.scale;
    acq["rate_hz"] = sf.rate;
    acq["config_crc"] = crc;
    acq["result_registers"] = regs;
    acq["device_periods"] = msid_mb_get_u32(&x[MSID_MB_IR_EST_PERIODS]);
    acq["requests"] = dev.cl.cnt.requests;
    acq["registers_read"] = dev.cl.cnt.registers_read;
    acq["retries"] = dev.cl.cnt.retries;
    acq["samples"] = samples;            // the device's samples: it holds every one, none crossed the link
    acq["samples_lost"] = 0;
    acq["overrun_samples"] = 0;
    acq["device_overruns"] = 0;
    acq["timeouts"] = dev.cl.cnt.timeouts;
    acq["crc_errors"] = dev.cl.cnt.crc_errors;
    acq["exceptions"] = dev.cl.cnt.exceptions;
    acq["reconnects"] = dev.cl.cnt.reconnects;
    acq["link_reg_rate"] = 0;
    acq["link_reg_rate_from"] = "not measured (on-device estimation: the samples do not cross the link)";
    acq["seconds"] = secs;
    doc["acquisition"] = acq;

    if (check_stream) {
        const Json host = read_json_file(host_file);
        const std::string diff = first_difference(doc, host);
        if (!diff.empty())
            throw Error(fmt("the device's FRF differs from the host's estimate from the streamed samples (%s): %s",
                            host_file.c_str(), diff.c_str()));
        doc["acquisition"]["stream_check"] = "bit-identical to " + host_file;
    }
    write_json_file(out, doc);
    std::printf("wrote %s: %zu lines, %u x %u, %u experiment(s) estimated on the device on %s (%u result registers)%s\n",
                out.c_str(), rq.bins.size(), ny, nu, m, dev.name.c_str(), regs,
                check_stream ? fmt("; bit for bit equal to the host's FRF from the streamed samples (%s)", host_file.c_str()).c_str() : "");
    return 0;
}

}  // namespace msidcli
