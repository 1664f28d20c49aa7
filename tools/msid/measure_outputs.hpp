// The products of `msid measure` beside frf.json: the model (msid fit in-process) and the plots
// (the Python package msid: `python3 -m msid.plot`, `python3 -m msid.report`).
#pragma once
#include <string>
#include <sys/types.h>
#include <vector>

namespace msidcli {

// Remove the files a previous run left in OUTDIR (model.json, bode.png, bode.svg, report.html,
// validation.json) so that the directory describes one run.
void clear_previous_outputs(const std::string &outdir);

// `msid fit --method M --order N|auto FRF -o MODEL`; "" on success, else the error message.
// A fit that ran out of iterations still writes its model ("converged": false) and returns "".
std::string fit_model(const std::string &frf, const std::string &model, const std::string &method,
                      const std::string &order, bool quiet);

// stdout to /dev/null for the scope (msid fit and validate print their tables there).
class SilenceStdout {
public:
    explicit SilenceStdout(bool on);
    ~SilenceStdout();
    SilenceStdout(const SilenceStdout &) = delete;
    SilenceStdout &operator=(const SilenceStdout &) = delete;
private:
    int saved_ = -1;
};

// OUTDIR/bode.png, bode.svg (model overlay when `model` is not empty) and report.html (which shows
// `command_line` when not empty). Never fails: returns "wrote ..." or one line saying the plots were
// skipped and why.
std::string make_plots(const std::string &outdir, const std::string &frf, const std::string &model,
                       const std::string &command_line = "");

// argv[0..argc-1] as one shell line ("msid measure --device ... -o 'my dir'"), argv[0] shown as "msid".
std::string shell_line(int argc, char **argv);

// Start argv (PATH lookup) with the environment plus `env` ("K=V"), its stdout and stderr on a pipe
// (*out, to read). detach: own process group, SIGTERM when this process dies. -1 if it cannot start.
pid_t spawn_piped(const std::vector<std::string> &argv, const std::vector<std::string> &env, bool detach, int *out);

// Run argv (PATH lookup) with the environment plus `env` ("K=V"); returns the exit status
// (-1: could not run) and the combined stdout/stderr in `out`.
int run_capture(const std::vector<std::string> &argv, const std::vector<std::string> &env, std::string &out);

// PYTHONPATH with the source tree's tools/python first (the installed package otherwise).
std::string python_path();

}  // namespace msidcli
