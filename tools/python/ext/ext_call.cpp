// msid._msid: calls without the GIL, their interrupt token, the planner lock and the exit (ext_call.hpp).
#include "ext_call.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cxxabi.h>
#include <deque>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

namespace msidpy {

using Clock = std::chrono::steady_clock;
using msidutil::Step;

namespace {

// How often the main thread's token asks Python for a pending signal: a check takes the GIL, which
// another Python thread may hold for up to its switch interval (5 ms); 20 ms keeps an interrupt well
// within 0.2 s and the work's cost of asking below 1%.
constexpr auto POLL = std::chrono::milliseconds(20);
// How long the interpreter's exit waits for the running calls to stop.
constexpr auto EXIT_WAIT = std::chrono::seconds(10);

std::atomic<bool> g_exiting{false};
std::atomic<uint64_t> g_progress[(size_t)Step::count_];
// The interrupt tests' hook: SIGINT as if pressed once the count of g_armed_step reaches g_armed_at
// (count_ : none), so that a test places the signal by the work done, not by a watcher thread's timing.
std::atomic<uint32_t> g_armed_step{(uint32_t)Step::count_};
std::atomic<uint64_t> g_armed_at{0};

void add_progress(Step s, uint64_t n)
{
    const uint64_t now = g_progress[(size_t)s].fetch_add(n, std::memory_order_relaxed) + n;
    uint32_t armed = (uint32_t)s;
    if (g_armed_step.load(std::memory_order_relaxed) == armed && now >= g_armed_at.load(std::memory_order_relaxed) &&
        g_armed_step.compare_exchange_strong(armed, (uint32_t)Step::count_))
        ::raise(SIGINT);   // the real signal, on this thread: through the wrapper (below) and Python's C handler
}

// ---- SIGINT seen without the GIL ----
// Python's C-level handler only marks a signal; its Python handler runs when the main thread asks
// (PyErr_CheckSignals, with the GIL: every POLL), and a loaded machine may leave the main thread
// unscheduled for long while the call's other threads work on. A call on the main thread whose
// SIGINT handler is Python's default (it raises KeyboardInterrupt) does not wait for that question:
// while it runs, Python's C handler is wrapped by one that also counts the signal, and every
// checkpoint of the call's threads sees the count change and stops; the main thread then asks
// Python, whose handler raises. The work done after the signal is the blocks in flight when it
// arrived, whatever the load. A handler installed by Python code during the call (signal.signal in
// a callback) replaces the wrapper and is asked every POLL as before.
std::atomic<uint64_t> g_sigints{0};
struct sigaction g_prev_sigint;   // Python's C handler, chained by the wrapper
int g_wrap_depth = 0;             // the main thread's nested calls (changed with the GIL held)

void on_sigint(int sig, siginfo_t *info, void *ctx)
{
    g_sigints.fetch_add(1);
    if (g_prev_sigint.sa_flags & SA_SIGINFO)
        g_prev_sigint.sa_sigaction(sig, info, ctx);
    else if (g_prev_sigint.sa_handler != SIG_DFL && g_prev_sigint.sa_handler != SIG_IGN)
        g_prev_sigint.sa_handler(sig);
}

// With the GIL held on the main thread: whether Python's SIGINT handler is its default, and if so
// the wrapper installed (once for nested calls). False: the call asks every POLL only.
bool wrap_sigint()
{
    PyObject *sig = PyImport_ImportModule("signal");
    if (!sig) {
        PyErr_Clear();
        return false;
    }
    PyObject *h = PyObject_CallMethod(sig, "getsignal", "i", SIGINT);
    PyObject *d = PyObject_GetAttrString(sig, "default_int_handler");
    const bool dflt = h && d && h == d;
    Py_XDECREF(h);
    Py_XDECREF(d);
    Py_DECREF(sig);
    PyErr_Clear();
    if (!dflt) return false;
    if (g_wrap_depth == 0) {
        struct sigaction cur, w;
        if (sigaction(SIGINT, nullptr, &cur) != 0) return false;
        if (!(cur.sa_flags & SA_SIGINFO) && (cur.sa_handler == SIG_DFL || cur.sa_handler == SIG_IGN)) return false;
        g_prev_sigint = cur;
        w = cur;
        w.sa_sigaction = on_sigint;
        w.sa_flags = cur.sa_flags | SA_SIGINFO;
        if (sigaction(SIGINT, &w, nullptr) != 0) return false;
    }
    ++g_wrap_depth;
    return true;
}

// The call that wrapped it ends: Python's handler back when it was the last and nothing replaced it.
void unwrap_sigint()
{
    if (--g_wrap_depth) return;
    struct sigaction cur;
    if (sigaction(SIGINT, nullptr, &cur) == 0 && (cur.sa_flags & SA_SIGINFO) && cur.sa_sigaction == on_sigint)
        sigaction(SIGINT, &g_prev_sigint, nullptr);
}

}  // namespace

uint64_t sigints_seen() { return g_sigints.load(); }

namespace {

// The running calls: the exit waits until each has taken the GIL back.
std::mutex g_run_mu;
std::condition_variable g_run_cv;
size_t g_running = 0;

unsigned long main_thread_ident()
{
    static const unsigned long id = [] {
        py::gil_scoped_acquire gil;
        return py::module_::import("threading").attr("main_thread")().attr("ident").cast<unsigned long>();
    }();
    return id;
}

}  // namespace

// The token of one call: counts progress; on the thread that runs the interpreter's signal handlers
// asks for a pending signal every POLL; stops every call when the interpreter exits.
struct Call::Token : msidutil::Cancel {
    PyThreadState **ts;                    // the calling thread's state while the GIL is released
    std::thread::id owner = std::this_thread::get_id();
    bool signals;                          // the main thread: Python runs signal handlers there
    bool interruptible;
    bool wrapped = false;                  // SIGINT counted by the wrapper: a count past `sigints0` stops
    uint64_t sigints0 = 0;
    Clock::time_point next = Clock::now() + POLL;
    std::atomic<bool> stop{false};
    PyObject *type = nullptr, *value = nullptr, *tb = nullptr;   // what the signal handler raised

