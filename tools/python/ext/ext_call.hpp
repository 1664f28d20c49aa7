// msid._msid: how every call runs the host libraries without the GIL. One place decides what a long
// call owes its caller: Ctrl-C in the main thread ends it at the libraries' next checkpoint
// (msidutil::checkpoint, msid_cancel.hpp) with the KeyboardInterrupt the signal handler raised; the
// interpreter's exit ends every running call and waits for them (a daemon thread is not killed inside
// C++); the GIL is taken back by a plain call, never in a destructor (a thread that the exiting
// interpreter ends there would abort the process); and the FFTW planner lock is reentrant (a
// callback of msid.measure, which holds it, may run msid.frf) and waited for interruptibly.
#pragma once
#include "ext.hpp"
#include "msid_cancel.hpp"

#include <functional>
#include <optional>
#include <type_traits>

namespace msidpy {

struct CallOptions {
    bool jobs = false;           // hold the FFTW planner lock (job_lock()) while the work runs
    bool interruptible = true;   // the work's checkpoints see Ctrl-C (msid.measure has its own stop)
    const char *what = "the call";   // named in the message of an interrupted wait
};

// One call into the host libraries (construct with the GIL held).
class Call {
public:
    explicit Call(const CallOptions &o);
    ~Call();
    Call(const Call &) = delete;
    Call &operator=(const Call &) = delete;
    // Release the GIL, run `work` with the call's token installed (and the planner lock held when
    // asked), take the GIL back, and raise: the Python exception that interrupted it, or the C++
    // exception it threw (module.cpp translates it).
    void run(const std::function<void()> &work);
    // Whether the interpreter is exiting (its atexit handlers ran): a running call stops, and a
    // measurement's progress callable is not called any more.
    static bool shutting_down();

private:
    struct Token;
    CallOptions o_;
    PyThreadState *ts_ = nullptr;
    std::unique_ptr<Token> tok_;
    bool registered_ = false;
    void leave();
};

// Run f() as one Call and return its value.
template <class F>
auto without_gil(const CallOptions &o, F &&f) -> decltype(f())
{
    using R = decltype(f());
    Call c(o);
    if constexpr (std::is_void_v<R>) {
        c.run([&] { f(); });
    } else {
        std::optional<R> r;
        c.run([&] { r.emplace(f()); });
        return std::move(*r);
    }
}

// The FFTW planner lock (FFTW's planner is not thread-safe): reentrant on one thread, waited for with
// the GIL released. release_later() frees an object whose destructor plans (an FrfJob) now when the
// lock is free or this thread's, else hands it to the holder, which frees it when it lets go: a
// destructor that runs with the GIL held never waits.
class JobLock {
public:
    // Take it; while another thread holds it, ask `interrupted` every 20 ms (true: throw Cancelled).
    void lock(const std::function<bool()> &interrupted, const char *what);
    void unlock();
    void release_later(std::function<void()> free);
};
JobLock &job_lock();

// The planner lock for a scope inside Call::run (the call's token asked while waiting for it).
class JobGuard {
public:
    explicit JobGuard(const char *what);
    ~JobGuard();
    JobGuard(const JobGuard &) = delete;
    JobGuard &operator=(const JobGuard &) = delete;
};

// Called by Python's atexit (module.cpp): stop every running call and wait for them, at most a few
// seconds, with the GIL released.
void shutdown_calls();

// The progress of every call so far, per step (msidutil::Step), for the interrupt tests.
py::dict progress_counts();
// Count `n` units of `s` done by work that runs with the GIL held (no token is asked there).
void count_progress(msidutil::Step s, uint64_t n);
// For the interrupt tests: SIGINT (as by Ctrl-C) once `at` more units of `step` (a name of
// progress_counts) are done, from the checkpoint that counts them; an empty `step` disarms it.
void interrupt_at(const std::string &step, uint64_t at);
// How many SIGINTs the wrapper of a running call's handler has counted (the interrupt tests: once it
// moved, every checkpoint of the call stops).
uint64_t sigints_seen();

}  // namespace msidpy
