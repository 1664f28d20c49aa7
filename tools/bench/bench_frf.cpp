// msid bench frf: the FRF job (line DFT, period statistics, MIMO LS FRF with both covariances) on
// the streaming and FFT paths, FFTW's own per-period transforms as the floor of the FFT path, and
// a NumPy peer of the same job in the same run.
#include "bench_util.hpp"
#include "msid_host_util.hpp"

extern "C" {
#include "msid/msid_fft_fftw.h"
}
#include <fftw3.h>

#include <cstdlib>
#include <sstream>
#include <vector>

namespace msidbench {

using msidutil::check;
using msidutil::fmt;
using msidutil::Mem;

namespace {

struct Config {
    const char *name;
    uint32_t P, L, nu, ny, m, K;
};

const Config CONFIGS[] = {
    {"P=1024 L=20 1x1", 1024, 20, 1, 1, 1, 8},
    {"P=4096 L=200 2in x 4out m=2", 4096, 200, 2, 4, 2, 8},
    {"P=65536 L=10000 1in x 2out", 65536, 10000, 1, 2, 1, 8},
};

// One configuration's records, line set, twiddles and FFTW plan.
struct Job {
    Config c;
    std::vector<uint32_t> bins;
    std::vector<std::vector<double>> data;   // per experiment: K*P rows of nu+ny
    Mem mtw;
    msid_twiddle tw{};
    msid_fft_fftw fftw{};
    bool have_fftw = false;

    explicit Job(const Config &cfg, msid_fftw_effort effort) : c(cfg)
    {
        msid_rng r;
        msid_rng_seed(&r, 42);
        // L distinct bins in [1, P/2) chosen by a seeded shuffle
        std::vector<uint32_t> all;
        for (uint32_t b = 1; 2 * b < c.P; ++b) all.push_back(b);
        for (size_t i = all.size() - 1; i > 0; --i) std::swap(all[i], all[msid_rng_u64(&r) % (i + 1)]);
        bins.assign(all.begin(), all.begin() + c.L);
        std::sort(bins.begin(), bins.end());
        // Inputs: one random period repeated (periodic, exciting every line, like a
        // multisine); outputs: white noise. Only the sizes matter for speed.
        const size_t C = c.nu + c.ny;
        data.resize(c.m);
        for (auto &d : data) {
            d.resize((size_t)c.K * c.P * C);
            for (size_t n = 0; n < (size_t)c.K * c.P; ++n)
                for (size_t ch = 0; ch < C; ++ch)
                    d[n * C + ch] = ch < c.nu && n >= c.P ? d[(n - c.P) * C + ch] : msid_rng_normal(&r);
        }
        mtw = Mem(msid_twiddle_mem_size(c.P));
        check(msid_twiddle_init(&tw, c.P, mtw.p, mtw.n), "twiddle");
        check(msid_fft_fftw_create(&fftw, c.P, effort), "fftw");
        have_fftw = true;
    }
    ~Job() { if (have_fftw) msid_fft_fftw_destroy(&fftw); }
    Job(const Job &) = delete;
    Job &operator=(const Job &) = delete;

