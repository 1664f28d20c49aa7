// msid can: measure an FRF over SocketCAN from an msid-can/1 device, and
// replay a candump log through the same decoder (bit-identical FRF).
#include "commands.hpp"
#include "host_libs.hpp"
#include "measure.hpp"
#include "msid_can_acq.hpp"

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

static const char *HELP =
    "usage: msid can measure --iface IF --design design.json -o frf.json [options]\n"
    "       msid can replay --log run.log [--design design.json] [--session N | --since T --until T] -o frf.json\n"
    "       msid can replay --log run.log --list\n"
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
    "                      as the log writes them, seconds since the epoch: 1700000000.123456)\n";

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

// ---- replay ------------------------------------------------------------------

// One session of a log: a committed design upload (CFG BEGIN..COMMIT) and the experiments the device
// ran with it (RUNNING .. DONE). Its frames run from the end of the session before (its last sample,
// RUNNING or DONE frame; the log's start for the first) to its own last such frame, so the device's
// answers before the upload (INFO) are decoded as the live session decoded them. Frame indices count
// the frames the candump reader returns (blank lines skipped), the same in every pass over the file.
struct LogSession {
    uint64_t begin = 0, upload = 0, commit = 0, end = 0;   // frames [begin, end); BEGIN and COMMIT frames
    uint64_t t_begin = 0, t_end = 0;           // ns since the epoch: the upload's BEGIN, the last run frame
    uint32_t crc = 0, period = 0, n_inputs = 0, n_experiments = 0, periods = 0, encoding = 0, fd = 0;
    uint64_t runs = 0, dones = 0, sample_frames = 0;
    bool same_design(const LogSession &o) const
    {
        return crc == o.crc && period == o.period && n_inputs == o.n_inputs && n_experiments == o.n_experiments &&
               periods == o.periods && encoding == o.encoding && fd == o.fd;
    }
};

// A log timestamp as candump writes it, "1700000000.123456" (or "(1700000000.123456)"): ns since the epoch.
static uint64_t parse_log_time(const std::string &v, const char *what)
{
    std::string t = v;
    if (t.size() >= 2 && t.front() == '(' && t.back() == ')') t = t.substr(1, t.size() - 2);
    uint64_t sec = 0, frac = 0;
    size_t i = 0, nd = 0, nf = 0;
    for (; i < t.size() && t[i] >= '0' && t[i] <= '9' && nd < 19; ++i, ++nd) sec = sec * 10 + (uint64_t)(t[i] - '0');
    if (i < t.size() && t[i] == '.')
        for (++i; i < t.size() && t[i] >= '0' && t[i] <= '9'; ++i, ++nf)
            if (nf < 9) frac = frac * 10 + (uint64_t)(t[i] - '0');
    if (nd == 0 || i != t.size() || sec > 18000000000ull)
        throw UsageError(fmt("%s: '%s' is not a log timestamp (seconds as the log writes them, e.g. 1700000000.123456)",
                             what, v.c_str()));
    for (; nf < 9; ++nf) frac *= 10;
    return sec * 1000000000ull + frac;
}

static std::string log_time(uint64_t ns)
{
    return fmt("%llu.%06llu", (unsigned long long)(ns / 1000000000ull), (unsigned long long)(ns % 1000000000ull / 1000ull));
}

// Pass over the whole log: the sessions at `base`, the device's INFO (version, outputs), the interface.
struct LogScan {
    std::vector<LogSession> sessions;
    bool have_info = false, have_upload = false;
    uint32_t ny = 0, version = 0;
    uint64_t frames = 0;
    std::string iface;
};

static bool is_sample_frame(const msid_can_frame &f, uint32_t base)
{
    return !(f.id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) && (f.id & 0x780u) == base &&
           (f.id & 0x7Fu) >= MSID_CAN_ID_S16;
}

