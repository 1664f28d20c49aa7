// Stop requests of a measurement (stop_signal.hpp).
#include "stop_signal.hpp"

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

bool measure_stop_requested() { return g_stop_signal != 0; }
int measure_stop_signal() { return (int)g_stop_signal; }

}  // namespace msidcli