    Token(PyThreadState **t, bool sig, bool intr) : ts(t), signals(sig), interruptible(intr) {}

    bool proceed_or_stop(Step s, uint64_t n) override
    {
        if (n) add_progress(s, n);
        return interruptible && interrupted(false);
    }

    // Ask now (`now`) or when POLL has passed since the last question.
    bool interrupted(bool now)
    {
        if (stop.load(std::memory_order_relaxed)) return true;
        if (g_exiting.load(std::memory_order_relaxed)) return stop = true;
        if (wrapped && g_sigints.load() != sigints0) return stop = true;   // any of the call's threads
        if (!signals || std::this_thread::get_id() != owner || !*ts) return false;
        const Clock::time_point t = Clock::now();
        if (!now && t < next) return false;
        next = t + POLL;
        PyEval_RestoreThread(*ts);   // the main thread: never ended by the exiting interpreter
        if (PyErr_CheckSignals() != 0) {
            PyErr_Fetch(&type, &value, &tb);
            stop = true;
        }
        *ts = PyEval_SaveThread();
        return stop;
    }
};

bool Call::shutting_down() { return g_exiting.load(std::memory_order_relaxed); }

Call::Call(const CallOptions &o) : o_(o)
{
    tok_ = std::make_unique<Token>(&ts_, PyThread_get_thread_ident() == main_thread_ident(), o.interruptible);
    if (tok_->signals && tok_->interruptible && wrap_sigint()) {
        tok_->wrapped = true;
        tok_->sigints0 = g_sigints.load();
    }
    std::lock_guard<std::mutex> g(g_run_mu);
    ++g_running;
    registered_ = true;
}

void Call::leave()
{
    if (!registered_) return;
    registered_ = false;
    if (tok_->wrapped) unwrap_sigint();
    std::lock_guard<std::mutex> g(g_run_mu);
    --g_running;
    g_run_cv.notify_all();
}

Call::~Call()
{
    leave();
    // a signal handler's exception that was never raised (the work failed first): dropped
    Py_XDECREF(tok_->type);
    Py_XDECREF(tok_->value);
    Py_XDECREF(tok_->tb);
}

void Call::run(const std::function<void()> &work)
{
    std::exception_ptr err;
    ts_ = PyEval_SaveThread();
    try {
        msidutil::CancelScope scope(tok_.get());
        if (o_.jobs) {
            job_lock().lock([&] { return tok_->interrupted(true); }, o_.what);
            try {
                work();
            } catch (...) {
                job_lock().unlock();
                throw;
            }
            job_lock().unlock();
        } else {
            work();
        }
    } catch (abi::__forced_unwind &) {
        throw;   // this thread is being ended: let it go
    } catch (...) {
        err = std::current_exception();
    }
    PyThreadState *ts = ts_;
    ts_ = nullptr;
    PyEval_RestoreThread(ts);   // a plain call: an exiting interpreter may end this thread here
    leave();
    if (tok_->stop) {
        if (tok_->type) {
            PyErr_Restore(tok_->type, tok_->value, tok_->tb);
            tok_->type = tok_->value = tok_->tb = nullptr;
            throw py::error_already_set();
        }
        if (g_exiting) {
            PyErr_SetString(PyExc_KeyboardInterrupt, "the interpreter is exiting");
            throw py::error_already_set();
        }
        if (tok_->wrapped && PyErr_CheckSignals() != 0) throw py::error_already_set();   // the handler raised
    }
    if (err) std::rethrow_exception(err);
}

// ---- the planner lock ----

namespace {
struct LockState {
    std::mutex mu;
    std::condition_variable cv;
    std::thread::id owner;
    unsigned depth = 0;
    std::deque<std::function<void()>> later;
};
LockState &lock_state()
{
    static LockState s;
    return s;
}
}  // namespace

void JobLock::lock(const std::function<bool()> &interrupted, const char *what)
{
    LockState &s = lock_state();
    std::unique_lock<std::mutex> g(s.mu);
    const std::thread::id me = std::this_thread::get_id();
    if (s.depth && s.owner == me) {
        ++s.depth;
        return;
    }
    while (s.depth) {
        s.cv.wait_for(g, POLL);
        if (!s.depth) break;
        g.unlock();   // the check may take the GIL: never while holding the lock's own mutex
        const bool stop = interrupted();
        g.lock();
        if (stop)
            throw msidutil::Cancelled{std::string(what) + " waited for another msid call (msid.measure or msid.frf "
                                                          "in another thread holds FFTW's planner)"};
    }
    s.owner = me;
    s.depth = 1;
}

void JobLock::unlock()
{
    LockState &s = lock_state();
    std::unique_lock<std::mutex> g(s.mu);
    if (--s.depth) return;
    while (!s.later.empty()) {   // what other threads freed while this one held the lock
        std::function<void()> f = std::move(s.later.front());
        s.later.pop_front();
        ++s.depth;
        g.unlock();
        f();
        g.lock();
        --s.depth;
    }
    s.owner = std::thread::id();
    s.cv.notify_all();
}

void JobLock::release_later(std::function<void()> free)
{
    LockState &s = lock_state();
    std::unique_lock<std::mutex> g(s.mu);
    if (s.depth && s.owner != std::this_thread::get_id()) {
        s.later.push_back(std::move(free));
        return;
    }
    const std::thread::id prev = s.owner;
    s.owner = std::this_thread::get_id();
    ++s.depth;
    g.unlock();
    free();
    g.lock();
    if (--s.depth == 0) {
        s.owner = prev;
        s.cv.notify_all();
    }
}

JobLock &job_lock()
{
    static JobLock l;
    return l;
}

JobGuard::JobGuard(const char *what)
{
    job_lock().lock(
        [] {
            msidutil::Cancel *c = msidutil::current_cancel();
            return c && c->proceed_or_stop(Step::solves, 0);
        },
        what);
}
JobGuard::~JobGuard() { job_lock().unlock(); }

void shutdown_calls()
{
    g_exiting = true;
    py::gil_scoped_release nogil;   // the main thread at exit: it is not ended in a destructor
    std::unique_lock<std::mutex> g(g_run_mu);
    g_run_cv.wait_for(g, EXIT_WAIT, [] { return g_running == 0; });
}

void count_progress(Step s, uint64_t n) { add_progress(s, n); }

void interrupt_at(const std::string &step, uint64_t at)
{
    static const char *const NAMES[] = {"rows", "lines", "orders", "iterations", "solves", "document"};
    if (step.empty()) {   // disarmed
        g_armed_step = (uint32_t)Step::count_;
        return;
    }
    for (size_t k = 0; k < (size_t)Step::count_; ++k)
        if (step == NAMES[k]) {
            g_armed_at = g_progress[k].load() + at;
            g_armed_step = (uint32_t)k;
            return;
        }
    throw std::invalid_argument("no step '" + step + "'");
}

py::dict progress_counts()
{
    static const char *const NAMES[] = {"rows", "lines", "orders", "iterations", "solves", "document"};
    static_assert(sizeof NAMES / sizeof NAMES[0] == (size_t)Step::count_, "a name per step");
    py::dict d;
    for (size_t k = 0; k < (size_t)Step::count_; ++k) d[NAMES[k]] = g_progress[k].load(std::memory_order_relaxed);
    return d;
}

}  // namespace msidpy
