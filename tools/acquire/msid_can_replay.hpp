// `msid can replay`: a candump log of an msid-can/1 session through the decoder of the live
// measurement (msid_can_acq.hpp): the same frames give the same FRF bits. A log may hold several
// sessions (a committed design upload and the runs made with it); one design's sessions are pooled, a
// log of several designs needs a selection (one session, or a time range). docs/can-protocol.md.
#pragma once
#include "msid_acquire.hpp"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace msidacq {

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

// A pass over a whole log: its sessions at `base`, the device's INFO (version, outputs), the interface.
struct LogScan {
    std::vector<LogSession> sessions;
    bool have_info = false, have_upload = false;
    uint32_t ny = 0, version = 0;
    uint64_t frames = 0;
    std::string iface;
};
LogScan scan_can_log(const std::string &path, uint32_t base);

// A log timestamp as candump writes it, "1700000000.123456" (or "(1700000000.123456)"), in ns since the
// epoch; UsageError naming `what` otherwise. log_time() writes one back (microseconds).
uint64_t parse_log_time(const std::string &v, const char *what);
std::string log_time(uint64_t ns);
// "session 2: T0 .. T1, design crc 0x..., ... sample frames" (`i` counted from 0).
std::string session_line(const LogSession &s, size_t i);

struct ReplayRequest {
    std::string log;                       // the candump log
    uint32_t base = 0x200;                 // the device's base identifier
    uint32_t window = 16;                  // reorder window, frames
    uint32_t session = 0;                  // replay this session only (from 1); 0: by time range
    uint64_t since = 0, until = UINT64_MAX;   // the sessions that start at or after / end at or before (ns)
    std::shared_ptr<const msidfmt::Design> design;   // optional: must be the log's (its file name in design_name)
    std::string design_name;
    // The estimating options (skip, transient, alpha, detection lines), set on the request the log's
    // design gives; may throw UsageError.
    std::function<void(FrfRequest &)> options;
};

struct ReplayResult {
    FrfOutcome o;              // msid-frf/1 with its `acquisition` block (log, sessions) and the notes
    std::string summary;       // "N lines, ny x nu, m experiment(s) replayed from LOG (session 1 of 2), ..."
};

// Replay the selected sessions of a log. Throws Error (the log: no INFO, another protocol version, no
// upload, no such session, designs that cannot be pooled, no samples) or UsageError (the request).
ReplayResult replay_can_log(const ReplayRequest &r);

}  // namespace msidacq
