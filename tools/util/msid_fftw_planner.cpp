#include "msid_fftw_planner.hpp"

#include "msid/msid_fft_fftw.h"

#include <exception>
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

}  // namespace msidutil
