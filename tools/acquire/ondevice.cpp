// Estimation on the device over Modbus and CAN (msid_ondevice.hpp).
#include "msid_ondevice.hpp"

extern "C" {
#include "msid_daq/msid_can_session.h"
#include "msid_daq/msid_mb_acq.h"
#include "msid_daq/msid_mb_est.h"
#include "msid_daq/msid_socketcan.h"
}

#include <algorithm>
#include <cmath>
#include <cstring>
#include <ctime>
#include <unistd.h>

namespace msidacq {

using msidutil::fmt;
using msidutil::check;
using msidutil::Mem;
using msidjob::FrfJob;
using msidjob::ExpSource;

namespace {

double secs_since(const timespec &t0)
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec);
}

// One device connection (the link of `msid modbus measure`) with a retrying client.
struct Device {
    MbLink link;
    msid_mb_client cl{};
    std::string name;
    void close() { link.close(); }
    void connect(const ModbusLink &l)
    {
        open_modbus_link(l, link);
        name = l.name;
        msid_mb_client_init(&cl, &link.m.tr, l.retries, 20);
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

// The estimator's failure as the device reported it (both links): "<msid_strerror> (msid_status N)", the
// byte counts of MSID_E_MEM_SIZE, the line (and its bin) or experiment it concerns.
struct EstStatus {
    uint32_t status = 0, need = 0, have = 0, bad = 0;   // bad: line or experiment + 1 (0: none)
};

std::string est_failure(const EstStatus &x, const FrfRequest &rq, const char *dims_what)
{
    const auto st = (msid_status)x.status;
    std::string s = fmt("%s (msid_status %u)", msid_strerror(st), (unsigned)st);
    if (st == MSID_E_MEM_SIZE && x.need)
        s += fmt(": its estimator needs %u bytes of working memory, it has %u", x.need, x.have);
    else if (st == MSID_E_DIMS)
        s += fmt(": the result block of this design does not fit the device's %s", dims_what);
    if (x.bad && (st == MSID_E_SINGULAR || st == MSID_E_RANGE) && x.bad <= rq.bins.size())
        s += fmt(" at line %u (bin %u)", x.bad, rq.bins[x.bad - 1]);
    else if (x.bad && st == MSID_E_FEW_PERIODS)
        s += fmt(" in experiment %u", x.bad);
    return s;
}

EstStatus mb_est_status(const std::vector<uint16_t> &x)
{
    EstStatus e;
    e.status = x[MSID_MB_IR_EST_STATUS];
    e.need = msid_mb_get_u32(&x[MSID_MB_IR_EST_NEED]);
    e.have = msid_mb_get_u32(&x[MSID_MB_IR_EST_HAVE]);
    e.bad = x[MSID_MB_IR_EST_BAD];
    return e;
}

// A value of the device's block that must be finite (a device is never trusted: nothing
// non-finite reaches the file, no count sizes anything unchecked).
double finite(const double *r, uint32_t k)
{
    if (!std::isfinite(r[k])) throw Error(fmt("the device's result block holds a non-finite value at double %u", k));
    return r[k];
}

uint64_t count(const double *r, uint32_t k)
{
    const double v = r[k];
    if (!(v >= 0 && v <= 9007199254740992.0 && v == std::floor(v)))   // 2^53: exact in a double
        throw Error(fmt("the device's result block holds %g at double %u where a count belongs", v, k));
    return (uint64_t)v;
}

Json cplx_matrix(const double *r, uint32_t k, size_t rows, size_t cols)
{
    std::vector<msid_cplx> v(rows * cols);
    for (size_t i = 0; i < v.size(); ++i) {
        v[i].re = finite(r, k + 2 * (uint32_t)i);
        v[i].im = finite(r, k + 2 * (uint32_t)i + 1);
    }
    return msidjob::cmat_json(v.data(), rows, cols);
}

Json finite_or_null(double v) { return std::isfinite(v) ? Json(v) : Json(nullptr); }

// The msid-frf/1 document from the device's result block (fields as FrfJob::finish writes them);
// `where` names the device ("modbus:tcp:127.0.0.1:1502", "can:vcan0").
Json device_doc(const FrfRequest &rq, const msid_mb_est_layout &lo, const double *r, const std::string &where)
{
    const uint32_t nu = lo.nu, ny = lo.ny, m = lo.m;
    const size_t g = (size_t)nu * ny;
    Json doc = frf_header(rq, nu, ny, m);
    Json exps = Json::array();
    uint64_t used = 0, rejected = 0;
    for (uint32_t e = 0; e < m; ++e) {
        auto X = [&](uint32_t k) { return (double)count(r, e * MSID_MB_EST_X_COUNT + k); };
        Json je;
        je["source"] = fmt("%s experiment %u (on device)", where.c_str(), e + 1);
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
        je["drift_p_value"] = finite_or_null(r[e * MSID_MB_EST_X_COUNT + MSID_MB_EST_X_DRIFT_P]);
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
        for (uint32_t i = 0; i < ny; ++i) snr.push_back(finite_or_null(r[b + lo.snr + i]));
        e["snr"] = snr;
        e["cond"] = finite(r, b + lo.cond);
        e["input_snr"] = finite_or_null(r[b + lo.usnr]);
        lines.push_back(e);
    }
    doc["lines"] = lines;
    return doc;
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

// The `acquisition` fields of both links, in one shape; each link adds its own counters.
Json ondevice_acq(const std::string &transport, const std::string &protocol, bool stream, const StreamFmt &sf,
                  uint32_t crc, uint32_t device_periods, double secs)
{
    Json j;
    j["transport"] = transport;
    j["protocol"] = protocol;
    j["extension"] = "estimate/1";
    j["on_device"] = true;
    j["estimate_mode"] = stream ? "estimate+stream" : "estimate";
    j["scale"] = (double)sf.scale;
    j["rate_hz"] = sf.rate;
    j["config_crc"] = crc;
    j["device_periods"] = device_periods;
    j["samples_lost"] = 0;
    j["seconds"] = secs;
    return j;
}

// Both links' end: every experiment kept 2 periods; the stream check's verdict; the summary.
void finish_ondevice(OnDeviceResult &R, Json acq, const std::string &check_name, const std::string &what,
                     const std::string &why = "")
{
    Json &doc = R.doc;
    uint64_t samples = 0;
    for (const auto &e : doc["experiments"]) {
        if (e["periods_used"].get<uint64_t>() < 2)
            throw Error(fmt("'%s': only %llu usable period(s): at least 2 are needed", e["source"].get<std::string>().c_str(),
                            (unsigned long long)e["periods_used"].get<uint64_t>()), 1, msidutil::ErrorKind::data);
        samples += e["samples"].get<uint64_t>();
    }
    acq["samples"] = samples;   // the device's samples: it holds every one (none crossed the link without a stream check)
    doc["acquisition"] = acq;
    if (R.checked) {
        const std::string diff = first_difference(doc, R.host.o.tree());
        if (!diff.empty())
            R.mismatch = fmt("the device's FRF differs from the host's estimate from the streamed samples (%s): %s%s",
                             check_name.c_str(), diff.c_str(), why.c_str());
        else
            doc["acquisition"]["stream_check"] = "bit-identical to " + check_name;
    }
    R.summary = fmt("%zu lines, %u x %u, %zu experiment(s) estimated on the device %s%s", doc["lines"].size(),
                    doc["n_outputs"].get<uint32_t>(), doc["n_inputs"].get<uint32_t>(), doc["experiments"].size(),
                    what.c_str(),
                    R.checked && R.mismatch.empty()
                        ? fmt("; bit for bit equal to the host's FRF from the streamed samples (%s)", check_name.c_str()).c_str()
                        : "");
}

// ---- Modbus ----

// The device: an msid-modbus/1 device with the estimate/1 extension and the design's inputs.
void identify_modbus(Device &dev, const msid_design &d, uint32_t &nu, uint32_t &ny)
{
    if (msid_mb_read_header(&dev.cl) < 0)
        throw Error(fmt("no msid-modbus device answered on %s: %s", dev.name.c_str(), dev.cl.err));
    const msid_mb_header &h = dev.cl.h;
    if (h.version != MSID_MB_PROTO_VERSION)
        throw Error(fmt("register map version mismatch: the device on %s serves msid-modbus/%u, this host msid-modbus/%u",
                        dev.name.c_str(), h.version, MSID_MB_PROTO_VERSION));
    if (h.nu != d.n_inputs)
        throw Error(fmt("the device has %u input(s) but the design has %u", h.nu, d.n_inputs), 1, msidutil::ErrorKind::data);
    nu = h.nu, ny = h.ny;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS || nu + ny > MSID_MAX_CHANNELS) throw Error(fmt("the device reports %u outputs", ny));
    const std::vector<uint16_t> x = dev.ext();
    if (!(x[MSID_MB_IR_EXT] & MSID_MB_EXT_ESTIMATE) || x[MSID_MB_IR_EST_VERSION] != MSID_MB_EST_VERSION)
        throw Error(fmt("the device on %s does not estimate on board (msid-modbus/1 without the estimate/%u extension: "
                        "input register 40 is %u); measure without " MSID_OPT("on_device"),
                        dev.name.c_str(), MSID_MB_EST_VERSION, x[MSID_MB_IR_EXT]));
}

// The estimator's settings, latched at the COMMIT of the upload.
void write_estimator_settings(Device &dev, const FrfRequest &rq, bool stream)
{
    uint16_t hr[MSID_MB_HR_EXT_COUNT - MSID_MB_HR_EST_MODE] = {};
    hr[0] = stream ? MSID_MB_EST_STREAM : MSID_MB_EST_ONLY;
    hr[MSID_MB_HR_EST_SKIP - MSID_MB_HR_EST_MODE] = (uint16_t)rq.skip;
    hr[MSID_MB_HR_EST_TRANSIENT - MSID_MB_HR_EST_MODE] = (uint16_t)rq.transient;
    msid_mb_put_f64(hr + (MSID_MB_HR_EST_ALPHA - MSID_MB_HR_EST_MODE), rq.alpha);
    if (msid_mb_call(&dev.cl, MSID_MB_WRITE_HOLDING, MSID_MB_HR_EST_MODE, MSID_MB_HR_EXT_COUNT - MSID_MB_HR_EST_MODE, hr) < 0)
        throw Error(fmt("writing the estimator settings to %s: %s", dev.name.c_str(), dev.cl.err));
}

// Estimate only: upload the design, then run the experiments; the device produces and estimates at
// its own pace. Returns the configuration's CRC.
uint32_t run_modbus_experiments(Device &dev, const ModbusLink &link, const MeasurePlan &P, Control &ctl)
{
    const msid_mb_header &h = dev.cl.h;
    const FrfRequest &rq = P.rq;
    auto cfg = config_from_design(*P.D, P.sf);
    const size_t nf = msid_params_frames(cfg.get(), nullptr, 0);
    std::vector<uint8_t> rec(nf * 8);
    msid_params_frames(cfg.get(), reinterpret_cast<uint8_t(*)[8]>(rec.data()), nf);
    const uint32_t crc = msid_can_get_u32(&rec[(nf - 1) * 8 + 4]);
    if (msid_mb_upload(&dev.cl, link.encoding, link.word_order, reinterpret_cast<const uint8_t(*)[8]>(rec.data()), nf) < 0)
        throw Error(fmt("design upload to %s failed: %s", dev.name.c_str(), dev.cl.err));
    if (h.state == MSID_MB_STATE_ERROR)
        throw Error(fmt("the device refused the configuration: %s%s", msid_can_device_error_name(h.error),
                        h.error == MSID_CAN_ERR_DESIGN ? (std::string(" (") + msid_strerror((msid_status)h.detail) + ")").c_str() : ""));
    if (h.state != MSID_MB_STATE_CONFIGURED) throw Error(fmt("the device did not confirm the configuration (state %u)", h.state));
    if (h.crc != crc) throw Error(fmt("the device confirmed configuration CRC %08X, the host sent %08X", h.crc, crc));
    const std::vector<uint16_t> x = dev.ext();
    if (x[MSID_MB_IR_EST_STATE] != MSID_MB_EST_STATE_ACCUMULATING)
        throw Error("the device cannot estimate on board: " + est_failure(mb_est_status(x), rq, "register map"));
    for (uint32_t e = 0; e < P.D->d.n_experiments; ++e) {
        if (msid_mb_command(&dev.cl, MSID_MB_CMD_START, e, P.sf.periods) < 0)
            throw Error(fmt("experiment %u on %s: %s", e + 1, dev.name.c_str(), dev.cl.err));
        if (h.state == MSID_MB_STATE_ERROR)
            throw Error(fmt("experiment %u on %s: the device refused START: %s", e + 1, dev.name.c_str(), msid_can_device_error_name(h.error)));
        timespec last;
        clock_gettime(CLOCK_MONOTONIC, &last);
        uint32_t wi = h.write_index;
        ProgressState ps;
        ps.exp = e + 1, ps.n_exp = P.D->d.n_experiments, ps.periods_target = P.sf.periods;
        auto ask = [&] {   // the caller sees the experiment run; a stop leaves no FRF (the device estimates whole runs)
            ctl.update(ps);
            if (const int sig = ctl.stop()) {
                (void)msid_mb_command(&dev.cl, MSID_MB_CMD_STOP, e, 0);   // best effort: the device may be gone
                throw Error(fmt("stopped (signal %d) during experiment %u on %s: a device that estimates on board "
                                "gives an FRF only for whole runs",
                                sig, e + 1, dev.name.c_str()),
                            128 + sig);
            }
        };
        ask();
        while (!(h.state == MSID_MB_STATE_DONE && h.experiment == e)) {
            usleep(20000);
            ask();
            if (msid_mb_read_header(&dev.cl) < 0)
                throw Error(fmt("experiment %u on %s: %s", e + 1, dev.name.c_str(), dev.cl.err));
            if (h.state == MSID_MB_STATE_ERROR)
                throw Error(fmt("experiment %u on %s: %s", e + 1, dev.name.c_str(), msid_can_device_error_name(h.error)));
            if (h.state != MSID_MB_STATE_RUNNING && h.state != MSID_MB_STATE_DONE)
                throw Error(fmt("experiment %u on %s: the device left the run (state %u)", e + 1, dev.name.c_str(), h.state));
            if (h.write_index != wi) {
                wi = h.write_index;
                clock_gettime(CLOCK_MONOTONIC, &last);
            } else if (secs_since(last) > P.timeout) {
                throw Error(fmt("the device on %s produced no new sample for %g s during experiment %u",
                                dev.name.c_str(), P.timeout, e + 1));
            }
        }
    }
    return crc;
}

// SOLVE, then the result block as doubles (its layout checked against the design).
std::vector<double> solve_modbus(Device &dev, const FrfRequest &rq, const msid_mb_est_layout &lo, std::vector<uint16_t> &x,
                                 uint32_t &regs)
{
    if (msid_mb_command(&dev.cl, MSID_MB_CMD_SOLVE, 0, 0) < 0)
        throw Error(fmt("SOLVE on %s: %s", dev.name.c_str(), dev.cl.err));
    x = dev.ext();
    if (x[MSID_MB_IR_EST_STATE] != MSID_MB_EST_STATE_READY)
        throw Error("the device's estimate failed: " + est_failure(mb_est_status(x), rq, "register map"));
    const uint32_t addr = x[MSID_MB_IR_EST_ADDR];
    regs = msid_mb_get_u32(&x[MSID_MB_IR_EST_REGS]);
    if (regs != msid_mb_est_regs(&lo) || (uint64_t)addr + regs > 65536u || addr < MSID_MB_RING_ADDR)
        throw Error(fmt("the device's result block (%u registers at %u) does not match the design (%u registers)", regs,
                        addr, msid_mb_est_regs(&lo)));
    std::vector<uint16_t> block(regs);
    for (uint32_t k = 0; k < regs; k += MSID_MB_MAX_READ) {
        const uint32_t n = std::min<uint32_t>(MSID_MB_MAX_READ, regs - k);
        if (msid_mb_call(&dev.cl, MSID_MB_READ_INPUT, addr + k, n, block.data() + k) < 0)
            throw Error(fmt("reading the result block from %s: %s", dev.name.c_str(), dev.cl.err));
    }
    std::vector<double> vals(lo.doubles);
    for (uint32_t k = 0; k < lo.doubles; ++k) vals[k] = msid_mb_est_value(block.data(), k);
    return vals;
}

// ---- CAN ----

// --stream-check over CAN: the ordinary host estimate (FrfJob) fed by a decoder attached to the session.
struct CanStream {
    std::unique_ptr<FrfJob> job;
    Mem mem;
    msid_can_decoder dec{};
    CanStream(const FrfRequest &rq, uint32_t nu, uint32_t ny, uint32_t m, const StreamFmt &sf, const msid_params &c,
              uint32_t base, uint32_t window)
        : job(std::make_unique<FrfJob>(rq, nu, ny, m, sf.periods, 4 * sf.periods + 8))
    {
        msid_can_decoder_cfg dc{};
        dc.base = base, dc.n_inputs = nu, dc.n_outputs = ny, dc.window = window, dc.meas = job->meas();
        dc.encoding = c.encoding, dc.fd = c.fd, dc.scale = (double)c.scale, dc.period = c.period;
        dc.samples_total = (uint64_t)sf.periods * c.period;
        mem = Mem(msid_can_decoder_mem_size(&dc));
        check(msid_can_decoder_init(&dec, &dc, mem.p, mem.n), "decoder setup");
    }
    // The host's msid-frf/1 from the streamed samples.
    Json doc(const std::string &iface, uint32_t m)
    {
        const msid_meas *ms = job->meas();
        std::vector<ExpSource> src;
        for (uint32_t e = 0; e < m; ++e)
            src.push_back({fmt("can:%s experiment %u", iface.c_str(), e + 1), ms->samples[e],
                           msid_pstats_get_counts(msid_meas_stats(ms, e)).offered, msid_meas_leftover(ms, e)});
        FrfOutcome o = job->finish(src);
        const msid_can_counters &k = dec.cnt;
        o.tail()["acquisition"] = {{"transport", "socketcan"}, {"interface", iface}, {"frames", k.frames},
                                {"sample_frames", k.sample_frames}, {"samples", k.samples},
                                {"samples_lost", k.samples_lost}, {"gap_events", k.gap_events}};
        return o.tree();
    }
};

// A failed session step: one message (the session's, or the core's reason a decoder refused).
[[noreturn]] void can_failed(const msid_can_session &s, int rc)
{
    const msid_status st = msid_daq_core_status(rc);
    if (st != MSID_OK && st != MSID_E_CAPACITY) check(st, "decoder");
    throw Error(s.err);
}

EstStatus can_est_status(const msid_can_est_view &x) { return {x.status, x.need, x.have, x.bad1}; }

}  // namespace

void check_ondevice_request(FrfRequest &rq)
{
    if (!rq.detect.empty())
        throw UsageError(MSID_OPT("detect_lines") " is not available with " MSID_OPT("on_device") " (the device solves the excited lines only)");
    if (rq.skip > 0xFFFFu) throw UsageError(MSID_OPT("skip_periods") " must be below 65536 with " MSID_OPT("on_device"));
    rq.path = MSID_DFT_STREAM;   // the device's line DFT path (the host's, for the stream check)
}

OnDeviceResult measure_modbus_ondevice(const ModbusLink &link, const MeasurePlan &P, const std::string &check_name,
                                       Control &ctl)
{
    OnDeviceResult R;
    R.checked = !check_name.empty();
    const FrfRequest &rq = P.rq;
    const uint32_t m = P.D->d.n_experiments;
    Device dev;
    dev.connect(link);
    uint32_t nu = 0, ny = 0;
    identify_modbus(dev, P.D->d, nu, ny);
    write_estimator_settings(dev, rq, R.checked);
    timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    uint32_t crc = 0;
    if (R.checked) {
        // the ordinary host measurement from the streamed samples (it uploads and runs every experiment)
        dev.close();
        R.host = measure_modbus(link, [&](uint32_t, MeasurePlan &Q) { Q = P; }, ctl);
        if (!R.host.complete) return R;
        dev.connect(link);
        if (msid_mb_read_header(&dev.cl) < 0) throw Error(fmt("%s: %s", dev.name.c_str(), dev.cl.err));
        crc = dev.cl.h.crc;
    } else {
        crc = run_modbus_experiments(dev, link, P, ctl);
    }
    msid_mb_est_layout lo;
    if (msid_mb_est_layout_init(&lo, nu, ny, m, (uint32_t)rq.bins.size()) != 0) throw Error("FRF dimensions out of range");
    std::vector<uint16_t> x;
    uint32_t regs = 0;
    const std::vector<double> vals = solve_modbus(dev, rq, lo, x, regs);
    const double secs = secs_since(t0);
    R.doc = device_doc(rq, lo, vals.data(), "modbus:" + dev.name);
    Json acq = ondevice_acq(std::string("modbus-") + msid_mb_backend_name(dev.cl.tr),
                            fmt("msid-modbus/%u", MSID_MB_PROTO_VERSION), R.checked, P.sf, crc,
                            msid_mb_get_u32(&x[MSID_MB_IR_EST_PERIODS]), secs);
    acq["endpoint"] = dev.name.substr(4);
    acq["encoding"] = msid_mb_encoding_name(link.encoding);
    acq["word_order"] = msid_mb_word_order_name(link.word_order);
    acq["result_registers"] = regs;
    acq["requests"] = dev.cl.cnt.requests;
    acq["registers_read"] = dev.cl.cnt.registers_read;
    acq["retries"] = dev.cl.cnt.retries;
    acq["overrun_samples"] = 0;
    acq["device_overruns"] = 0;
    acq["timeouts"] = dev.cl.cnt.timeouts;
    acq["crc_errors"] = dev.cl.cnt.crc_errors;
    acq["exceptions"] = dev.cl.cnt.exceptions;
    acq["reconnects"] = dev.cl.cnt.reconnects;
    acq["link_reg_rate"] = 0;
    acq["link_reg_rate_from"] = "not measured (on-device estimation: the samples do not cross the link)";
    finish_ondevice(R, acq, check_name, fmt("on %s (%u result registers)", dev.name.c_str(), regs));
    return R;
}

OnDeviceResult measure_can_ondevice(const CanLink &link, const MeasurePlan &P, const std::string &check_name)
{
    OnDeviceResult R;
    R.checked = !check_name.empty();
    // a bitrate bounds a sample stream; estimating on the device no sample crosses the bus. The stream check
    // streams every sample on a bus `msid can measure --bitrate` would judge: it runs on a virtual bus.
    if (R.checked && (link.bitrate > 0 || link.data_bitrate > 0))
        throw UsageError(MSID_OPT("stream_check") " streams every sample: run it on a virtual bus (without " MSID_OPT("bitrate") ")");
    const FrfRequest &rq = P.rq;
    const StreamFmt &sf = P.sf;
    const std::string &iface = link.iface;
    const uint32_t base = link.base, m = P.D->d.n_experiments;
    auto cfg = config_from_design(*P.D, sf);
    std::vector<uint8_t> cf(msid_params_frames(cfg.get(), nullptr, 0) * 8);
    const size_t nf = cf.size() / 8;
    msid_params_frames(cfg.get(), reinterpret_cast<uint8_t(*)[8]>(cf.data()), nf);

    // 1. the bus (the device's 128 identifiers and error frames) and the session: who is there?
    msid_socketcan sc;
    msid_socketcan_cfg scc{};
    scc.iface = iface.c_str(), scc.fd_frames = sf.fd, scc.err_frames = 1, scc.rcvbuf = link.rcvbuf;
    scc.n_filters = 1, scc.filter_id[0] = base, scc.filter_mask[0] = 0x780u | MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG;
    if (msid_socketcan_open(&sc, &scc) < 0) throw Error(sc.err);
    struct Closer { msid_socketcan &s; ~Closer() { msid_can_close(&s.tr); } } closer{sc};
    auto s = std::make_unique<msid_can_session>();
    msid_can_session_cfg ssc{};
    ssc.tr = &sc.tr, ssc.base = base, ssc.silence_ms = (uint32_t)std::ceil(P.timeout * 1000.0);
    if (msid_can_session_init(s.get(), &ssc) < 0) throw Error("CAN session setup");
    timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int rc = msid_can_session_identify(s.get(), 2000);
    if (rc < 0) throw Error(fmt("%s (on %s)", s->err, iface.c_str()));
    const uint32_t nu = s->dev.nu, ny = s->dev.ny;
    if (nu != P.D->d.n_inputs)
        throw Error(fmt("the device has %u input(s) but the design has %u", nu, P.D->d.n_inputs), 1, msidutil::ErrorKind::data);
    if (ny == 0 || ny > MSID_MAX_OUTPUTS || nu + ny > MSID_MAX_CHANNELS) throw Error(fmt("the device reports %u outputs", ny));
    msid_mb_est_layout lo;
    if (msid_mb_est_layout_init(&lo, nu, ny, m, (uint32_t)rq.bins.size()) != 0) throw Error("FRF dimensions out of range");

    // 2. with the stream check the host's estimate from the streamed samples; the design; the device's estimator
    std::unique_ptr<CanStream> host;
    if (R.checked) {
        host = std::make_unique<CanStream>(rq, nu, ny, m, sf, *cfg, base, link.window);
        if ((rc = msid_can_session_attach(s.get(), &host->dec)) < 0) can_failed(*s, rc);
    }
    if ((rc = msid_can_session_upload(s.get(), reinterpret_cast<const uint8_t(*)[8]>(cf.data()), nf)) < 0)
        can_failed(*s, rc);
    rc = msid_can_session_est_setup(s.get(), R.checked ? MSID_MB_EST_STREAM : MSID_MB_EST_ONLY, (uint32_t)rq.transient,
                                    rq.skip, rq.alpha);
    if (rc == -MSID_DAQ_E_PROTOCOL) throw Error(fmt("%s on %s; measure without " MSID_OPT("on_device"), s->err, iface.c_str()));
    if (rc == -MSID_DAQ_E_DEVICE)
        throw Error("the device cannot estimate on board: " + est_failure(can_est_status(s->est), rq, "24-bit value index"));
    if (rc < 0) can_failed(*s, rc);

    // 3. the experiments (the device produces and estimates at its own pace), SOLVE and the result block
    for (uint32_t e = 0; e < m; ++e)
        if ((rc = msid_can_session_run(s.get(), e, sf.periods)) < 0) can_failed(*s, rc);
    std::vector<double> vals(lo.doubles);
    std::vector<uint8_t> got(lo.doubles);
    rc = msid_can_session_est_solve(s.get(), vals.data(), got.data(), lo.doubles);
    if (rc == -MSID_DAQ_E_DEVICE)
        throw Error("the device's estimate failed: " + est_failure(can_est_status(s->est), rq, "24-bit value index"));
    if (rc < 0) can_failed(*s, rc);
    const double secs = secs_since(t0);

    R.doc = device_doc(rq, lo, vals.data(), "can:" + iface);
    Json acq = ondevice_acq("socketcan", fmt("msid-can/%u", MSID_CAN_PROTO_VERSION), R.checked, sf, s->crc,
                            s->est.periods, secs);
    acq["interface"] = iface;
    acq["base_id"] = base;
    acq["frame_format"] = std::string(sf.fd ? "fd" : "classic") + "/" + (sf.encoding ? "float32" : "int16");
    acq["result_doubles"] = lo.doubles;
    acq["est_frames"] = s->cnt.est_frames;
    acq["solves"] = s->cnt.est_solves;
    acq["frames_sent"] = s->cnt.frames_sent;
    acq["queries"] = s->cnt.queries;
    msid_can_link_stats ls;
    msid_can_get_stats(&sc.tr, &ls);
    const msid_can_counters none{};
    const msid_can_counters &k = host ? host->dec.cnt : none;   // the sample stream's (none when estimating only)
    acq["frames_missing"] = k.frames_missing;
    acq["duplicates"] = k.duplicates;
    acq["reordered"] = k.reordered;
    acq["malformed"] = k.malformed;
    acq["error_frames"] = s->cnt.error_frames;
    acq["bus_state"] = msid_can_bus_state_name(s->bus);
    acq["kernel_drops"] = ls.kernel_drops;
    acq["send_retries"] = ls.send_retries;
    std::string why;
    if (host) {
        R.host.o.doc = host->doc(iface, m);
        acq["sample_frames"] = host->dec.cnt.sample_frames;
        if (host->dec.cnt.samples_lost)
            why = fmt(" (%llu streamed sample(s) were lost on the way to the host: raise --rcvbuf)",
                      (unsigned long long)host->dec.cnt.samples_lost);
    }
    finish_ondevice(R, acq, check_name,
                    fmt("on %s (%u result values in %llu EST frames)", iface.c_str(), lo.doubles,
                        (unsigned long long)s->cnt.est_frames), why);
    return R;
}

OnDeviceResult measure_device_ondevice(const DeviceUri &dev, const MeasurePlan &P, const std::string &check_name,
                                       Control &ctl)
{
    if (dev.kind == DeviceUri::CAN) {
        CanLink l = can_link_from_uri(dev);
        return measure_can_ondevice(l, P, check_name);
    }
    return measure_modbus_ondevice(modbus_link_from_uri(dev), P, check_name, ctl);
}

}  // namespace msidacq
