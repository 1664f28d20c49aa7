// msid demo: the whole chain without hardware. msid-devsim serves a known 2x2 plant with coloured
// noise on Modbus TCP loopback (a free port); `msid measure` designs the excitation, measures every
// experiment over the real Modbus stack, fits a model (ml), validates and plots into ./msid-demo/;
// then the true poles beside the estimated ones, the fit error, the coverage of the 95% regions and
// the validation verdict. The simulator is stopped in every case (errors, Ctrl-C included).
#include "commands.hpp"
#include "host_libs.hpp"
#include "measure.hpp"
#include "measure_outputs.hpp"

#include "model_io.hpp"
#include "models.hpp"
#include "text_scan.hpp"

#include <cerrno>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstring>
#include <poll.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace msidcli {

static const char *HELP =
    "usage: msid demo [--out DIR] [--seed S] [--periods K] [--order n|auto] [--no-plots] [--quiet]\n"
    "\n"
    "Starts msid-devsim on Modbus TCP loopback (a free port) with a known 4-state 2x2 plant, coloured\n"
    "output noise and input measurement noise, and runs `msid measure` on it: 2 experiments x K periods\n"
    "(default 8, the first skipped), `--fit ml --order 4` (or --order), validation and plots into DIR\n"
    "(default msid-demo). Prints the true poles beside the estimated ones, the fit error, how many true\n"
    "FRF values lie inside their 95% regions, and the validation verdict. Exit status 1 when the\n"
    "coverage is far below 95%. Needs msid-devsim next to msid (or MSID_DEVSIM), no privileges.\n";

// The plant: two lightly damped modes, coupled 2x2, discrete time at a nominal fs = 1 kHz.
struct DemoPlant {
    double r[2] = {0.97, 0.95}, th[2] = {2 * M_PI * 0.02, 2 * M_PI * 0.09};
    double A[16], B[8] = {0.10, 0.02, 0.00, 0.05, 0.04, 0.10, 0.08, 0.00};
    double C[8] = {1.0, 0.0, 0.6, 0.2, 0.3, 0.5, 0.0, 1.0}, D[4] = {0.05, 0.0, 0.0, 0.02};
    DemoPlant()
    {
        std::memset(A, 0, sizeof A);
        for (int k = 0; k < 2; ++k) {
            const int o = 2 * k;
            A[o * 4 + o] = r[k] * std::cos(th[k]);
            A[o * 4 + o + 1] = -r[k] * std::sin(th[k]);
            A[(o + 1) * 4 + o] = r[k] * std::sin(th[k]);
            A[(o + 1) * 4 + o + 1] = r[k] * std::cos(th[k]);
        }
    }
    // natural frequency (Hz) and damping ratio of mode k: s = fs ln z
    double fn(int k, double fs) const { return std::abs(std::log(std::polar(r[k], th[k]))) * fs / (2 * M_PI); }
    double zeta(int k) const { const auto s = std::log(std::polar(r[k], th[k])); return -s.real() / std::abs(s); }
    // msid-devsim's plant file format (firmware_sim/plant.c)
    std::string text() const
    {
        std::string s = "# msid demo plant: two modes, |z| = 0.97 at 0.02 and 0.95 at 0.09 cycles/sample\n"
                        "type dt states 4 inputs 2 outputs 2\n";
        auto mat = [&](const char *name, const double *v, int n) {
            s += name;
            for (int i = 0; i < n; ++i) s += fmt(" %.17g", v[i]);
            s += "\n";
        };
        mat("A", A, 16);
        mat("B", B, 8);
        mat("C", C, 8);
        mat("D", D, 4);
        return s;
    }
};

// This msid's own path ("msid" when the system does not say).
static std::string self_path()
{
    char self[4096];
    const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return "msid";
    self[n] = 0;
    return self;
}

// msid-devsim: the environment's MSID_DEVSIM, next to msid, in the build tree, or on PATH.
static std::string find_devsim()
{
    if (const char *e = std::getenv("MSID_DEVSIM"); e && *e) return e;
    const std::string self = self_path();
    if (self.find('/') != std::string::npos) {
        const std::string dir = self.substr(0, self.rfind('/'));
        for (const std::string &p : {dir + "/msid-devsim", dir + "/../firmware_sim/msid-devsim"}) {
            char real[4096];
            if (access(p.c_str(), X_OK) == 0) return realpath(p.c_str(), real) ? std::string(real) : p;
        }
    }
    return "msid-devsim";
}