    // One whole job on the given path; returns G[0] real part to keep the optimiser honest.
    double run(msid_dft_path path, Mem &mm, Mem &mf)
    {
        msid_meas_cfg mc{};
        mc.period = c.P; mc.n_inputs = c.nu; mc.n_outputs = c.ny; mc.n_experiments = c.m;
        mc.n_lines = c.L; mc.bins = bins.data(); mc.twiddle = &tw; mc.path = path;
        mc.fft = &fftw.be;
        if (mm.n < msid_meas_mem_size(&mc)) mm = Mem(msid_meas_mem_size(&mc));
        msid_meas ms;
        check(msid_meas_init(&ms, &mc, mm.p, mm.n), "meas");
        for (uint32_t e = 0; e < c.m; ++e) {
            check(msid_meas_begin(&ms, e), "begin");
            check(msid_meas_push(&ms, data[e].data(), (size_t)c.K * c.P), "push");
            check(msid_meas_end(&ms, nullptr), "end");
        }
        msid_frf_cfg fc{c.P, c.nu, c.ny, c.m, c.L, 0, nullptr};
        if (mf.n < msid_frf_mem_size(&fc)) mf = Mem(msid_frf_mem_size(&fc));
        msid_frf f;
        check(msid_frf_init(&f, &fc, mf.p, mf.n), "frf");
        const msid_pstats *ps[MSID_MAX_EXPERIMENTS];
        for (uint32_t e = 0; e < c.m; ++e) ps[e] = msid_meas_stats(&ms, e);
        check(msid_frf_compute(&f, ps), "frf compute");
        return msid_frf_G(&f, 0)[0].re;
    }
};

// The NumPy peer's time of the same job [s] (-1 when it failed; `note` says why, or its NumPy).
double run_peer(const Config &c, double min_s, std::string &note)
{
    std::ostringstream cmd;
    cmd << "python3 '" << peers_dir() << "/msid_peers/bench_peer.py" << "' " << c.P << ' ' << c.L << ' ' << c.nu << ' '
        << c.ny << ' ' << c.m << ' ' << c.K << ' ' << min_s << " 2>&1";
    std::string out;
    const int rc = capture(cmd.str(), out);
    if (rc == -1) { note = "cannot start python3"; return -1; }
    auto k = out.find("\"sec_per_job\": ");
    if (rc != 0 || k == std::string::npos) {
        note = "NumPy peer failed: " + out.substr(0, 200);
        return -1;
    }
    auto v = out.find("\"numpy\": \"");
    if (v != std::string::npos) note = "numpy " + out.substr(v + 10, out.find('"', v + 10) - v - 10);
    return std::atof(out.c_str() + k + 15);
}

// FFTW's own transforms of the same record as stored (rows of C interleaved channels): one
// plan_many (stride C, C transforms) per period, every period of every experiment, same planning
// effort. This is the floor of the FFT path. Returns the time per period [s].
double fftw_floor(Job &job, msid_fftw_effort effort, double min_s)
{
    const Config &c = job.c;
    const int C = (int)(c.nu + c.ny);
    const int n1[1] = {(int)c.P};
    fftw_complex *fo = fftw_alloc_complex((size_t)C * (c.P / 2 + 1));
    // every period starts 16-byte aligned (P even)
    fftw_plan pm = fftw_plan_many_dft_r2c(1, n1, C, job.data[0].data(), nullptr, C, 1, fo, nullptr,
                                          1, (int)(c.P / 2 + 1),
                                          (effort == MSID_FFTW_MEASURE ? FFTW_MEASURE : FFTW_ESTIMATE));
    const double t_job = best_time(
        [&] {
            for (uint32_t e = 0; e < c.m; ++e)
                for (uint32_t k = 0; k < c.K; ++k)
                    fftw_execute_dft_r2c(pm, job.data[e].data() + (size_t)k * c.P * (size_t)C, fo);
        },
        min_s / 2);
    fftw_destroy_plan(pm);
    fftw_free(fo);
    return t_job / ((double)c.K * c.m);
}

// One configuration timed on both paths, FFTW's floor and the peer.
FrfBenchRow time_config(const Config &c, const FrfBenchRequest &rq, msid_fftw_effort effort, std::string &note)
{
    Job job(c, effort);
    Mem mm, mf;
    volatile double sink = 0;
    FrfBenchRow row;
    row.config = c.name;
    row.stream_s = best_time([&] { sink = sink + job.run(MSID_DFT_STREAM, mm, mf); }, rq.min_seconds);
    row.fft_s = best_time([&] { sink = sink + job.run(MSID_DFT_FFT, mm, mf); }, rq.min_seconds);
    row.fftw_period_s = fftw_floor(job, effort, rq.min_seconds);
    row.peer_s = rq.peer ? run_peer(c, rq.min_seconds, note) : -1;
    return row;
}

void print_config(Writer &w, const Config &c, const FrfBenchRow &row, const std::string &note, bool peer)
{
    const double samples = (double)c.K * c.P * c.m;   // sample rows
    const double C = c.nu + c.ny;
    const double fft_per_period = row.fft_s / ((double)c.K * c.m);
    const msid_dft_path autop = msid_linedft_choose(c.P, c.L, (uint32_t)C, 1);
    for (int path = 0; path < 2; ++path) {
        const double t = path == 0 ? row.stream_s : row.fft_s;
        w.print("%-30s %-7s %11.3f %11.2f %13.3f %11s %9s %9s%s\n", path == 0 ? c.name : "", path == 0 ? "stream" : "fft",
                t * 1e3, t / samples * 1e9, t / (samples * c.L * C) * 1e9,
                path == 1 ? fmt("%.2f us", row.fftw_period_s * 1e6).c_str() : "",
                path == 1 ? fmt("%.2f", fft_per_period / row.fftw_period_s).c_str() : "",
                row.peer_s > 0 ? fmt("%.1f", row.peer_s / t).c_str() : "-",
                (path == 0) == (autop == MSID_DFT_STREAM) ? "  <- auto" : "");
    }
    if (row.peer_s > 0)
        w.print("%-30s %-7s %11.3f %11.2f %13s %11s %9s %9s  (%s)\n", "", "numpy", row.peer_s * 1e3,
                row.peer_s / samples * 1e9, "", "", "", "1.0", note.c_str());
    else if (peer)
        w.print("%-30s numpy peer unavailable: %s\n", "", note.c_str());
}

}  // namespace

FrfBenchResult bench_frf(const FrfBenchRequest &rq, const Sink &sink)
{
    if (rq.only > 3) throw msidutil::UsageError("--only takes 1, 2 or 3");
    FrfBenchResult res;
    Writer w(sink, res.report);
    const msid_fftw_effort effort = rq.fftw_measure ? MSID_FFTW_MEASURE : MSID_FFTW_ESTIMATE;
    w.print("msid bench frf  (msid %s, FFTW %s, %s plans)\n", MSID_VERSION, fftw_version,
            effort == MSID_FFTW_MEASURE ? "MEASURE" : "ESTIMATE");
    w.print("machine: %s\n", machine().c_str());
    w.print("job: %s periods per experiment; times are the best of repeated runs (>= %.2g s each)\n\n", "8",
            rq.min_seconds);
    w.print("%-30s %-7s %11s %11s %13s %11s %9s %9s\n", "config", "path", "job [ms]", "ns/sample", "ns/line.ch.s",
            "FFTW/per", "x FFTW", "x numpy");
    for (const Config &c : CONFIGS) {
        if (rq.only && &c != &CONFIGS[rq.only - 1]) continue;
        std::string note;
        res.rows.push_back(time_config(c, rq, effort, note));
        print_config(w, c, res.rows.back(), note, rq.peer);
    }
    w.print("\ncolumns: job = whole FRF job for all experiments; ns/sample per sample row (all channels);\n"
            "ns/line.ch.s = job / (samples x lines x channels); FFTW/per = FFTW's own r2c transforms of one\n"
            "period of the record as stored (plan_many, stride C, averaged over all periods); x FFTW = FFT-path\n"
            "job time per period / that; x numpy = NumPy peer time / msid time (same job, same sizes).\n");
    return res;
}

}  // namespace msidbench