static LogScan scan_sessions(msid_candump_reader &rd, const std::string &path, uint32_t base)
{
    LogScan sc;
    auto cfg = std::make_unique<msid_params>();
    std::memset(cfg.get(), 0, sizeof *cfg);
    msid_params_reset(cfg.get());
    bool pending = false;          // a committed upload not yet followed by a run
    LogSession cand;               // that upload
    uint64_t upload_begin = 0, upload_t = 0, run_end = 0;   // run_end: after the last run frame so far
    msid_can_frame fr[64];
    msid_candump_rewind(&rd);
    for (;;) {
        const int k = msid_can_recv(&rd.tr, fr, 64, 0);
        if (k == -MSID_DAQ_E_EOF) break;
        if (k < 0) throw Error("'" + path + "': " + msid_can_error(&rd.tr));
        for (int i = 0; i < k; ++i, ++sc.frames) {
            const msid_can_frame &f = fr[i];
            if (sc.iface.empty()) sc.iface = rd.iface;
            LogSession *cur = sc.sessions.empty() ? nullptr : &sc.sessions.back();
            auto run_frame = [&] {
                if (!cur) return;
                run_end = sc.frames + 1;
                cur->t_end = f.t_ns;
            };
            if (is_sample_frame(f, base)) {
                if (cur) cur->sample_frames++;
                run_frame();
            }
            if (f.id == base + MSID_CAN_ID_CFG) {
                if (f.len >= 1 && f.data[0] == MSID_CAN_P_BEGIN) {
                    upload_begin = sc.frames;
                    upload_t = f.t_ns;
                }
                if (msid_params_feed(cfg.get(), f.data, f.len, MSID_CAN_PROTO_VERSION) == 1) {
                    sc.have_upload = true;
                    pending = true;
                    cand = LogSession{};
                    cand.upload = upload_begin;
                    cand.t_begin = upload_t;
                    cand.commit = sc.frames;
                    cand.crc = cfg->crc;
                    cand.period = cfg->period;
                    cand.n_inputs = cfg->n_inputs;
                    cand.n_experiments = cfg->n_experiments;
                    cand.periods = cfg->periods;
                    cand.encoding = cfg->encoding;
                    cand.fd = cfg->fd;
                }
            } else if (f.id == base + MSID_CAN_ID_STATUS && f.len == 8) {
                if (f.data[0] == MSID_CAN_ST_INFO) {
                    sc.have_info = true;
                    sc.version = f.data[1];
                    sc.ny = f.data[3];
                } else if (f.data[0] == MSID_CAN_ST_STATE && f.data[1] == MSID_CAN_STATE_RUNNING) {
                    if (pending) {   // the upload's first run: a new session
                        cand.begin = cur ? std::min(run_end, cand.upload) : 0;
                        if (cur) cur->end = cand.begin;
                        sc.sessions.push_back(cand);
                        pending = false;
                        cur = &sc.sessions.back();
                    }
                    if (cur) cur->runs++;
                    run_frame();
                } else if (f.data[0] == MSID_CAN_ST_STATE && f.data[1] == MSID_CAN_STATE_DONE && cur) {
                    cur->dones++;
                    run_frame();
                }
            }
        }
    }
    // A log whose last upload never ran (and nothing ran before it) still has that one session:
    // its replay reports what is missing.
    if (sc.sessions.empty() && pending) {
        sc.sessions.push_back(cand);
        sc.sessions.back().begin = 0;
        sc.sessions.back().t_end = cand.t_begin;
    }
    if (!sc.sessions.empty()) sc.sessions.back().end = sc.frames;
    return sc;
}

static std::string session_line(const LogSession &s, size_t i)
{
    return fmt("session %zu: %s .. %s, design crc 0x%08X (%u input(s), %u experiment(s), %u periods of %u), "
               "%llu run(s), %llu DONE, %llu sample frames",
               i + 1, log_time(s.t_begin).c_str(), log_time(s.t_end).c_str(), s.crc, s.n_inputs, s.n_experiments,
               s.periods, s.period, (unsigned long long)s.runs, (unsigned long long)s.dones,
               (unsigned long long)s.sample_frames);
}