// The simulator as a child process: its own process group (a terminal's Ctrl-C reaches msid, which
// stops the measurement cleanly first), SIGTERM when msid dies, and --idle-exit as the last resort.
class Devsim {
public:
    Devsim(const std::vector<std::string> &args)
    {
        pid_ = spawn_piped(args, {}, true, &out_);
        if (pid_ < 0) throw Error("cannot start " + args[0] + ": " + std::strerror(errno));
        // the ready line names the port
        std::string text;
        for (int waited = 0; waited < 200 && text.find('\n') == std::string::npos; ++waited) {
            pollfd p{out_, POLLIN, 0};
            if (poll(&p, 1, 100) <= 0) continue;
            char buf[512];
            const ssize_t k = read(out_, buf, sizeof buf);
            if (k <= 0) break;
            text.append(buf, (size_t)k);
        }
        const std::string line = text.substr(0, text.find('\n'));
        static const std::string ready = "ready on modbus-tcp 127.0.0.1:";   // then the port's digits
        const size_t at = line.find(ready);
        size_t i = at == std::string::npos ? 0 : at + ready.size();
        const std::string port = at == std::string::npos ? std::string() : msidfit::scan_digits(line, i);
        if (port.empty()) {
            stop();
            throw Error("msid-devsim (" + args[0] + ") did not start: " + (line.empty() ? "no output in 20 s" : line));
        }
        port_ = std::stoi(port);
    }
    ~Devsim() { stop(); }
    int port() const { return port_; }
    void stop()
    {
        if (pid_ > 0) {
            kill(pid_, SIGCONT);
            kill(pid_, SIGTERM);
            int st;
            for (int i = 0; i < 100 && waitpid(pid_, &st, WNOHANG) == 0; ++i) usleep(20000);
            if (waitpid(pid_, &st, WNOHANG) == 0) {
                kill(pid_, SIGKILL);
                waitpid(pid_, &st, 0);
            }
            pid_ = -1;
        }
        if (out_ >= 0) { close(out_); out_ = -1; }
    }

private:
    pid_t pid_ = -1;
    int out_ = -1, port_ = 0;
};

struct DemoArgs {
    std::string dir = "msid-demo", order = "4";
    uint64_t seed = 2026;
    uint32_t K = 8;
    bool quiet = false, plots = true;
};

static void interrupted_check()
{
    if (measure_stop_requested()) throw Error("interrupted", 128 + measure_stop_signal());
}

