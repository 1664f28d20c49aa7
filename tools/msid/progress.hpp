// Live progress of `msid measure` (docs/measure.md): on a terminal one line rewritten in place
// (at most 10 times a second), otherwise one line per event (an experiment starts or ends, a
// period is acquired or rejected, samples are lost, link errors). Goes to stderr by default so
// that stdout keeps the results.
#pragma once
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

namespace msidcli {

// What the acquisition knows at one moment.
struct ProgressState {
    uint32_t exp = 0, n_exp = 0;           // current experiment (1-based) of n_exp
    uint32_t periods = 0, periods_target = 0;  // complete periods acquired in this experiment, of the target
    uint64_t periods_total = 0;            // complete periods acquired in all experiments
    uint64_t rejected = 0;                 // periods rejected so far (gaps, non-finite, transient)
    uint64_t lost = 0;                     // samples lost (drops, overruns)
    uint64_t link_errors = 0;              // bus errors / retried requests
    double snr_db = NAN;                   // running output SNR per period (dB), NaN before 2 periods
    double eta_s = NAN;                    // estimated seconds left, NaN when unknown
};

class Progress {
public:
    // out: where to write; tty: rewrite one line (else one line per event); quiet: nothing at all;
    // prefix: the command naming each line ("msid measure", "msid can", "msid modbus").
    Progress(FILE *out, bool tty, bool quiet = false, std::string prefix = "msid measure");
    ~Progress();
    // A new state: redrawn on a terminal (rate-limited), a line when an event happened otherwise.
    void update(const ProgressState &s);
    // A line of its own (the live line is finished first).
    void note(const std::string &msg);
    // Finish the live line (a terminal gets its newline).
    void done();
    static std::string format(const ProgressState &s);

private:
    FILE *out_;
    std::string prefix_;
    bool tty_, quiet_, live_ = false;
    double last_draw_ = -1;
    ProgressState last_{};
    bool have_last_ = false;
};

// isatty(fileno(f)) and TERM is not "dumb".
bool is_terminal(FILE *f);

}  // namespace msidcli
