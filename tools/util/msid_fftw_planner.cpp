#include "msid_fftw_planner.hpp"

#include "msid/msid_fft_fftw.h"

#include <exception>
#include <map>
#include <mutex>
#include <system_error>
#include <thread>

namespace msidutil {

namespace {
std::mutex g_mu;                  // guards g_thread
// the warm-up, joinable until fftw_planner_ready(); never destroyed: a process that ends on an
// error before it was joined must not meet std::thread's destructor (std::terminate)
std::thread *g_thread = nullptr;
// The warm plan, kept to the exit (reachable: not a leak); FFTW's planner keeps what it learnt
// (its solvers and the problem's solution) and the twiddles while a plan of the length lives.
msid_fft_fftw g_plan{};
}  // namespace

void fftw_warmup_start(uint32_t period)
{
    std::lock_guard<std::mutex> lk(g_mu);
    if (g_thread) return;
    try {
        // a failed plan (a period out of range, no memory) leaves g_plan zeroed: the job then
        // plans, and reports, as without a warm-up
        g_thread = new std::thread([period] { (void)msid_fft_fftw_create(&g_plan, period, MSID_FFTW_LINES); });
    } catch (const std::exception &) {   // no thread (std::system_error) or no memory: no warm-up
    }
}

void fftw_planner_ready()
{
    std::lock_guard<std::mutex> lk(g_mu);
    if (g_thread && g_thread->joinable()) g_thread->join();
}

// FFTW's planner is not thread-safe: every plan of the shared_*_plan functions is made under this
// one lock (a fit may plan on two threads, e.g. cissim's correlations beside its regression).
static std::mutex &planner_mutex()
{
    static std::mutex mu;
    return mu;
}

fftw_plan shared_real_plan(size_t n, bool inverse)
{
    struct Plans {
        fftw_plan fwd = nullptr, inv = nullptr;
    };
    std::mutex &mu = planner_mutex();
    // never destroyed: the plans stay reachable to the exit (a static map's destructor would run
    // before a leak check and orphan them), and no exit-time destructor races a late job
    static auto *cache = new std::map<size_t, Plans>;
    if (n < 1 || n > (size_t)0x7FFFFFFF) return nullptr;
    std::lock_guard<std::mutex> lock(mu);
    Plans &p = (*cache)[n];
    fftw_plan &slot = inverse ? p.inv : p.fwd;
    if (slot) return slot;
    fftw_planner_ready();   // msid frf's warm-up plan may be in the planner on another thread
    double *re = fftw_alloc_real(n);
    fftw_complex *cx = fftw_alloc_complex(n / 2 + 1);
    if (re && cx)
        slot = inverse ? fftw_plan_dft_c2r_1d((int)n, cx, re, FFTW_ESTIMATE)
                       : fftw_plan_dft_r2c_1d((int)n, re, cx, FFTW_ESTIMATE);
    fftw_free(re);
    fftw_free(cx);
    return slot;
}

fftw_plan shared_half_plan(size_t m)
{
    std::mutex &mu = planner_mutex();
    static auto *cache = new std::map<size_t, fftw_plan>;   // never destroyed, as shared_real_plan's
    if (m < 1 || m > (size_t)0x40000000) return nullptr;
    std::lock_guard<std::mutex> lock(mu);
    fftw_plan &slot = (*cache)[m];
    if (slot) return slot;
    fftw_planner_ready();
    fftw_complex *a = fftw_alloc_complex(m), *b = fftw_alloc_complex(m);
    if (a && b) slot = fftw_plan_dft_1d((int)m, a, b, FFTW_FORWARD, FFTW_ESTIMATE);
    fftw_free(a);
    fftw_free(b);
    return slot;
}

}  // namespace msidutil