int cmd_demo(int argc, char **argv)
{
    Args a(argc, argv, 2, HELP, {"out", "seed", "periods", "order"}, {"quiet", "no-plots"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    DemoArgs o;
    o.dir = a.get("out", o.dir);
    o.seed = a.u64("seed", o.seed);
    o.K = a.u32("periods", o.K);
    if (o.K < 3) throw UsageError("--periods must be at least 3 (one is skipped as transient)");
    o.order = a.get("order", o.order);
    o.quiet = a.has("quiet");
    o.plots = !a.has("no-plots");
    const double fs = 1000.0;
    const double sigma_y = 0.02, color = 0.7, sigma_u = 0.002;
    const DemoPlant pl;

    StopOnSignal stop_guard;   // Ctrl-C: the simulator is stopped, what was measured is kept
    if (::mkdir(o.dir.c_str(), 0755) != 0 && errno != EEXIST)
        throw Error("cannot create directory '" + o.dir + "': " + std::strerror(errno));
    const std::string plant_file = o.dir + "/plant.txt", truth_file = o.dir + "/truth.json";
    write_file_atomic(plant_file, pl.text());
    ::unlink(truth_file.c_str());
    Devsim sim({find_devsim(), "--modbus-tcp", "127.0.0.1:0", "--plant", plant_file, "--noise-y", fmt("%g", sigma_y),
                "--noise-color", fmt("%g", color), "--noise-u", fmt("%g", sigma_u), "--seed",
                std::to_string(o.seed), "--truth", truth_file, "--idle-exit", "30"});
    interrupted_check();
    const std::string uri = fmt("modbus-tcp://127.0.0.1:%d", sim.port());
    if (!o.quiet)
        std::printf("msid demo: msid-devsim serves a 4-state 2x2 plant (modes at %.1f Hz and %.1f Hz) on %s\n"
                    "  with coloured output noise (AR(1) pole %.1f, innovation std %.3g) and input noise (std %.3g);\n"
                    "  2 experiments x %u periods of 1024 samples, the first skipped (transient), fs %.0f Hz.\n\n",
                    pl.fn(0, fs), pl.fn(1, fs), uri.c_str(), color, sigma_y, sigma_u,
                    o.K, fs);
    std::fflush(stdout);

    // design + measure + fit + plots: exactly `msid measure`
    std::vector<std::string> margs = {"msid", "measure", "--device", uri, "--period", "1024", "--lines",
                                      "2,3,5,8,12,17,20,25,35,50,80,92,150,300", "--amplitudes", "0.5", "--seed",
                                      std::to_string(o.seed), "--experiments", "2", "--periods", std::to_string(o.K),
                                      "--skip-periods", "1", "--fs", fmt("%g", fs), "--fit", "ml", "--order", o.order,
                                      "-o", o.dir};
    if (!o.plots) margs.push_back("--no-plots");
    std::vector<char *> av;
    for (auto &s : margs) av.push_back(&s[0]);
    Args ma((int)av.size(), av.data(), 2, measure_keys(), {"no-plots", "quiet"});
    MeasureOptions mo = parse_measure_command(ma);
    mo.quiet_fit = true;
    mo.command_line = shell_line(argc, argv);
    Progress pg(stderr, is_terminal(stderr), o.quiet);
    MeasureRun run = run_measure(mo, pg);
    sim.stop();
    const bool complete = run.m.complete;
    if (!complete) {
        std::fprintf(stderr, "msid demo: interrupted: %s holds the FRF of the complete periods\n", run.frf.c_str());
        return 128 + measure_stop_signal();
    }
    interrupted_check();

    // coverage of the 95% regions against the simulator's exact FRF
    const Json &doc = run.m.o.doc;
    const Json truth = read_json_file(truth_file);
    const auto &lines = doc["lines"];
    const uint32_t ny = 2, nu = 2, P = 1024;
    size_t inside = 0, total = 0;
    double e_frf = 0, e_model = 0, g_norm = 0;
    std::unique_ptr<msidfit::ModelFile> mf;
    if (!run.model.empty()) mf = std::make_unique<msidfit::ModelFile>(msidfit::read_model(run.model));
    for (size_t l = 0; l < lines.size(); ++l) {
        const uint32_t b = lines[l]["bin"].get<uint32_t>();
        const Json *tl = nullptr;
        for (const auto &t : truth["lines"])
            if (t["bin"].get<uint32_t>() == b) tl = &t;
        if (!tl) throw Error(fmt("the simulator's truth has no line at bin %u", b));
        const double dof = lines[l]["dof"].get<double>();
        const double fq = dof * (std::pow(0.05, -1.0 / dof) - 1.0);   // |e|^2/v ~ F(2, 2 dof): 95% radius^2 / v
        const std::complex<double> z = std::polar(1.0, 2 * M_PI * b / P);
        msidfit::MatC Gm;
        if (mf) Gm = mf->lmfd ? msidfit::lmfd_eval(*mf->lmfd, z) : msidfit::ss_eval(mf->ss, z);
        for (uint32_t i = 0; i < ny; ++i)
            for (uint32_t j = 0; j < nu; ++j) {
                const std::complex<double> G(lines[l]["G"]["re"][i][j].get<double>(), lines[l]["G"]["im"][i][j].get<double>());
                const std::complex<double> G0((*tl)["G"]["re"][i][j].get<double>(), (*tl)["G"]["im"][i][j].get<double>());
                const size_t v = i + (size_t)ny * j;
                const double var = lines[l]["cov"]["re"][v][v].get<double>();
                inside += std::norm(G - G0) <= var * fq;
                ++total;
                e_frf += std::norm(G - G0);
                g_norm += std::norm(G0);
                if (mf) e_model += std::norm(std::complex<double>(Gm((Eigen::Index)i, (Eigen::Index)j)) - G0);
            }
    }
    const double expct = 0.95 * (double)total, sd = std::sqrt((double)total * 0.95 * 0.05);

    // true against estimated poles
    if (mf && !o.quiet) {
        const Json model = read_json_file(run.model);
        std::printf("\npoles: true against estimated (ml fit, order %s)\n", model.value("order", Json()).dump().c_str());
        std::printf("  %-6s %12s %20s %10s %20s\n", "mode", "f true [Hz]", "f est [Hz] +- sd", "zeta true",
                    "zeta est +- sd");
        for (int k = 0; k < 2; ++k) {
            const double f0 = pl.fn(k, fs), z0 = pl.zeta(k);
            const Json *best = nullptr;
            double bd = 1e300;
            if (model.contains("modes") && model["modes"].contains("modes"))
                for (const auto &m : model["modes"]["modes"])
                    if (m.contains("fn") && m["fn"].is_number() && std::fabs(m["fn"].get<double>() - f0) < bd) {
                        bd = std::fabs(m["fn"].get<double>() - f0);
                        best = &m;
                    }
            auto num = [](const Json &m, const char *key) { return m.contains(key) && m[key].is_number() ? m[key].get<double>() : NAN; };
            if (best)
                std::printf("  %-6d %12.4f %11.4f +- %-6.2g %10.4f %11.4f +- %-6.2g\n", k + 1, f0, num(*best, "fn"),
                            num(*best, "sd_fn"), z0, num(*best, "zeta"), num(*best, "sd_zeta"));
            else
                std::printf("  %-6d %12.4f %20s %10.4f\n", k + 1, f0, "(none)", z0);
        }
    }
    std::printf("\n%zu of %zu true FRF values lie inside their 95%% region (expected %.1f +- %.1f).\n", inside, total,
                expct, sd);
    std::printf("FRF error against the true plant: %.3g%% relative RMS (nonparametric estimate)", 100 * std::sqrt(e_frf / g_norm));
    if (mf) std::printf(", %.3g%% (fitted model)", 100 * std::sqrt(e_model / g_norm));
    std::printf("\n");
    if (!run.fit_error.empty()) std::printf("fit: FAILED: %s\n", run.fit_error.c_str());

    // validation: the model against the measured FRF (msid validate)
    int rc = 0;
    if (mf) {
        const std::string vfile = o.dir + "/validation.json";
        std::vector<std::string> vargs = {"msid", "validate", run.model, run.frf, "-o", vfile};
        std::vector<char *> vv;
        for (auto &s : vargs) vv.push_back(&s[0]);
        {
            SilenceStdout quiet(true);   // msid validate prints its verdict: reported from the file below
            cmd_validate((int)vv.size(), vv.data());
        }
        const Json v = read_json_file(vfile);
        std::printf("validation: weighted cost %.4g, expected %.4g, p-value %.3g: %s\n", v["cost"].get<double>(),
                    v["expected"].get<double>(), v["p_value"].get<double>(),
                    v["consistent_at_5pct"].get<bool>() ? "the model is consistent with the data at 5%"
                                                         : "the model is NOT consistent with the data at 5%");
    }
    if (!run.plot_note.empty()) std::printf("%s\n", run.plot_note.c_str());
    std::printf("files: %s/{plant.txt,truth.json,design.json,frf.json%s}\n", o.dir.c_str(),
                mf ? ",model.json,validation.json" : "");
    // the same measurement by hand, as a shell runs it: the binaries by their paths (they need not be
    // on PATH), the sample rate (modes in Hz), and the simulator stopped at the end
    std::printf("measure it yourself (the simulator in the background, msid against it, the simulator stopped):\n"
                "  %s --modbus-tcp 127.0.0.1:1502 --plant %s & %s measure --device modbus-tcp://127.0.0.1:1502 "
                "--design %s/design.json --skip-periods 1 --fs %g --fit ml -o out; kill $!\n",
                find_devsim().c_str(), plant_file.c_str(), self_path().c_str(), o.dir.c_str(), fs);
    if (!run.fit_error.empty()) rc = 1;
    // A demo that misses badly is a failure, not a success.
    if ((double)inside + 4 * sd < expct) {
        std::fprintf(stderr, "msid demo: error: coverage far below 95%%\n");
        rc = 1;
    }
    return rc;
}

}  // namespace msidcli
