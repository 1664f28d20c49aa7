// msid bench frf: time the FRF job (line DFT, period statistics, MIMO LS FRF
// with both covariances) on the streaming and FFTW paths, FFTW's own
// per-period transform as the floor, and a NumPy peer in the same run.
#include "cli_util.hpp"
#include "commands.hpp"

extern "C" {
#include "msid/msid_fft_fftw.h"
}
#include <fftw3.h>

#include "host_libs.hpp"
#include "frf_file.hpp"
#include "lmfd_fit.hpp"
#include "poleres.hpp"
#include "model_io.hpp"
#include "subspace.hpp"

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

std::string peer_script() { return bench_peers_dir() + "/msid_peers/bench_peer.py"; }

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

std::string bench_machine() { return machine(); }

std::string bench_peers_dir()
{
    const char *env = std::getenv("MSID_PEERS_DIR");
    return env ? env : std::string(MSID_SOURCE_DIR) + "/tools/peers";
}

static const char *HELP =
    "usage: msid bench frf [--quick] [--min-seconds S] [--no-peer] [--measure] [--only 1|2|3]\n"
    "\n"
    "Times the FRF job (line DFT, period statistics, LS FRF with both covariances) on\n"
    "  P=1024, 20 lines, 1x1;  P=4096, 200 lines, 2 inputs x 4 outputs, 2 experiments;\n"
    "  P=65536, 10000 lines, 1 input x 2 outputs\n"
    "for the streaming and FFTW paths, FFTW's own per-period transforms (C real FFTs of\n"
    "length P) as the floor of the FFT path, and a NumPy peer of the same job.\n"
    "--measure plans FFTW with FFTW_MEASURE (default FFTW_ESTIMATE, as `msid frf`).\n";

static int bench_fit(int argc, char **argv);
int cmd_bench_crest(int argc, char **argv);   // cmd_bench_crest.cpp
static int bench_frf(int argc, char **argv);

static const char *BENCH_HELP =
    "usage: msid bench <name> [options]   (msid bench <name> --help: the options of one)\n"
    "\n"
    "  frf     the FRF job (line DFT, period statistics, LS FRF) on both paths against FFTW and NumPy\n"
    "  fit     subspace, lmfd and ml fits against NumPy and scikit-rf vector fitting\n"
    "  lpm     the local polynomial method against its NumPy peer\n"
    "  io      reading experiment files (CSV, .npy, .mat) against pandas / NumPy / SciPy\n"
    "  can     the highest lossless CAN sample rate over vcan (Debian kernel under qemu)\n"
    "  modbus  the highest lossless sample rate x channels over Modbus from msid-devsim\n"
    "  target  instructions per sample of the core on a Cortex-M (qemu)\n"
    "  wcet    per-sample time of generation + streaming estimation on the host\n"
    "  crest   design set-up for large P: crest factors by FFT vs direct synthesis vs NumPy\n"
    "\n"
    "Results with date and machine go to docs/benchmarks.md.\n";

int cmd_bench(int argc, char **argv)
{
    return dispatch_subcommand(argc, argv, "bench", BENCH_HELP,
                               {{"frf", bench_frf},
                                {"fit", bench_fit},
                                {"lpm", cmd_bench_lpm},
                                {"io", cmd_bench_io},
                                {"can", cmd_bench_can},
                                {"modbus", cmd_bench_modbus},
                                {"target", cmd_bench_target},
                                {"wcet", cmd_bench_target},
                                {"crest", cmd_bench_crest}},
                               true);
}

static int bench_frf(int argc, char **argv)
{
    Args a(argc, argv, 3, HELP, {"min-seconds", "only"}, {"quick", "no-peer", "measure"});
    const uint32_t only = a.u32("only", 0);
    if (only > 3) throw UsageError("--only takes 1, 2 or 3");
    double min_s = a.f64("min-seconds", 1.0);
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
    }
    std::printf("\ncolumns: job = whole FRF job for all experiments; ns/sample per sample row (all channels);\n"
                "ns/line.ch.s = job / (samples x lines x channels); FFTW/per = FFTW's own r2c transforms of one\n"
                "period of the record as stored (plan_many, stride C, averaged over all periods); x FFTW = FFT-path\n"
                "job time per period / that; x numpy = NumPy peer time / msid time (same job, same sizes).\n");
    return 0;
}

}  // namespace msidcli