static int cmd_replay(int argc, char **argv)
{
    Args a(argc, argv, 3,
           {"log", "design", "base", "window", "skip-periods", "transient", "alpha", "detect-lines", "output",
            "session", "since", "until"},
           {"list"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    const bool list = a.has("list");
    const std::string out = list ? a.get("output") : a.require("output"), path = a.require("log");
    const uint32_t base = parse_base(a), window = parse_window(a);
    if (a.has("session") && (a.has("since") || a.has("until")))
        throw UsageError("--session and --since/--until select in different ways: give one of them");
    const uint32_t want_session = a.has("session") ? parse_u32(a.get("session"), "--session") : 0;
    if (a.has("session") && want_session == 0) throw UsageError("--session counts from 1");
    const uint64_t since = a.has("since") ? parse_log_time(a.get("since"), "--since") : 0;
    const uint64_t until = a.has("until") ? parse_log_time(a.get("until"), "--until") : UINT64_MAX;
    if (since > until) throw UsageError("--since is after --until");
    msid_candump_reader rd;
    if (msid_candump_open(&rd, path.c_str()) < 0) throw Error(rd.err);
    struct Closer { msid_candump_reader &r; ~Closer() { msid_can_close(&r.tr); } } closer{rd};
    msid_can_transport &t = rd.tr;

    // Pass 1: the sessions and the device's INFO.
    const LogScan sc = scan_sessions(rd, path, base);
    const size_t ns = sc.sessions.size();
    if (list) {
        std::printf("%s: %zu session(s) at base %s, %llu frames\n", path.c_str(), ns, hex(base).c_str(),
                    (unsigned long long)sc.frames);
        for (size_t i = 0; i < ns; ++i) std::printf("  %s\n", session_line(sc.sessions[i], i).c_str());
        return 0;
    }
    if (!sc.have_info) throw Error("'" + path + "': no device INFO frame at base " + hex(base) + " (wrong --base, or not an msid-can log?)");
    if (sc.version != MSID_CAN_PROTO_VERSION)
        throw Error(fmt("'%s': protocol version mismatch: the log's device speaks msid-can/%u, this host msid-can/%u",
                        path.c_str(), sc.version, MSID_CAN_PROTO_VERSION));
    if (!sc.have_upload) throw Error("'" + path + "': no complete design upload (CFG BEGIN..COMMIT with a valid CRC)");

    // The selection: --session N, the sessions inside [--since, --until], or all of them.
    std::vector<size_t> sel;
    if (want_session) {
        if (want_session > ns)
            throw Error(fmt("'%s' holds %zu session(s): there is no session %u", path.c_str(), ns, want_session));
        sel.push_back(want_session - 1);
    } else {
        for (size_t i = 0; i < ns; ++i)
            if (sc.sessions[i].t_begin >= since && sc.sessions[i].t_end <= until) sel.push_back(i);
        if (sel.empty())
            throw Error(fmt("'%s' holds %zu session(s), none from %s to %s (sessions %s .. %s; see --list)", path.c_str(),
                            ns, log_time(since).c_str(), until == UINT64_MAX ? "the end" : log_time(until).c_str(),
                            log_time(sc.sessions.front().t_begin).c_str(), log_time(sc.sessions.back().t_end).c_str()));
    }
    size_t designs = 0;
    for (size_t i = 0; i < sel.size(); ++i) {
        bool seen = false;
        for (size_t j = 0; j < i && !seen; ++j) seen = sc.sessions[sel[j]].same_design(sc.sessions[sel[i]]);
        designs += !seen;
    }
    if (designs > 1)
        throw Error(fmt("'%s' holds %zu sessions of %zu different designs%s: pooling them is refused; replay one with "
                        "--session N (1..%zu) or a time range with --since/--until (--list shows them)",
                        path.c_str(), sel.size(), designs, sel.size() < ns ? " in the selected range" : "", ns));
    const LogSession &first = sc.sessions[sel[0]];
    std::vector<std::pair<uint64_t, uint64_t>> ranges;   // frames fed to the decoder
    uint64_t sample_frames = 0;
    for (size_t i : sel) {
        ranges.push_back({sc.sessions[i].begin, sc.sessions[i].end});
        sample_frames += sc.sessions[i].sample_frames;
    }

    // Pass 2: the configuration the first selected session committed.
    auto cfg = std::make_unique<msid_params>();
    auto got = std::make_unique<msid_params>();
    std::memset(cfg.get(), 0, sizeof *cfg);
    std::memset(got.get(), 0, sizeof *got);
    msid_params_reset(cfg.get());
    msid_can_frame fr[64];
    msid_candump_rewind(&rd);
    uint64_t idx = 0;
    bool have_cfg = false;
    while (!have_cfg) {
        const int k = msid_can_recv(&t, fr, 64, 0);
        if (k < 0) break;
        for (int i = 0; i < k && !have_cfg; ++i, ++idx)
            if (idx >= first.begin && fr[i].id == base + MSID_CAN_ID_CFG &&
                msid_params_feed(cfg.get(), fr[i].data, fr[i].len, MSID_CAN_PROTO_VERSION) == 1 && idx == first.commit) {
                std::memcpy(got.get(), cfg.get(), sizeof *cfg);
                have_cfg = true;
            }
    }
    if (!have_cfg) throw Error("'" + path + "': the log changed while it was read");
    const uint32_t ny = sc.ny;
    auto dd = device_design(*got);
    if (dd->st != MSID_OK) throw Error("'" + path + "': the logged design is invalid: " + msid_strerror(dd->st));
    FrfRequest rq;
    std::unique_ptr<Design> D;
    if (a.has("design")) {
        D = read_design_file(a.get("design"));
        if (!same_coef(D->d, dd->d))
            throw Error("'" + path + "': the design in the log differs from '" + a.get("design") + "'");
        request_from_design(rq, *D);
    } else {
        request_from_core_design(rq, dd->d);
    }
    parse_estimate_options(a, rq);
    if (got->rate_hz && !dd->d.is_ct) rq.fs = got->rate_hz;
    const uint32_t nu = got->n_inputs, m = got->n_experiments;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS) throw Error(fmt("'%s': the device reports %u outputs", path.c_str(), ny));
    if ((uint64_t)rq.skip + 2 > got->periods)
        throw Error(fmt("--skip-periods %u leaves fewer than 2 of the %u periods", rq.skip, got->periods));

    // Pass 3: the selected sessions' frames through the decoder, as live.
    msidacq::CanAcq acq;
    acq.iface = sc.iface;
    // The history is sized by what the log can hold, not by the periods its upload asks for (a 7 KB log
    // must not size gigabytes): no experiment has more periods than the log has frames for.
    const uint64_t fit = sample_frames / ((uint64_t)got->period * msid_can_chunks(nu + ny, got->encoding, got->fd)) + 8;
    const uint64_t want = 4ull * got->periods * sel.size() + 8;
    acq.init(rq, nu, ny, m, got->periods, base, *got, window, (uint32_t)std::min<uint64_t>(fit < want ? fit : want, UINT32_MAX));
    msid_candump_rewind(&rd);
    idx = 0;
    size_t r = 0;
    for (;;) {
        const int k = msid_can_recv(&t, fr, 64, 0);
        if (k == -MSID_DAQ_E_EOF) break;
        if (k < 0) throw Error("'" + path + "': " + msid_can_error(&t));
        for (int i = 0; i < k; ++i, ++idx) {
            while (r < ranges.size() && idx >= ranges[r].second) ++r;
            if (r < ranges.size() && idx >= ranges[r].first) acq.feed(fr[i]);
        }
    }
    std::vector<std::string> notes;
    if (acq.dec.open) {
        notes.push_back(fmt("the log ends during experiment %u: its pending samples were flushed", acq.dec.exp + 1));
        check(msid_can_decoder_abort(&acq.dec), "decoder");
    }
    for (uint32_t e = 0; e < m; ++e)
        if (msid_meas_stats(acq.dec.cfg.meas, e) && acq.dec.cfg.meas->samples[e] == 0)
            throw Error(fmt("'%s' holds no samples of experiment %u of %u", path.c_str(), e + 1, m));
    if (sel.size() > 1)
        notes.push_back(fmt("%zu sessions of the same design pooled (--session N replays one)", sel.size()));
    msid_can_link_stats ls;
    msid_can_get_stats(&t, &ls);
    auto ln = msidacq::can_loss_notes(acq.dec, ls);
    notes.insert(notes.end(), ln.begin(), ln.end());
    FrfOutcome o = acq.job->finish(msidacq::can_sources(acq, m), notes);
    Json acqj = msidacq::can_acquisition_json(acq, ls, "candump", base, *got, got->crc);
    acqj["log"] = path;
    acqj["sessions_in_log"] = ns;
    Json sj = Json::array();
    for (size_t i : sel)
        sj.push_back({{"session", i + 1}, {"start", log_time(sc.sessions[i].t_begin)}, {"end", log_time(sc.sessions[i].t_end)}});
    acqj["sessions"] = sj;
    o.doc["acquisition"] = acqj;
    write_json_file(out, o.doc);
    for (const auto &n : o.notes) std::fprintf(stderr, "msid can: note: %s\n", n.c_str());
    std::string which = sel.size() == 1 ? fmt("session %zu of %zu", sel[0] + 1, ns)
                                        : fmt("%zu of %zu sessions", sel.size(), ns);
    std::printf("wrote %s: %zu lines, %u x %u, %u experiment(s) replayed from %s (%s), %llu samples, %llu missing\n",
                out.c_str(), rq.bins.size(), ny, nu, m, path.c_str(), which.c_str(),
                (unsigned long long)acq.dec.cnt.samples, (unsigned long long)acq.dec.cnt.samples_lost);
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
    return dispatch_subcommand(argc, argv, "can", HELP, {{"measure", cmd_measure}, {"replay", cmd_replay}});
}

}  // namespace msidcli
