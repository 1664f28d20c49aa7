// Ctrl-C and SIGTERM during a measurement: they set a flag that the acquisition polls (through
// Progress::stop), so the FRF of the complete periods is kept and the exit status says 128 + signal.
#pragma once
#include <csignal>

namespace msidcli {

// SIGINT and SIGTERM set the flag while this lives (installed for the scope, the old handlers back after).
class StopOnSignal {
public:
    StopOnSignal();
    ~StopOnSignal();
    StopOnSignal(const StopOnSignal &) = delete;
    StopOnSignal &operator=(const StopOnSignal &) = delete;
private:
    struct sigaction old_int_{}, old_term_{};
};
bool measure_stop_requested();
// For the whole command: SIGINT, SIGTERM, SIGHUP and SIGPIPE, where not ignored, remove the temporary
// files being written (msid_partial_file.hpp) and then end the process by the same signal, as before:
// no OUT.tmp.PID is left by a command ended from outside.
void remove_partials_on_fatal_signals();
int measure_stop_signal();     // the signal that asked (0: none)

}  // namespace msidcli
