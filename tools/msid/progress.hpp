// Live progress of `msid measure` (docs/measure.md): on a terminal one line rewritten in place
// (at most 10 times a second), otherwise one line per event (an experiment starts or ends, a
// period is acquired or rejected, samples are lost, link errors). Goes to stderr by default so
// that stdout keeps the results.
// It is the acquisition's Control (tools/acquire): its stop requests are Ctrl-C and SIGTERM
// (StopOnSignal).
#pragma once
#include "msid_acquire.hpp"

#include <cstdint>
#include <cstdio>
#include <string>

namespace msidcli {

using msidacq::ProgressState;

class Progress : public msidacq::Control {
public:
    // out: where to write; tty: rewrite one line (else one line per event); quiet: nothing at all;
    // prefix: the command naming each line ("msid measure", "msid can", "msid modbus").
    Progress(FILE *out, bool tty, bool quiet = false, std::string prefix = "msid measure");
    ~Progress() override;
    // A new state: redrawn on a terminal (rate-limited), a line when an event happened otherwise.
    void update(const ProgressState &s) override;
    // A line of its own (the live line is finished first).
    void note(const std::string &msg) override;
    // Finish the live line (a terminal gets its newline).
    void done() override;
    // The signal that asked to stop (StopOnSignal), 0 while none did.
    int stop() override;
    static std::string format(const ProgressState &s);

private:
    FILE *out_;
    std::string prefix_;
    bool tty_, quiet_, live_ = false;
    double last_draw_ = -1;
    double last_event_ = -1e9;   // the last line written for a change of counts (not a terminal)
    ProgressState last_{};
    bool have_last_ = false;
};

// isatty(fileno(f)) and TERM is not "dumb".
bool is_terminal(FILE *f);

}  // namespace msidcli
