// msid bench frf: time the FRF job (line DFT, period statistics, MIMO LS FRF
// with both covariances) on the streaming and FFTW paths, FFTW's own
// per-period transform as the floor, and a NumPy peer in the same run.
#include "cli_util.hpp"
#include "commands.hpp"

extern "C" {
#include "msid/msid_fft_fftw.h"
}
#include <fftw3.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/utsname.h>
#include <unistd.h>

namespace msidcli {

namespace {

struct Config {
    const char *name;
    uint32_t P, L, nu, ny, m, K;
};

double now()
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Best time of fn() over repetitions lasting at least min_s (and >= 3 runs).
template <class F> double best_time(F fn, double min_s)
{
    fn();
    double best = 1e30, t_end = now() + min_s;
    int reps = 0;
    while (reps < 3 || now() < t_end) {
        const double t0 = now();
        fn();
        best = std::min(best, now() - t0);
        ++reps;
    }
    return best;
}

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

std::string machine()
{
    std::string cpu = "unknown cpu";
    std::ifstream f("/proc/cpuinfo");
    std::string line;
    while (std::getline(f, line))
        if (line.rfind("model name", 0) == 0) { cpu = line.substr(line.find(':') + 2); break; }
    struct utsname u;
    uname(&u);
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return cpu + ", " + std::to_string(n) + " cores, " + u.sysname + " " + u.release;
}

std::string peer_script()
{
    const char *env = std::getenv("MSID_PYTHON_DIR");
    std::string dir = env ? env : std::string(MSID_SOURCE_DIR) + "/tools/python";
    return dir + "/msid/bench_peer.py";
}

double run_peer(const Config &c, double min_s, std::string &note)
{
    std::ostringstream cmd;
    cmd << "python3 '" << peer_script() << "' " << c.P << ' ' << c.L << ' ' << c.nu << ' ' << c.ny << ' ' << c.m << ' '
        << c.K << ' ' << min_s << " 2>&1";
    FILE *p = popen(cmd.str().c_str(), "r");
    if (!p) { note = "cannot start python3"; return -1; }
    std::string out;
    char buf[512];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    const int rc = pclose(p);
    auto k = out.find("\"sec_per_job\": ");
    if (rc != 0 || k == std::string::npos) {
        note = "NumPy peer failed: " + out.substr(0, 200);
        return -1;
    }
    auto v = out.find("\"numpy\": \"");
    if (v != std::string::npos) note = "numpy " + out.substr(v + 10, out.find('"', v + 10) - v - 10);
    return std::atof(out.c_str() + k + 15);
}

}  // namespace

static const char *HELP =
    "usage: msid bench frf [--quick] [--min-seconds S] [--no-peer] [--measure] [--only 1|2|3]\n"
    "\n"
    "Times the FRF job (line DFT, period statistics, LS FRF with both covariances) on\n"
    "  P=1024, 20 lines, 1x1;  P=4096, 200 lines, 2 inputs x 4 outputs, 2 experiments;\n"
    "  P=65536, 10000 lines, 1 input x 2 outputs\n"
    "for the streaming and FFTW paths, FFTW's own per-period transforms (C real FFTs of\n"
    "length P) as the floor of the FFT path, and a NumPy peer of the same job.\n"
    "--measure plans FFTW with FFTW_MEASURE (default FFTW_ESTIMATE, as `msid frf`).\n";

int cmd_bench(int argc, char **argv)
{
    if (argc < 3 || std::strcmp(argv[2], "frf") != 0) {
        if (argc >= 3 && !std::strcmp(argv[2], "--help")) { std::fputs(HELP, stdout); return 0; }
        throw UsageError("usage: msid bench frf [--quick] [--min-seconds S] [--no-peer] [--measure] [--only 1|2|3]");
    }
    for (int i = 3; i < argc; ++i)
        if (!std::strcmp(argv[i], "--help")) { std::fputs(HELP, stdout); return 0; }
    Args a(argc, argv, 3, {"min-seconds", "only"}, {"quick", "no-peer", "measure"});
    const uint32_t only = a.has("only") ? parse_u32(a.get("only"), "--only") : 0;
    if (only > 3) throw UsageError("--only takes 1, 2 or 3");
    double min_s = a.has("min-seconds") ? parse_double(a.get("min-seconds"), "--min-seconds") : 1.0;
    if (a.has("quick")) min_s = 0.1;
    const msid_fftw_effort effort = a.has("measure") ? MSID_FFTW_MEASURE : MSID_FFTW_ESTIMATE;
    const Config cfgs[] = {
        {"P=1024 L=20 1x1", 1024, 20, 1, 1, 1, 8},
        {"P=4096 L=200 2in x 4out m=2", 4096, 200, 2, 4, 2, 8},
        {"P=65536 L=10000 1in x 2out", 65536, 10000, 1, 2, 1, 8},
    };
    std::printf("msid bench frf  (msid %s, FFTW %s, %s plans)\n", MSID_VERSION, fftw_version,
                effort == MSID_FFTW_MEASURE ? "MEASURE" : "ESTIMATE");
    std::printf("machine: %s\n", machine().c_str());
    std::printf("job: %s periods per experiment; times are the best of repeated runs (>= %.2g s each)\n\n", "8", min_s);
    std::printf("%-30s %-7s %11s %11s %13s %11s %9s %9s\n", "config", "path", "job [ms]", "ns/sample", "ns/line.ch.s",
                "FFTW/per", "x FFTW", "x numpy");
    int worst_fail = 0;
    for (const Config &c : cfgs) {
        if (only && &c != &cfgs[only - 1]) continue;
        Job job(c, effort);
        Mem mm, mf;
        const double samples = (double)c.K * c.P * c.m;   // sample rows
        const double C = c.nu + c.ny;
        volatile double sink = 0;
        const double t_stream = best_time([&] { sink = sink + job.run(MSID_DFT_STREAM, mm, mf); }, min_s);
        const double t_fft = best_time([&] { sink = sink + job.run(MSID_DFT_FFT, mm, mf); }, min_s);
        // FFTW's own transforms of the same record as stored (rows of C interleaved
        // channels): one plan_many (stride C, C transforms) per period, every period of
        // every experiment, same planning effort. This is the floor of the FFT path.
        const int n1[1] = {(int)c.P};
        fftw_complex *fo = fftw_alloc_complex((size_t)C * (c.P / 2 + 1));
        fftw_plan pm = fftw_plan_many_dft_r2c(1, n1, (int)C, job.data[0].data(), nullptr, (int)C, 1, fo, nullptr, 1,
                                              (int)(c.P / 2 + 1),
                                              (effort == MSID_FFTW_MEASURE ? FFTW_MEASURE : FFTW_ESTIMATE));   // every period starts 16-byte aligned (P even)
        const double t_fftw_job = best_time(
            [&] {
                for (uint32_t e = 0; e < c.m; ++e)
                    for (uint32_t k = 0; k < c.K; ++k)
                        fftw_execute_dft_r2c(pm, job.data[e].data() + (size_t)k * c.P * (size_t)C, fo);
            },
            min_s / 2);
        fftw_destroy_plan(pm);
        fftw_free(fo);
        const double t_fftw_period = t_fftw_job / ((double)c.K * c.m);
        const double periods = (double)c.K * c.m;
        const double fft_per_period = t_fft / periods;
        std::string note;
        double t_peer = a.has("no-peer") ? -1 : run_peer(c, min_s, note);
        const msid_dft_path autop = msid_linedft_choose(c.P, c.L, (uint32_t)C, 1);
        for (int path = 0; path < 2; ++path) {
            const double t = path == 0 ? t_stream : t_fft;
            std::printf("%-30s %-7s %11.3f %11.2f %13.3f %11s %9s %9s%s\n", path == 0 ? c.name : "",
                        path == 0 ? "stream" : "fft", t * 1e3, t / samples * 1e9, t / (samples * c.L * C) * 1e9,
                        path == 1 ? fmt("%.2f us", t_fftw_period * 1e6).c_str() : "",
                        path == 1 ? fmt("%.2f", fft_per_period / t_fftw_period).c_str() : "",
                        t_peer > 0 ? fmt("%.1f", t_peer / t).c_str() : "-",
                        (path == 0) == (autop == MSID_DFT_STREAM) ? "  <- auto" : "");
        }
        if (t_peer > 0)
            std::printf("%-30s %-7s %11.3f %11.2f %13s %11s %9s %9s  (%s)\n", "", "numpy", t_peer * 1e3,
                        t_peer / samples * 1e9, "", "", "", "1.0", note.c_str());
        else if (!a.has("no-peer"))
            std::printf("%-30s numpy peer unavailable: %s\n", "", note.c_str());
        (void)worst_fail;
    }
    std::printf("\ncolumns: job = whole FRF job for all experiments; ns/sample per sample row (all channels);\n"
                "ns/line.ch.s = job / (samples x lines x channels); FFTW/per = FFTW's own r2c transforms of one\n"
                "period of the record as stored (plan_many, stride C, averaged over all periods); x FFTW = FFT-path\n"
                "job time per period / that; x numpy = NumPy peer time / msid time (same job, same sizes).\n");
    return 0;
}

}  // namespace msidcli