namespace msidcli {

// ---------------- msid bench fit ----------------

namespace {

using namespace msidfit;

// A random stable DT system: n/2 lightly damped modes, random B, C, D.
SSModel random_system(msid_rng &r, int n, int nu, int ny)
{
    SSModel m;
    m.domain = Domain::DT;
    m.A = MatR::Zero(n, n);
    for (int k = 0; k < n / 2; ++k) {
        const double rad = 0.5 + 0.45 * msid_rng_uniform(&r), th = 0.1 + 2.7 * msid_rng_uniform(&r);
        m.A(2 * k, 2 * k) = m.A(2 * k + 1, 2 * k + 1) = rad * std::cos(th);
        m.A(2 * k, 2 * k + 1) = -rad * std::sin(th);
        m.A(2 * k + 1, 2 * k) = rad * std::sin(th);
    }
    m.B = MatR(n, nu);
    m.C = MatR(ny, n);
    m.D = MatR(ny, nu);
    for (int i = 0; i < m.B.size(); ++i) m.B.data()[i] = msid_rng_normal(&r);
    for (int i = 0; i < m.C.size(); ++i) m.C.data()[i] = msid_rng_normal(&r);
    for (int i = 0; i < m.D.size(); ++i) m.D.data()[i] = 0.5 * msid_rng_normal(&r);
    return m;
}

// FRF at L lines (bins 1..L of P = 2L+2) with M noisy repetitions per line:
// G + mean of M complex Gaussian noises (covariance s^2 I), sample covariance / M.
Json frf_doc(msid_rng &r, const SSModel &m, int L, double snr_db, int M)
{
    const int ny = (int)m.C.rows(), nu = (int)m.B.cols(), g = ny * nu, P = 2 * L + 2;
    std::vector<MatC> G(L);
    double pw = 0;
    for (int l = 0; l < L; ++l) {
        G[l] = ss_eval(m, std::polar(1.0, 2 * M_PI * (l + 1) / P));
        pw += G[l].squaredNorm() / (g * L);
    }
    const double s2 = pw * std::pow(10.0, -snr_db / 10.0);
    msidfrf::Header hd;
    hd.period = (uint32_t)P;
    hd.nu = (uint32_t)nu;
    hd.ny = (uint32_t)ny;
    hd.m = (uint32_t)nu;
    Json doc = msidfrf::header(hd);
    doc["periods_used"] = M;
    doc["periods_rejected"] = 0;
    doc["noise_cov"] = msidfrf::cmat(MatC(MatC::Identity(ny, ny) * (s2 / P)));
    doc["experiments"] = Json::array();
    Json lines = Json::array();
    for (int l = 0; l < L; ++l) {
        std::vector<VecC> x(M, VecC(g));
        VecC mean = VecC::Zero(g);
        for (int k = 0; k < M; ++k) {
            for (int a = 0; a < g; ++a)
                x[k](a) = Eigen::Map<const VecC>(G[l].data(), g)(a) +
                          std::sqrt(s2 / 2) * cd(msid_rng_normal(&r), msid_rng_normal(&r));
            mean += x[k] / (double)M;
        }
        MatC S = MatC::Zero(g, g);
        for (int k = 0; k < M; ++k) S += (x[k] - mean) * (x[k] - mean).adjoint();
        S /= (double)(M - 1) * M;
        msidfrf::Position pos;
        pos.bin = (uint32_t)(l + 1);
        pos.period = (uint32_t)P;
        msidfrf::LineStats st;
        st.G = Eigen::Map<const MatC>(mean.data(), ny, nu);
        st.cov = S;
        st.dof = M - 1;   // cov_known_input: the same
        lines.push_back(msidfrf::line(msidfrf::position(pos), st));
    }
    doc["lines"] = lines;
    return doc;
}

struct FitCfg {
    const char *name;
    int n, nu, ny, L;
};

}  // namespace

namespace {


// Run a shell command, capture stdout+stderr; returns the exit status.
int run_capture(const std::string &cmd, std::string &out)
{
    FILE *p = popen((cmd + " 2>&1").c_str(), "r");
    char buf[512];
    while (p && std::fgets(buf, sizeof buf, p)) out += buf;
    return p ? pclose(p) : -1;
}

// Wall time of a whole process (median of reps).
double process_time(const std::string &cmd, int reps)
{
    std::vector<double> t;
    for (int k = 0; k < reps; ++k) {
        const double t0 = now();
        if (std::system((cmd + " >/dev/null 2>&1").c_str()) != 0) return -1;
        t.push_back(now() - t0);
    }
    std::sort(t.begin(), t.end());
    return t[t.size() / 2];
}

// |G - G0| / |G0| over the lines, G0 as the peer writes it (re/im per line, vec order).
double rel_error_to(const std::vector<MatC> &G, const Json &G0, Eigen::Index g)
{
    double num = 0, den = 0;
    for (size_t l = 0; l < G.size(); ++l)
        for (Eigen::Index ij = 0; ij < g; ++ij) {
            const cd g0(G0["re"][l][(size_t)ij].get<double>(), G0["im"][l][(size_t)ij].get<double>());
            num += std::norm(G[l].data()[ij] - g0);
            den += std::norm(g0);
        }
    return std::sqrt(num / den);
}

// |G - G_measured| / |G_measured| over the lines: the relative fit error vector fitting reports.
double fit_error_to(const std::vector<MatC> &G, const std::vector<WeightedLine> &w)
{
    double num = 0, den = 0;
    for (size_t l = 0; l < w.size(); ++l) {
        num += (G[l] - w[l].G).squaredNorm();
        den += w[l].G.squaredNorm();
    }
    return std::sqrt(num / den);
}

// Eq. (40) of model FRFs G on the per-line weights w (the file's covariance).
double cost_on(const std::vector<WeightedLine> &w, const std::vector<MatC> &G)
{
    double V = 0;
    for (size_t l = 0; l < w.size(); ++l)
        V += (w[l].real ? 0.5 : 1.0) * (w[l].Linv * Eigen::Map<const VecC>(MatC(w[l].G - G[l]).data(), w[l].G.size())).squaredNorm();
    return V;
}

double median_of(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// The Monte Carlo over noise seeds (--runs N): ml as `msid fit` runs it against vector fitting at
// the same order, per case the mean and median of ml's error against the truth over vector
// fitting's, its standard error, the mean cost ratio and the stable fraction (docs/benchmarks.md).
void bench_structures_mc(const Json &mc)
{
    if (mc.empty()) return;
    std::printf("  Monte Carlo over noise seeds 0..%zu (ml error against the truth / vector fitting's, same file, same order):\n",
                mc[0]["runs"].size() - 1);
    std::printf("  %-14s %5s %4s | %-28s | %-9s | %-19s | %-19s | %-19s | %-12s | %s\n", "case", "order", "runs",
                "err ratio mean (se), median", "ml <= VF", "fit err ml/VF (n > 1)", "cost ml/VF (n > 1)",
                "pooled ml/VF (n > 1)", "ml stable", "VF time");
    for (const Json &c : mc) {
        std::vector<double> er, fe, cr, cp;
        int stable = 0, better = 0;
        double tvf = 0;
        for (const Json &run : c["runs"]) {
            const FrfData f = read_frf(run["file"].get<std::string>());
            const auto w = weigh(f, Domain::CT, Weight::Cov);
            auto wp = w;
            smooth_weights(wp, ML_WEIGHT_SMOOTH);
            PrOptions po;
            po.order = c["order"].get<int>();
            const PrResult r = pr_ml_fit(f, Domain::CT, wp, true, po);
            const double e = rel_error_to(r.G, run["G0"], (Eigen::Index)f.g());
            er.push_back(e / run["vf_rel_error"].get<double>());
            fe.push_back(fit_error_to(r.G, w) / run["vf_fit_error"].get<double>());
            cr.push_back(cost_on(w, r.G) / run["vf_cost"].get<double>());
            cp.push_back(r.cost / run["vf_cost_pooled"].get<double>());   // the cost ml minimises, on both
            stable += ss_stable(pr_to_ss(r.model));
            better += er.back() <= 1.0;
            tvf += run["vf_seconds"].get<double>();
        }
        const double n = (double)er.size();
        double m = 0, v = 0, mc_ = 0;
        for (double x : er) m += x / n;
        for (double x : er) v += (x - m) * (x - m) / std::max(n - 1, 1.0);
        for (double x : cr) mc_ += x / n;
        double mp = 0, mf = 0;
        for (double x : cp) mp += x / n;
        for (double x : fe) mf += x / n;
        const long fe_above = std::count_if(fe.begin(), fe.end(), [](double x) { return x > 1.0; });
        const long cr_above = std::count_if(cr.begin(), cr.end(), [](double x) { return x > 1.0; });
        const long cp_above = std::count_if(cp.begin(), cp.end(), [](double x) { return x > 1.0; });
        const std::string name = c["kind"].get<std::string>() + " " + std::to_string(c["modes"].get<int>()) + " modes";
        const int order = c["order"].get<int>(), nominal = c["nominal_order"].get<int>();
        std::printf("  %-14s %5d %4.0f | %6.4f (%6.4f), %6.4f        | %4d/%-4.0f | %8.4f (%3ld)      | %8.4f (%3ld)      | %8.4f (%3ld)      | %4d/%-4.0f   | %.2f s/fit%s\n",
                    name.c_str(), order, n, m, std::sqrt(v / n), median_of(er), better, n, mf, fe_above, mc_, cr_above, mp,
                    cp_above, stable, n, tvf / n,
                    order < nominal ? "  (one mode below the noise left out)" : "");
    }
    std::printf("  (err ratio: against the true FRF; fit err: |G_model - G_measured| / |G_measured|, vector fitting's own "
                "measure)\n");
    std::printf("  (the SISO structures hold a mode whose peak is 0.1 (10 modes) / 0.2 (12) times the noise sd: at the "
                "nominal order its pole pair is free and ml, which\n"
                "   minimises the cost, spends it on the noise: lower cost, higher error; at the order the data identify "
                "ml and vector fitting agree. docs/benchmarks.md)\n\n");
}

// The simulated structures against vector fitting (scikit-rf), and the order-20 ml timing.
void bench_structures(const std::string &dir, double min_s, uint32_t runs)
{
    std::printf("structures: accelerances, rigid-body + elastic modes with 0.5-2%% damping, 267 lines, "
                "0.2%% noise, 16 periods; peer: scikit-rf VectorFitting at the same order\n");
    std::string outp;
    const std::string js = dir + "/vf.json";
    const int rc = run_capture("cd '" + dir + "' && PYTHONPATH='" + bench_peers_dir() + "' python3 -m msid_peers.bench_vf_peer '" + dir +
                                   "' '" + js + "' --runs " + std::to_string(runs), outp);
    if (rc != 0) {
        std::printf("  peer unavailable (scripts/deps.sh installs scikit-rf): %s\n\n", outp.substr(0, 300).c_str());
        return;
    }
    const Json pj = read_json_file(js);
    std::printf("  %-14s %5s %6s | %-30s | %-30s | %-16s | %-26s\n", "case", "order", "range", "vector fitting: cost, rel.err, time",
                "msid ml: cost, rel.err, time", "ml H=0: rel.err", "msid subspace: cost (x VF)");
    for (const Json &c : pj["cases"]) {
        const FrfData f = read_frf(c["file"].get<std::string>());
        const auto w = weigh(f, Domain::CT, Weight::Cov);
        auto wp = w;   // ml as `msid fit` runs it: pooled weights (--weight-smooth 4)
        smooth_weights(wp, ML_WEIGHT_SMOOTH);
        const int n = c["order"].get<int>();
        PrOptions po;
        po.order = n;
        PrResult r, r0;
        const double t_ml = best_time([&] { r = pr_ml_fit(f, Domain::CT, wp, true, po); }, c["modes"].get<int>() == 10 ? min_s : 0.0);
        r0 = pr_ml_fit(f, Domain::CT, w, true, po);
        auto rel_err = [&](const std::vector<MatC> &G) { return rel_error_to(G, c["G0"], (Eigen::Index)f.g()); };
        const double V = cost_on(w, r.G);   // eq. (40) on the file's (per-line) covariance, as vector fitting's cost
        SubspaceOptions so;   // as `msid fit --method subspace` runs it: refined, stable unless the data need not
        so.order = n;
        so.stable_auto = true;
        so.refine_iter = 30;
        so.refine_w = &wp;   // the refinement on the pooled weights, as msid fit (the cost on the file's)
        SubspaceResult sr;
        const double t_sub = best_time([&] { sr = fit_subspace(f, Domain::CT, w, true, so); }, 0.0);
        const std::string name = std::string(c["kind"].get<std::string>()) + " " + std::to_string(c["modes"].get<int>()) + " modes";
        const double vfe = c["vf_rel_error"].get<double>(), e_ml = rel_err(r.G), e_ml0 = rel_err(r0.G);
        std::printf("  %-14s %5d %4.0fdB | %9.5g %9.3g %8.3f s | %9.5g %9.3g %8.3f s | %9.3g (%.3fx) | %9.5g (%.2fx) %s %5.1f ms\n",
                    name.c_str(), n, c["dynamic_range_db"].get<double>(), c["vf_cost"].get<double>(),
                    vfe, c["vf_seconds"].get<double>(), V, e_ml, t_ml, e_ml0, e_ml0 / vfe,
                    sr.cost, sr.cost / c["vf_cost"].get<double>(), ss_stable(sr.model) ? "stable" : "UNSTABLE",
                    t_sub * 1e3);
    }
    std::printf("  (scikit-rf %s; rel.err = |G_model - G_true| / |G_true| over the lines; cost = eq. (40) on the file's "
                "covariance; ml: pooled weights, --weight-smooth 4 (the default); ml H=0: each line's own covariance as weight;\n"
                "   ml time: best of runs for the 10-mode SISO, one run otherwise)\n",
                pj["skrf"].get<std::string>().c_str());
    bench_structures_mc(pj.value("monte_carlo", Json::array()));
    std::printf("\n");
}

// The whole `msid fit --method subspace` process against a plain NumPy weighted subspace (fixed r = 12) process.
void bench_process(const std::string &dir)
{
    msid_rng r;
    msid_rng_seed(&r, 606);
    const SSModel m = random_system(r, 6, 2, 2);
    const std::string frf = dir + "/proc.json";
    write_json_file(frf, frf_doc(r, m, 202, 40.0, 10));
    char self[4096];
    const ssize_t k = readlink("/proc/self/exe", self, sizeof self - 1);
    if (k <= 0) return;
    self[k] = 0;
    const std::string msid_cmd = std::string("'") + self + "' fit --method subspace --order 6 '" + frf + "' -o '" + dir + "/proc-model.json'";
    const std::string peer_cmd = "python3 '" + bench_peers_dir() + "/msid_peers/bench_fit_peer.py' 6 '" + dir + "/proc-peer.json' '" + frf + "' --r 12";
    const double t_msid = process_time(msid_cmd, 15), t_peer = process_time(peer_cmd, 5);
    std::printf("whole process: 2x2, order 6, 202 lines (wall time, median)\n");
    std::printf("  msid fit --method subspace   %8.1f ms\n", t_msid * 1e3);
    if (t_peer > 0)
        std::printf("  NumPy subspace, r = 12       %8.1f ms   (python3 start-up, import, fit)   msid %.1fx faster\n\n",
                    t_peer * 1e3, t_peer / t_msid);
    else
        std::printf("  NumPy peer failed\n\n");
}

}  // namespace

static int bench_fit(int argc, char **argv)
{
    for (int i = 3; i + 1 < argc; ++i)   // --only multi: cmd_bench_multi.cpp
        if (!std::strcmp(argv[i], "--only") && !std::strcmp(argv[i + 1], "multi")) return cmd_bench_fit_multi(argc, argv);
    for (int i = 3; i < argc; ++i)
        if (!std::strcmp(argv[i], "--cissim")) return cmd_bench_cissim(argc, argv);
    for (int i = 3; i + 1 < argc; ++i)   // --only cissim: cmd_bench_cissim.cpp
        if (!std::strcmp(argv[i], "--only") && !std::strcmp(argv[i + 1], "cissim")) return cmd_bench_cissim(argc, argv);
    static const char *HELP_FIT =
        "usage: msid bench fit [--systems N] [--min-seconds S] [--no-peer] [--only 1|2|3|4] [--runs N]\n"
        "Times subspace, lmfd and ml on SISO n=4 with 1000 lines and 2x2 n=8 with 500 lines\n"
        "(random stable DT systems, 40 dB SNR, covariance from 10 repetitions per line), the NumPy\n"
        "peer of the weighted subspace algorithm on the same files, and the accuracy (relative H2\n"
        "error against the true system) over N random systems (default 50); 3: the simulated\n"
        "structures (ml and subspace against scikit-rf vector fitting, ml at order 20);\n"
        "--runs N (default 3, 0: none): with 3, also a Monte Carlo over N noise seeds of the SISO 10- and\n"
        "12-mode structures (nominal order and the order the data identify) and the 2x3 one: ml's error\n"
        "against the truth over vector fitting's, mean, median and standard error (vector fitting takes\n"
        "seconds per fit: 20 runs take minutes).\n"
        "4: the whole `msid fit --method subspace` process against a NumPy subspace process.\n"
        "Without --only it also runs `msid bench fit --only multi --runs 50` (case M1, multiple experiments)\n"
        "and, last, the cissim benchmark with --quick and the same --systems. --only cissim (or --cissim):\n"
        "discrete-cISSIM, `msid bench fit --cissim --help`.\n";
    Args a(argc, argv, 3, HELP_FIT, {"systems", "min-seconds", "only", "runs"}, {"no-peer"});
    const uint32_t only = a.u32("only", 0);
    if (only > 4) throw UsageError("--only takes 1 (SISO), 2 (2x2), 3 (structures) or 4 (whole process)");
    const int NS = (int)a.u32("systems", 50);
    const double min_s = a.f64("min-seconds", 0.5);
    if (NS < 1) throw UsageError("--systems must be at least 1");
    const uint32_t runs = a.u32("runs", 3);
    if (runs > 1000) throw UsageError("--runs must be at most 1000 (each run is 5 vector fits of seconds each)");
    char tmpl[] = "/tmp/msid-bench-fit-XXXXXX";
    if (!mkdtemp(tmpl)) throw Error("cannot create a temporary directory");
    const std::string dir = tmpl;
    const FitCfg cfgs[] = {{"SISO n=4, 1000 lines", 4, 1, 1, 1000}, {"2x2 n=8, 500 lines", 8, 2, 2, 500}};
    std::printf("msid bench fit  (msid %s, Eigen %d.%d.%d)\nmachine: %s\n", MSID_VERSION, EIGEN_WORLD_VERSION,
                EIGEN_MAJOR_VERSION, EIGEN_MINOR_VERSION, machine().c_str());
    std::printf("data: random stable DT systems, 40 dB SNR, line covariance from 10 repetitions; times: best of runs >= %.2g s\n\n", min_s);
    for (const FitCfg &c : cfgs) {
        if (only && (only > 2 || &c != &cfgs[only - 1])) continue;
        msid_rng r;
        msid_rng_seed(&r, 1000 + c.n);
        std::vector<SSModel> truth;
        std::vector<std::string> files;
        for (int k = 0; k < NS; ++k) {
            truth.push_back(random_system(r, c.n, c.nu, c.ny));
            files.push_back(dir + "/" + std::to_string(c.n) + "-" + std::to_string(k) + ".json");
            write_json_file(files.back(), frf_doc(r, truth.back(), c.L, 40.0, 10));
        }
        const FrfData f0 = read_frf(files[0]);
        const auto w0 = weigh(f0, Domain::DT, Weight::Cov);
        SubspaceOptions so;   // as `msid fit --method subspace` runs it (the ml start below too)
        so.order = c.n;
        so.stable_auto = true;
        so.refine_iter = 30;
        LmfdSpec ls;
        ls.nD = c.n / c.ny;
        ls.nN = ls.nD;
        volatile double sink = 0;
        // as msid fit: the refinement on the covariances pooled over 2H+1 lines (500 lines: dense), the
        // pooling inside the timed fit; ml (--param lmfd, the DT MIMO default) on the pooled weights
        auto pooled = [](std::vector<WeightedLine> w) {
            smooth_weights(w, ML_WEIGHT_SMOOTH);
            return w;
        };
        auto sub_fit_pooled = [&](const std::vector<WeightedLine> &w, const std::vector<WeightedLine> &wp,
                                  const FrfData &f) {
            SubspaceOptions sp = so;
            sp.refine_w = &wp;
            return fit_subspace(f, Domain::DT, w, true, sp);
        };
        auto sub_fit = [&](const std::vector<WeightedLine> &w, const FrfData &f) {
            return sub_fit_pooled(w, pooled(w), f);
        };
        const double t_sub = best_time([&] { sink = sink + sub_fit(w0, f0).cost; }, min_s);
        // lmfd closed form: the fully/under-constrained case, on as many lines as the LMFD has unknowns / 2
        const int qrow = ls.nD * c.ny + (ls.nN + 1) * c.nu, Lfc = qrow / (2 * c.nu);
        std::vector<WeightedLine> wfc(w0.begin(), w0.begin() + Lfc);
        const double t_lmfd = best_time([&] { sink = sink + lmfd_closed_form(wfc, Domain::DT, 0, ls).model.Nm[0](0, 0); }, min_s);
        MlOptions mo;
        auto ml_fit = [&](const std::vector<WeightedLine> &w, const FrfData &f) {
            const auto wp = pooled(w);
            const SubspaceResult sr = sub_fit_pooled(w, wp, f);
            std::vector<MatC> target;
            for (const auto &l : w) target.push_back(ss_eval(sr.model, l.x));
            return lmfd_ml(wp, Domain::DT, 0, ls, lmfd_sk(wp, Domain::DT, 0, ls, 30, &target), mo, false);
        };
        const double t_ml = best_time([&] { sink = sink + ml_fit(w0, f0).cost; }, min_s);
        // accuracy over the systems
        std::vector<double> e_sub, e_ml;
        for (int k = 0; k < NS; ++k) {
            const FrfData f = read_frf(files[k]);
            const auto w = weigh(f, Domain::DT, Weight::Cov);
            e_sub.push_back(ss_distance(sub_fit(w, f).model, truth[k]).h2);
            try {
                e_ml.push_back(ss_distance(lmfd_to_ss(ml_fit(w, f).model), truth[k]).h2);
            } catch (const FitError &) {
                e_ml.push_back(NAN);
            }
        }
        auto mean = [](const std::vector<double> &v) { double s = 0; int n = 0; for (double x : v) if (std::isfinite(x)) { s += x; ++n; } return n ? s / n : NAN; };
        auto median = [](std::vector<double> v) { std::sort(v.begin(), v.end()); return v[v.size() / 2]; };
        double t_peer = -1, ep_mean = NAN, ep_med = NAN;
        std::string note;
        if (!a.has("no-peer")) {
            std::string cmd = "python3 '" + bench_peers_dir() + "/msid_peers/bench_fit_peer.py' " + std::to_string(c.n) + " '" + dir + "/peer.json'";
            for (auto &fl : files) cmd += " '" + fl + "'";
            cmd += " 2>&1";
            FILE *p = popen(cmd.c_str(), "r");
            std::string outp;
            char buf[512];
            while (p && std::fgets(buf, sizeof buf, p)) outp += buf;
            const int rc = p ? pclose(p) : -1;
            if (rc == 0) {
                const Json pj = read_json_file(dir + "/peer.json");
                std::vector<double> ep, tp;
                for (size_t k = 0; k < pj["models"].size(); ++k) {
                    const Json &mj = pj["models"][k];
                    SSModel pm;
                    pm.domain = Domain::DT;
                    auto rm = [](const Json &v) {
                        MatR M((Eigen::Index)v.size(), v.empty() ? 0 : (Eigen::Index)v[0].size());
                        for (size_t i = 0; i < v.size(); ++i)
                            for (size_t j = 0; j < v[i].size(); ++j) M((Eigen::Index)i, (Eigen::Index)j) = v[i][j].get<double>();
                        return M;
                    };
                    pm.A = rm(mj["A"]); pm.B = rm(mj["B"]); pm.C = rm(mj["C"]); pm.D = rm(mj["D"]);
                    try { ep.push_back(ss_distance(pm, truth[k]).h2); } catch (const FitError &) { ep.push_back(NAN); }
                    tp.push_back(pj["sec_per_fit"][k].get<double>());
                }
                t_peer = median(tp);
                ep_mean = mean(ep);
                ep_med = median(ep);
                note = "numpy " + pj["numpy"].get<std::string>();
            } else {
                note = "peer failed: " + outp.substr(0, 200);
            }
        }
        std::printf("%s\n", c.name);
        const SubspaceResult s0 = sub_fit(w0, f0);
        std::printf("  %-10s %10.3f ms   rel. H2 error vs truth: mean %.3g, median %.3g (%d systems)%s\n", "subspace",
                    t_sub * 1e3, mean(e_sub), median(e_sub), NS,
                    t_peer > 0 ? fmt("   %.1fx faster than the peer", t_peer / t_sub).c_str() : "");
        std::printf("  %-10s   (system 1: r = %d, %d refinement steps, cost %.6g -> %.6g)\n", "", s0.r, s0.refine_steps,
                    s0.cost_unrefined, s0.cost);
        std::printf("  %-10s %10.3f ms   (closed form, %d lines: fully/under-constrained)\n", "lmfd", t_lmfd * 1e3, Lfc);
        std::printf("  %-10s %10.3f ms   rel. H2 error vs truth: mean %.3g, median %.3g (subspace start + SK + LM)\n", "ml",
                    t_ml * 1e3, mean(e_ml), median(e_ml));
        if (t_peer > 0)
            std::printf("  %-10s %10.3f ms   rel. H2 error vs truth: mean %.3g, median %.3g  (%s, median time per fit)\n",
                        "peer", t_peer * 1e3, ep_mean, ep_med, note.c_str());
        else if (!a.has("no-peer"))
            std::printf("  peer unavailable: %s\n", note.c_str());
        std::printf("\n");
    }
    if ((!only || only == 3) && !a.has("no-peer")) bench_structures(dir, min_s, runs);
    if (!only || only == 4) bench_process(dir);
    if (!only) {   // the multiple-experiment ML on case M1 (cmd_bench_multi.cpp), 50 runs per N
        std::vector<std::string> mv = {"msid", "bench", "fit", "--only", "multi", "--runs", "50"};
        if (a.has("no-peer")) mv.push_back("--no-peer");
        std::vector<char *> mp;
        for (auto &x : mv) mp.push_back(&x[0]);
        std::printf("\n");
        cmd_bench_fit_multi((int)mp.size(), mp.data());
    }
    std::string rm = "rm -rf '" + dir + "'";
    if (std::system(rm.c_str()) != 0) std::fprintf(stderr, "msid bench: note: could not remove %s\n", dir.c_str());
    if (!only) {   // discrete-cISSIM on its own simulated records (cmd_bench_cissim.cpp)
        std::string ns = std::to_string(NS);
        char a0[] = "msid", a1[] = "bench", a2[] = "fit", a3[] = "--quick", a4[] = "--systems";
        char *cargv[] = {a0, a1, a2, a3, a4, &ns[0], nullptr};
        std::printf("\n");
        cmd_bench_cissim(6, cargv);
    }
    return 0;
}

}  // namespace msidcli
