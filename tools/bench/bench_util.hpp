// What the benchmarks of msid_bench share: the report writer, clocks, repeated timing, the machine
// line, the peers' directory and running a peer or a whole process.
#pragma once
#include <algorithm>
#include <string>
#include <vector>

#include "msid_bench.hpp"

namespace msidbench {

// Writes a benchmark's report: into the Report, and to the Sink at once.
class Writer {
public:
    Writer(const Sink &sink, Report &report) : sink_(sink), report_(report) {}
    void print(const char *f, ...) __attribute__((format(printf, 2, 3)));
    // A diagnostic line (without its '\n').
    void error(const std::string &line);
    void fail() { report_.status = 1; }

private:
    const Sink &sink_;
    Report &report_;
};

// A benchmark that writes into another's report as well, run with a report of its own.
template <class Result, class Request> Result with_report(void (*part)(Writer &, const Request &), const Request &rq,
                                                          const Sink &sink)
{
    Result res;
    Writer w(sink, res.report);
    part(w, rq);
    return res;
}

// Monotonic wall time [s].
double wall_s();
// CPU time of this process, all threads (std::clock) [s].
double process_cpu_s();
// CPU time of the calling thread [s]: on a shared machine the wall time can be several times the work.
double thread_cpu_s();

// Best time of fn() over repetitions lasting at least min_s (and >= 3 runs), after one warm-up run.
template <class F> double best_time(F fn, double min_s)
{
    fn();
    double best = 1e30;
    const double t_end = wall_s() + min_s;
    int reps = 0;
    while (reps < 3 || wall_s() < t_end) {
        const double t0 = wall_s();
        fn();
        best = std::min(best, wall_s() - t0);
        ++reps;
    }
    return best;
}

// "CPU model, N cores, kernel": the machine line every report starts with.
std::string machine();
// The directory holding the Python package msid_peers (the independent peers, tools/peers):
// $MSID_PEERS_DIR, else the source tree's.
std::string peers_dir();

// Run the shell command `cmd` (redirections included), its stdout appended to `out`: its exit
// status as pclose gives it, or -1 when it could not be started.
int capture(const std::string &cmd, std::string &out);

// Wall time of the whole shell command `cmd` (output discarded), the median of `reps` runs; -1
// when a run fails.
double process_time(const std::string &cmd, int reps);

// Write the bytes `s` to the file `path` (Error if it cannot).
void write_all(const std::string &path, const std::string &s);
// .npy v1.0 of an n x cols float64 matrix (C order).
std::string npy_image(const std::vector<double> &x, size_t n, size_t cols);

// Best wall and CPU (user + system, all threads) times of the process `exe args...` (args[0] is its
// name; exe a path, or a name looked up in PATH), stdout (and with `quiet` stderr: notes repeated at
// every run) to /dev/null, over >= 3 runs lasting
// >= min_s after one warm-up run; each best separately. posix_spawn (vfork semantics): the child
// starts without a copy of this process's page tables (a bench holds tens of MB of generated
// records), so the wall time is the child's own. Error when a run fails.
struct Times {
    double wall = 1e30, cpu = 1e30;
};
// min_runs: the timed runs at least; exit3_ok: exit status 3 (`msid fit`: the best iterate of a fit that did
// not converge, written) counts as a run.
Times time_process(const std::string &exe, const std::vector<std::string> &args, double min_s, bool quiet = false,
                   int min_runs = 3, bool exit3_ok = false);

// A new directory /tmp/<prefix>-XXXXXX (Error if it cannot be made).
std::string temp_dir(const char *prefix);

// Remove the directory `dir` and all in it (a diagnostic through `w` if that fails).
void remove_dir(Writer &w, const std::string &dir, const char *note);

}  // namespace msidbench
