// `msid can replay` as a library (msid_can_replay.hpp): three passes over a candump log, each through
// the same reader: the sessions, the configuration the first selected one committed, and the selected
// sessions' frames through the live decoder.
#include "msid_can_replay.hpp"
#include "msid_can_acq.hpp"

extern "C" {
#include "msid_daq/msid_candump.h"
#include "msid_daq/msid_params.h"
}

#include <algorithm>
#include <cstring>

namespace msidacq {

using msidutil::fmt;
using msidutil::check;

// A log timestamp as candump writes it, "1700000000.123456" (or "(1700000000.123456)"): ns since the epoch.
uint64_t parse_log_time(const std::string &v, const char *what)
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

std::string log_time(uint64_t ns)
{
    return fmt("%llu.%06llu", (unsigned long long)(ns / 1000000000ull), (unsigned long long)(ns % 1000000000ull / 1000ull));
}

namespace {

bool is_sample_frame(const msid_can_frame &f, uint32_t base)
{
    return !(f.id & (MSID_CAN_EFF_FLAG | MSID_CAN_RTR_FLAG | MSID_CAN_ERR_FLAG)) && (f.id & 0x780u) == base &&
           (f.id & 0x7Fu) >= MSID_CAN_ID_S16;
}

std::string hex(uint32_t v) { return fmt("0x%X", v); }

// An open log, closed by the destructor.
struct Log {
    msid_candump_reader rd;
    explicit Log(const std::string &path)
    {
        if (msid_candump_open(&rd, path.c_str()) < 0) throw Error(rd.err);
    }
    ~Log() { msid_can_close(&rd.tr); }
    Log(const Log &) = delete;
    Log &operator=(const Log &) = delete;
};

LogScan scan_sessions(msid_candump_reader &rd, const std::string &path, uint32_t base)
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

// The log holds an msid-can/1 device of this host's protocol version and a committed upload.
void check_log(const LogScan &sc, const std::string &path, uint32_t base)
{
    if (!sc.have_info) throw Error("'" + path + "': no device INFO frame at base " + hex(base) + " (wrong " MSID_OPT("base") ", or not an msid-can log?)");
    if (sc.version != MSID_CAN_PROTO_VERSION)
        throw Error(fmt("'%s': protocol version mismatch: the log's device speaks msid-can/%u, this host msid-can/%u",
                        path.c_str(), sc.version, MSID_CAN_PROTO_VERSION));
    if (!sc.have_upload) throw Error("'" + path + "': no complete design upload (CFG BEGIN..COMMIT with a valid CRC)");
}

// The selection: the request's session, the sessions inside [since, until], or all of them; of one design.
std::vector<size_t> select_sessions(const LogScan &sc, const ReplayRequest &r)
{
    const std::string &path = r.log;
    const size_t ns = sc.sessions.size();
    std::vector<size_t> sel;
    if (r.session) {
        if (r.session > ns) throw Error(fmt("'%s' holds %zu session(s): there is no session %u", path.c_str(), ns, r.session));
        sel.push_back(r.session - 1);
    } else {
        for (size_t i = 0; i < ns; ++i)
            if (sc.sessions[i].t_begin >= r.since && sc.sessions[i].t_end <= r.until) sel.push_back(i);
        if (sel.empty())
            throw Error(fmt("'%s' holds %zu session(s), none from %s to %s (sessions %s .. %s; see " MSID_OPT("list") ")", path.c_str(),
                            ns, log_time(r.since).c_str(), r.until == UINT64_MAX ? "the end" : log_time(r.until).c_str(),
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
                        MSID_OPT("session") " N (1..%zu) or a time range with " MSID_OPT("since") "/" MSID_OPT("until") " (" MSID_OPT("list") " shows them)",
                        path.c_str(), sel.size(), designs, sel.size() < ns ? " in the selected range" : "", ns));
    return sel;
}

// Pass 2: the configuration the session `first` committed.
std::unique_ptr<msid_params> committed_config(msid_candump_reader &rd, const LogSession &first, const ReplayRequest &r)
{
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
        const int k = msid_can_recv(&rd.tr, fr, 64, 0);
        if (k < 0) break;
        for (int i = 0; i < k && !have_cfg; ++i, ++idx)
            if (idx >= first.begin && fr[i].id == r.base + MSID_CAN_ID_CFG &&
                msid_params_feed(cfg.get(), fr[i].data, fr[i].len, MSID_CAN_PROTO_VERSION) == 1 && idx == first.commit) {
                std::memcpy(got.get(), cfg.get(), sizeof *cfg);
                have_cfg = true;
            }
    }
    if (!have_cfg) throw Error("'" + r.log + "': the log changed while it was read");
    return got;
}

// The FRF request of the logged design (checked against the request's design when given) and options.
FrfRequest replay_request(const msid_params &got, const ReplayRequest &r)
{
    auto dd = device_design(got);
    if (dd->st != MSID_OK) throw Error("'" + r.log + "': the logged design is invalid: " + msid_strerror(dd->st));
    FrfRequest rq;
    if (r.design) {
        if (!same_coef(r.design->d, dd->d))
            throw Error("'" + r.log + "': the design in the log differs from '" + r.design_name + "'");
        msidjob::request_from_design(rq, *r.design);
    } else {
        msidjob::request_from_core_design(rq, dd->d);
    }
    if (r.options) r.options(rq);
    if (got.rate_hz && !dd->d.is_ct) rq.fs = got.rate_hz;
    return rq;
}

// Pass 3: the selected sessions' frames through the decoder, as live.
void decode_sessions(msid_candump_reader &rd, const std::vector<std::pair<uint64_t, uint64_t>> &ranges, CanAcq &acq,
                     const std::string &path)
{
    msid_can_frame fr[64];
    msid_candump_rewind(&rd);
    uint64_t idx = 0;
    size_t r = 0;
    for (;;) {
        const int k = msid_can_recv(&rd.tr, fr, 64, 0);
        if (k == -MSID_DAQ_E_EOF) break;
        if (k < 0) throw Error("'" + path + "': " + msid_can_error(&rd.tr));
        for (int i = 0; i < k; ++i, ++idx) {
            while (r < ranges.size() && idx >= ranges[r].second) ++r;
            if (r < ranges.size() && idx >= ranges[r].first) acq.feed(fr[i]);
        }
    }
}

}  // namespace

LogScan scan_can_log(const std::string &path, uint32_t base)
{
    Log L(path);
    return scan_sessions(L.rd, path, base);
}

std::string session_line(const LogSession &s, size_t i)
{
    return fmt("session %zu: %s .. %s, design crc 0x%08X (%u input(s), %u experiment(s), %u periods of %u), "
               "%llu run(s), %llu DONE, %llu sample frames",
               i + 1, log_time(s.t_begin).c_str(), log_time(s.t_end).c_str(), s.crc, s.n_inputs, s.n_experiments,
               s.periods, s.period, (unsigned long long)s.runs, (unsigned long long)s.dones,
               (unsigned long long)s.sample_frames);
}

ReplayResult replay_can_log(const ReplayRequest &r)
{
    const std::string &path = r.log;
    Log L(path);
    msid_candump_reader &rd = L.rd;

    // Pass 1: the sessions and the device's INFO; the selection.
    const LogScan sc = scan_sessions(rd, path, r.base);
    const size_t ns = sc.sessions.size();
    check_log(sc, path, r.base);
    const std::vector<size_t> sel = select_sessions(sc, r);
    std::vector<std::pair<uint64_t, uint64_t>> ranges;   // frames fed to the decoder
    uint64_t sample_frames = 0;
    for (size_t i : sel) {
        ranges.push_back({sc.sessions[i].begin, sc.sessions[i].end});
        sample_frames += sc.sessions[i].sample_frames;
    }

    // Pass 2: the configuration, the request.
    const auto got = committed_config(rd, sc.sessions[sel[0]], r);
    const FrfRequest rq = replay_request(*got, r);
    const uint32_t ny = sc.ny, nu = got->n_inputs, m = got->n_experiments;
    if (ny == 0 || ny > MSID_MAX_OUTPUTS) throw Error(fmt("'%s': the device reports %u outputs", path.c_str(), ny));
    if ((uint64_t)rq.skip + 2 > got->periods)
        throw Error(fmt(MSID_OPT("skip_periods") " %u leaves fewer than 2 of the %u periods", rq.skip, got->periods), 1,
                    msidutil::ErrorKind::usage);

    // Pass 3: decode. The history is sized by what the log can hold, not by the periods its upload asks
    // for (a 7 KB log must not size gigabytes): no experiment has more periods than the log has frames for.
    CanAcq acq;
    acq.iface = sc.iface;
    const uint64_t fit = sample_frames / ((uint64_t)got->period * msid_can_chunks(nu + ny, got->encoding, got->fd)) + 8;
    const uint64_t want = 4ull * got->periods * sel.size() + 8;
    acq.init(rq, nu, ny, m, got->periods, r.base, *got, r.window, (uint32_t)std::min<uint64_t>(fit < want ? fit : want, UINT32_MAX));
    decode_sessions(rd, ranges, acq, path);

    // The FRF and what the log gave and lacked.
    std::vector<std::string> notes;
    if (acq.dec.open) {
        notes.push_back(fmt("the log ends during experiment %u: its pending samples were flushed", acq.dec.exp + 1));
        check(msid_can_decoder_abort(&acq.dec), "decoder");
    }
    for (uint32_t e = 0; e < m; ++e)
        if (msid_meas_stats(acq.dec.cfg.meas, e) && acq.dec.cfg.meas->samples[e] == 0)
            throw Error(fmt("'%s' holds no samples of experiment %u of %u", path.c_str(), e + 1, m), 1,
                        msidutil::ErrorKind::data);
    if (sel.size() > 1) notes.push_back(fmt("%zu sessions of the same design pooled (--session N replays one)", sel.size()));
    msid_can_link_stats ls;
    msid_can_get_stats(&rd.tr, &ls);
    auto ln = can_loss_notes(acq.dec, ls);
    notes.insert(notes.end(), ln.begin(), ln.end());
    ReplayResult R;
    R.o = acq.job->finish(can_sources(acq, m), notes);
    Json acqj = can_acquisition_json(acq, ls, "candump", r.base, *got, got->crc);
    acqj["log"] = path;
    acqj["sessions_in_log"] = ns;
    Json sj = Json::array();
    for (size_t i : sel)
        sj.push_back({{"session", i + 1}, {"start", log_time(sc.sessions[i].t_begin)}, {"end", log_time(sc.sessions[i].t_end)}});
    acqj["sessions"] = sj;
    R.o.tail()["acquisition"] = acqj;
    const std::string which = sel.size() == 1 ? fmt("session %zu of %zu", sel[0] + 1, ns) : fmt("%zu of %zu sessions", sel.size(), ns);
    R.summary = fmt("%zu lines, %u x %u, %u experiment(s) replayed from %s (%s), %llu samples, %llu missing",
                    rq.bins.size(), ny, nu, m, path.c_str(), which.c_str(), (unsigned long long)acq.dec.cnt.samples,
                    (unsigned long long)acq.dec.cnt.samples_lost);
    return R;
}

}  // namespace msidacq
