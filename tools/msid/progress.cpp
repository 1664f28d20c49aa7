// Live progress of `msid measure` (progress.hpp).
#include "progress.hpp"
#include "cli_util.hpp"
#include "stop_signal.hpp"

#include <cstdlib>
#include <cstring>
#include <ctime>
#include <unistd.h>

namespace msidcli {

static double mono_s()
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

bool is_terminal(FILE *f)
{
    const char *term = std::getenv("TERM");
    return isatty(fileno(f)) && !(term && !std::strcmp(term, "dumb"));
}

Progress::Progress(FILE *out, bool tty, bool quiet, std::string prefix)
    : out_(out), prefix_(std::move(prefix)), tty_(tty), quiet_(quiet) {}

Progress::~Progress() { done(); }

std::string Progress::format(const ProgressState &s)
{
    std::string r = fmt("experiment %u/%u: %u/%u periods acquired, %llu rejected, %llu samples lost, %llu link errors",
                        s.exp, s.n_exp, s.periods, s.periods_target, (unsigned long long)s.rejected,
                        (unsigned long long)s.lost, (unsigned long long)s.link_errors);
    if (std::isfinite(s.lateness_p99_s))
        r += fmt(", lateness p99 %.2g ms, %llu missed tick(s)", 1e3 * s.lateness_p99_s, (unsigned long long)s.missed_ticks);
    if (std::isfinite(s.snr_db)) r += fmt(", SNR %.1f dB", s.snr_db);
    if (std::isfinite(s.eta_s)) r += fmt(", ETA %.0f s", std::ceil(s.eta_s));
    return r;
}

void Progress::update(const ProgressState &s)
{
    if (quiet_) return;
    // a new experiment or period is an event of its own; a change of the loss and error counts is one at most
    // once a second (a link that fails every tick must not fill the log)
    const bool milestone = !have_last_ || s.exp != last_.exp || s.periods != last_.periods;
    const bool counts = have_last_ && (s.rejected != last_.rejected || s.lost != last_.lost ||
                                       s.link_errors != last_.link_errors || s.missed_ticks != last_.missed_ticks);
    const double t_now = mono_s();
    const bool event = milestone || (counts && (tty_ || t_now - last_event_ >= 1.0));
    if (event && !tty_) last_event_ = t_now;
    if (tty_) {
        const double now = mono_s();
        if (!event && now - last_draw_ < 0.1) return;
        if (event && now - last_draw_ < 0.1 && have_last_ && s.exp == last_.exp && s.periods != s.periods_target) {
            last_ = s;   // drawn on the next update
            return;
        }
        last_draw_ = now;
        std::fprintf(out_, "\r%s\033[K", format(s).c_str());
        live_ = true;
    } else if (event) {
        // every acquired period is an event of its own, also when one poll brought several
        ProgressState k = s;
        const bool same = have_last_ && s.exp == last_.exp;
        for (k.periods = same && s.periods > last_.periods ? last_.periods + 1 : s.periods; k.periods < s.periods; ++k.periods)
            std::fprintf(out_, "%s: %s\n", prefix_.c_str(), format(k).c_str());
        std::fprintf(out_, "%s: %s\n", prefix_.c_str(), format(s).c_str());
    }
    std::fflush(out_);
    last_ = s;
    have_last_ = true;
}

void Progress::note(const std::string &msg)
{
    if (quiet_) return;
    done();
    std::fprintf(out_, "%s: %s\n", prefix_.c_str(), msg.c_str());
    std::fflush(out_);
}

void Progress::done()
{
    if (live_) {
        std::fprintf(out_, "\r%s\033[K\n", format(last_).c_str());
        std::fflush(out_);
        live_ = false;
    }
}

int Progress::stop() { return measure_stop_signal(); }

}  // namespace msidcli
