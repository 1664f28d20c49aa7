// msid bench wcet: per-sample time of the streaming path on the host (msid_gen_next +
// msid_meas_push of one row), median, p99, p99.9 and max, and the period-end samples apart.
#include "bench_util.hpp"

#include "msid_host_util.hpp"

#include <cstdlib>
#include <ctime>
#include <vector>

namespace msidbench {

namespace {

struct Wcase { uint32_t P, nu, ny, m, L; const char *name; int spread; };

const Wcase CASES[] = {{1000, 1, 1, 1, 1, "SISO 1 line", 0},       {1000, 1, 1, 1, 50, "SISO 50 lines", 0},
                       {1000, 2, 2, 2, 50, "2x2 m=2 50 lines", 0},  {1000, 1, 1, 1, 50, "SISO 50 spread", 1},
                       {1000, 2, 2, 2, 50, "2x2 50 spread", 1}};

double now_ns()
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return 1e9 * (double)t.tv_sec + (double)t.tv_nsec;
}

// The core's objects of one case: twiddles, design, generator and streaming estimator in their own memory.
struct Stream {
    std::vector<uint32_t> bins;
    msid_twiddle tw;
    msid_design d;
    msid_gen g;
    msid_meas ms;
    void *mem[4] = {nullptr, nullptr, nullptr, nullptr};

    static void *alloc(size_t n) { return std::aligned_alloc(64, (n + 63) & ~(size_t)63); }

    explicit Stream(const Wcase &c) : bins(c.L)
    {
        for (uint32_t l = 0; l < c.L; ++l) bins[l] = 1 + 2 * l;
        size_t n = msid_twiddle_mem_size(c.P);
        mem[0] = alloc(n);
        msid_twiddle_init(&tw, c.P, mem[0], n);
        msid_design_cfg dc{};
        dc.period = c.P; dc.n_lines = c.L; dc.bins = bins.data(); dc.n_inputs = c.nu; dc.n_experiments = c.m;
        dc.twiddle = &tw;
        n = msid_design_mem_size(&dc);
        mem[1] = alloc(n);
        if (msid_design_init(&d, &dc, mem[1], n) != MSID_OK) { release(); throw msidutil::Error("bench wcet: design"); }
        msid_gen_cfg gc{&d, &tw, 0u, 1};
        n = msid_gen_mem_size(&gc);
        mem[2] = alloc(n);
        msid_gen_init(&g, &gc, mem[2], n);
        msid_meas_cfg mc{};
        mc.period = c.P; mc.n_inputs = c.nu; mc.n_outputs = c.ny; mc.n_experiments = c.m; mc.n_lines = c.L;
        mc.bins = bins.data(); mc.twiddle = &tw; mc.path = MSID_DFT_STREAM;
        mc.spread = c.spread;   // "spread": period-end work one line per sample over the next period
        n = msid_meas_mem_size(&mc);
        mem[3] = alloc(n);
        if (msid_meas_init(&ms, &mc, mem[3], n) != MSID_OK) { release(); throw msidutil::Error("bench wcet: meas"); }
        msid_meas_begin(&ms, 0);
    }
    void release()
    {
        for (void *&p : mem) { std::free(p); p = nullptr; }
    }
    ~Stream() { release(); }
    Stream(const Stream &) = delete;
    Stream &operator=(const Stream &) = delete;
};

// The sample at fraction f of a histogram in 1 ns bins.
double quantile(const std::vector<uint64_t> &h, uint64_t total, double f)
{
    const uint64_t want = (uint64_t)(f * (double)total);
    uint64_t acc = 0;
    for (size_t i = 0; i < h.size(); ++i)
        if ((acc += h[i]) > want) return (double)i;
    return (double)h.size();
}

WcetBenchRow time_case(Writer &w, const Wcase &c, uint64_t N)
{
    Stream st(c);
    // histogram in 1 ns bins up to 100 us, exact max beyond
    std::vector<uint64_t> hist(100000, 0), hend(100000, 0);   // all samples, period-end samples
    double mx = 0, mx_end = 0, mx_first = 0;
    double row[8] = {0};
    for (uint64_t s = 0; s < N; ++s) {
        const double t0 = now_ns();
        msid_gen_next(&st.g, row);
        for (uint32_t i = 0; i < c.ny; ++i) row[c.nu + i] = 0.5 * row[i % c.nu];
        msid_meas_push(&st.ms, row, 1);
        const double dt = now_ns() - t0;
        const size_t b = dt < 0 ? 0 : (size_t)dt;
        hist[std::min(b, hist.size() - 1)]++;
        if (dt > mx) mx = dt;
        if ((s + 1) % c.P == 0) {
            hend[std::min(b, hend.size() - 1)]++;
            if (dt > mx_end) mx_end = dt;
        }
        if (s + 1 == N / 10) mx_first = mx;
    }
    const uint64_t ne = N / c.P;
    WcetBenchRow r;
    r.name = c.name;
    r.median_ns = quantile(hist, N, 0.5);
    r.p99_ns = quantile(hist, N, 0.99);
    r.p999_ns = quantile(hist, N, 0.999);
    r.max_ns = mx;
    r.period_end_median_ns = quantile(hend, ne, 0.5);
    r.period_end_max_ns = mx_end;
    w.print("  %-17s median %5.0f  p99 %5.0f  p99.9 %6.0f  max %9.0f (first 10%%: %9.0f) ns\n", c.name, r.median_ns,
            r.p99_ns, r.p999_ns, mx, mx_first);
    w.print("  %-17s period-end samples (%llu): median %6.0f  p99 %6.0f  max %9.0f ns\n", "", (unsigned long long)ne,
            r.period_end_median_ns, quantile(hend, ne, 0.99), mx_end);
    return r;
}

}  // namespace

WcetBenchResult bench_wcet(const WcetBenchRequest &rq, const Sink &sink)
{
    if (rq.samples < 100000ull) throw msidutil::UsageError("msid bench wcet: --samples must be at least 100000");
    WcetBenchResult res;
    Writer w(sink, res.report);
    w.print("msid bench wcet  (msid %s, %llu samples per case, per-sample times in ns incl. ~20 ns clock read)\n",
            MSID_VERSION, (unsigned long long)rq.samples);
    for (const Wcase &c : CASES) res.rows.push_back(time_case(w, c, rq.samples));
    w.print("Wall-clock maxima include operating-system preemption (milliseconds on a shared machine); the\n"
            "library's own per-sample bound is the period-end median here and the instruction count\n"
            "`msid bench target` reads on the emulated Cortex-M (max insn), which no preemption disturbs.\n");
    return res;
}

}  // namespace msidbench
