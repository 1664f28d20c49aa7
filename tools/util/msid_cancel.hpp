// A caller's request to give up long host work early (Ctrl-C in the Python extension, a stop button
// of a GUI): one token per call, asked by the host libraries at named checkpoints between steps of
// bounded cost (a block of samples, a line, an order of a scan, an iteration), never inside the C core.
// The libraries do not know who asks: the command line installs no token (SIGINT ends the process),
// the Python extension installs one that sees a pending KeyboardInterrupt.
#pragma once
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <system_error>
#include <thread>


namespace msidutil {

// What a checkpoint has just finished: the unit in which a caller counts a long call's progress.
enum class Step : uint32_t {
    rows,         // samples of a record pushed into the core (per block of at most 256 KiB)
    lines,        // frequency lines of a local-polynomial or ETFE estimate
    orders,       // orders of an order scan, each fitted and scored
    iterations,   // iterations of an iterative fit (ml, lmfd refinement, multi)
    solves,       // linear-algebra steps of one fit (a decomposition, a basis column block)
    document,     // lines of a result document built, turned into Python objects or freed (per chunk)
    count_
};

class Cancel {
public:
    virtual ~Cancel() = default;
    // `n` more units of `step` are done; true asks the work to stop. Called at every checkpoint, from
    // the thread that installed the token and from the worker threads a library started for its work
    // (Scope below): cheap, and safe from any thread.
    virtual bool proceed_or_stop(Step step, uint64_t n) = 0;
};

// Thrown at a checkpoint once the token asked to stop: the work is abandoned, nothing half-built is
// returned. Not a std::exception on purpose: the libraries' handlers that turn a failed step into
// a result (an order of a scan that gives no model, a start that fails) do not catch it; only the
// caller that installed the token does.
struct Cancelled {
    std::string where;   // the work that was stopped ("the order scan")
    const char *what() const noexcept { return where.c_str(); }
};

// The calling thread's token for the scope's lifetime (nullptr: none); scopes nest, the innermost
// counts. A library that starts threads installs the token of the thread that started them in each.
class CancelScope {
public:
    explicit CancelScope(Cancel *c);
    ~CancelScope();
    CancelScope(const CancelScope &) = delete;
    CancelScope &operator=(const CancelScope &) = delete;

private:
    Cancel *prev_;
};

// This thread's token (nullptr: none).
Cancel *current_cancel();

// A checkpoint: `n` units of `step` are done; throws Cancelled naming `where` (the work, e.g.
// "the order scan") when this thread's token asks to stop. Without a token: nothing.
void checkpoint(Step step, uint64_t n, const char *where);

// One long step without checkpoints of its own (a large dense decomposition): with a token installed,
// `work` runs on a thread of its own while this thread asks the token every few milliseconds. On a
// stop the step is abandoned: it finishes on its thread, on the data it owns (`work` must hold its
// inputs by value), its result is dropped, and Cancelled is thrown here at once. Without a token (the
// command line) or without a thread to be had, `work` runs here, as a plain call.
template <class R>
R abandonable(std::function<R()> work, Step step, const char *where)
{
    if (!current_cancel()) return work();
    checkpoint(step, 1, where);   // the step began (a caller counts it: one when begun, two when done)
    struct Shared {
        std::mutex mu;
        std::condition_variable cv;
        std::optional<R> value;
        std::exception_ptr err;
        bool done = false;
    };
    auto sh = std::make_shared<Shared>();
    auto w = std::make_shared<std::function<R()>>(std::move(work));
    try {
        std::thread([sh, w] {
            std::optional<R> v;
            std::exception_ptr e;
            try {
                v.emplace((*w)());
            } catch (...) {
                e = std::current_exception();
            }
            std::lock_guard<std::mutex> g(sh->mu);
            sh->value = std::move(v);
            sh->err = e;
            sh->done = true;
            sh->cv.notify_all();
        }).detach();
    } catch (const std::system_error &) {
        return (*w)();
    }
    std::unique_lock<std::mutex> g(sh->mu);
    while (!sh->done) {
        sh->cv.wait_for(g, std::chrono::milliseconds(5));
        if (sh->done) break;
        g.unlock();
        checkpoint(step, 0, where);   // throws Cancelled: the thread finishes alone
        g.lock();
    }
    if (sh->err) std::rethrow_exception(sh->err);
    g.unlock();
    checkpoint(step, 1, where);   // the step is done
    return std::move(*sh->value);
}

}  // namespace msidutil
