// Stop requests of a measurement (stop_signal.hpp).
#include "stop_signal.hpp"

#include "msid_partial_file.hpp"

namespace msidcli {

static volatile sig_atomic_t g_stop_signal = 0;

static void on_stop_signal(int sig) { g_stop_signal = sig; }

StopOnSignal::StopOnSignal()
{
    g_stop_signal = 0;
    struct sigaction sa{};
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;   // no SA_RESTART: a sleep or a blocking read returns at once
    sigaction(SIGINT, &sa, &old_int_);
    sigaction(SIGTERM, &sa, &old_term_);
}

StopOnSignal::~StopOnSignal()
{
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
}

// The default action once the temporaries are gone: SA_RESETHAND put it back, and the signal raised here
// is blocked until the handler returns, then ends the process (its exit status names the signal).
static void on_fatal_signal(int sig)
{
    msidutil::remove_partial_files();
    raise(sig);
}

void remove_partials_on_fatal_signals()
{
    for (int sig : {SIGINT, SIGTERM, SIGHUP, SIGPIPE}) {
        struct sigaction old{};
        if (sigaction(sig, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) continue;   // nohup, a shell's trap
        struct sigaction sa{};
        sa.sa_handler = on_fatal_signal;
        sigemptyset(&sa.sa_mask);
        sa.sa_flags = SA_RESETHAND;
        sigaction(sig, &sa, nullptr);
    }
}

bool measure_stop_requested() { return g_stop_signal != 0; }
int measure_stop_signal() { return (int)g_stop_signal; }

}  // namespace msidcli
