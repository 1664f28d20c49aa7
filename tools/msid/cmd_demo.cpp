// msid demo: the whole chain without hardware. msid-devsim serves a known 2x2 plant with coloured
// noise on Modbus TCP loopback (a free port); `msid measure` designs the excitation, measures every
// experiment over the real Modbus stack, fits a model (ml), validates and plots into ./msid-demo/;
// then the true poles beside the estimated ones, the fit error, the coverage of the 95% regions and
// the validation verdict. The simulator is stopped in every case (errors, Ctrl-C included).
#include "commands.hpp"
#include "devsim_child.hpp"
#include "host_libs.hpp"
#include "measure.hpp"
#include "measure_outputs.hpp"

#include "frf_import.hpp"
#include "model_io.hpp"
#include "models.hpp"
#include "msid_fit_job.hpp"

#include <cerrno>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstring>
#include <memory>
#include <sys/stat.h>
#include <unistd.h>

namespace msidcli {

static const char *DEMO_HELP =
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

struct DemoArgs {
    std::string dir = "msid-demo", order = "4";
    uint64_t seed = 2026;
    uint32_t K = 8;
    bool quiet = false, plots = true;
};

// The simulator's set-up: rate, noise levels (output noise coloured by an AR(1) pole) and the design.
constexpr double FS = 1000.0, SIGMA_Y = 0.02, COLOR = 0.7, SIGMA_U = 0.002;
constexpr uint32_t PERIOD = 1024;
static const char *const LINES = "2,3,5,8,12,17,20,25,35,50,80,92,150,300";

static void interrupted_check()
{
    if (measure_stop_requested()) throw Error("interrupted", 128 + measure_stop_signal());
}

static DemoArgs parse_demo(int argc, char **argv)
{
    Args a(argc, argv, 2, DEMO_HELP, {"out", "seed", "periods", "order"}, {"quiet", "no-plots"});
    if (!a.positional().empty()) throw UsageError("unexpected argument '" + a.positional()[0] + "'");
    DemoArgs o;
    o.dir = a.get("out", o.dir);
    o.seed = a.u64("seed", o.seed);
    o.K = a.u32("periods", o.K);
    if (o.K < 3) throw UsageError("--periods must be at least 3 (one is skipped as transient)");
    o.order = a.get("order", o.order);
    o.quiet = a.has("quiet");
    o.plots = !a.has("no-plots");
    return o;
}

// Step 1: the plant and the simulator serving it (its exact FRF written to DIR/truth.json).
static std::unique_ptr<Devsim> start_simulator(const DemoArgs &o, const DemoPlant &pl)
{
    if (::mkdir(o.dir.c_str(), 0755) != 0 && errno != EEXIST)
        throw Error("cannot create directory '" + o.dir + "': " + std::strerror(errno));
    const std::string plant_file = o.dir + "/plant.txt", truth_file = o.dir + "/truth.json";
    write_file_atomic(plant_file, pl.text());
    ::unlink(truth_file.c_str());
    return std::make_unique<Devsim>(std::vector<std::string>{
        find_devsim(), "--modbus-tcp", "127.0.0.1:0", "--plant", plant_file, "--noise-y", fmt("%g", SIGMA_Y),
        "--noise-color", fmt("%g", COLOR), "--noise-u", fmt("%g", SIGMA_U), "--seed", std::to_string(o.seed),
        "--truth", truth_file, "--idle-exit", "30"});
}

// Step 2: design + measure + fit + plots, exactly as `msid measure` with these options.
static MeasureRun measure_plant(const DemoArgs &o, const std::string &uri, const std::string &command_line)
{
    std::vector<std::string> margs = {"msid", "measure", "--device", uri, "--period", std::to_string(PERIOD),
                                      "--lines", LINES, "--amplitudes", "0.5", "--seed", std::to_string(o.seed),
                                      "--experiments", "2", "--periods", std::to_string(o.K), "--skip-periods", "1",
                                      "--fs", fmt("%g", FS), "--fit", "ml", "--order", o.order, "-o", o.dir};
    if (!o.plots) margs.push_back("--no-plots");
    std::vector<char *> av;
    for (auto &s : margs) av.push_back(&s[0]);
    Args ma((int)av.size(), av.data(), 2, measure_keys(), {"no-plots", "quiet"});
    MeasureOptions mo = parse_measure_command(ma);
    mo.quiet_fit = true;
    mo.command_line = command_line;
    Progress pg(stderr, is_terminal(stderr), o.quiet);
    return run_measure(mo, pg);
}

// Step 3: the estimates against the simulator's exact FRF.
struct Score {
    size_t inside = 0, total = 0;        // true FRF values inside their 95% region, of all
    double e_frf = 0, e_model = 0, g_norm = 0;   // squared errors of the FRF and the model, |G0|^2
    double expected() const { return 0.95 * (double)total; }
    double sd() const { return std::sqrt((double)total * 0.95 * 0.05); }
};

static Score score_against_truth(const Json &doc, const Json &truth, const msidfit::ModelFile *mf)
{
    const auto &lines = doc["lines"];
    const uint32_t ny = 2, nu = 2;
    Score s;
    for (size_t l = 0; l < lines.size(); ++l) {
        const uint32_t b = lines[l]["bin"].get<uint32_t>();
        const Json *tl = nullptr;
        for (const auto &t : truth["lines"])
            if (t["bin"].get<uint32_t>() == b) tl = &t;
        if (!tl) throw Error(fmt("the simulator's truth has no line at bin %u", b));
        const double dof = lines[l]["dof"].get<double>();
        const double fq = dof * (std::pow(0.05, -1.0 / dof) - 1.0);   // |e|^2/v ~ F(2, 2 dof): 95% radius^2 / v
        const std::complex<double> z = std::polar(1.0, 2 * M_PI * b / PERIOD);
        msidfit::MatC Gm;
        if (mf) Gm = mf->lmfd ? msidfit::lmfd_eval(*mf->lmfd, z) : msidfit::ss_eval(mf->ss, z);
        for (uint32_t i = 0; i < ny; ++i)
            for (uint32_t j = 0; j < nu; ++j) {
                const std::complex<double> G(lines[l]["G"]["re"][i][j].get<double>(), lines[l]["G"]["im"][i][j].get<double>());
                const std::complex<double> G0((*tl)["G"]["re"][i][j].get<double>(), (*tl)["G"]["im"][i][j].get<double>());
                const size_t v = i + (size_t)ny * j;
                const double var = lines[l]["cov"]["re"][v][v].get<double>();
                s.inside += std::norm(G - G0) <= var * fq;
                ++s.total;
                s.e_frf += std::norm(G - G0);
                s.g_norm += std::norm(G0);
                if (mf) s.e_model += std::norm(std::complex<double>(Gm((Eigen::Index)i, (Eigen::Index)j)) - G0);
            }
    }
    return s;
}

// Step 4: the true modes beside the fitted model's nearest ones.
static void print_poles(const std::string &model_path, const DemoPlant &pl)
{
    const Json model = read_json_file(model_path);
    std::printf("\npoles: true against estimated (ml fit, order %s)\n", model.value("order", Json()).dump().c_str());
    std::printf("  %-6s %12s %20s %10s %20s\n", "mode", "f true [Hz]", "f est [Hz] +- sd", "zeta true", "zeta est +- sd");
    auto num = [](const Json &m, const char *key) { return m.contains(key) && m[key].is_number() ? m[key].get<double>() : NAN; };
    for (int k = 0; k < 2; ++k) {
        const double f0 = pl.fn(k, FS), z0 = pl.zeta(k);
        const Json *best = nullptr;
        double bd = 1e300;
        if (model.contains("modes") && model["modes"].contains("modes"))
            for (const auto &m : model["modes"]["modes"])
                if (m.contains("fn") && m["fn"].is_number() && std::fabs(m["fn"].get<double>() - f0) < bd) {
                    bd = std::fabs(m["fn"].get<double>() - f0);
                    best = &m;
                }
        if (best)
            std::printf("  %-6d %12.4f %11.4f +- %-6.2g %10.4f %11.4f +- %-6.2g\n", k + 1, f0, num(*best, "fn"),
                        num(*best, "sd_fn"), z0, num(*best, "zeta"), num(*best, "sd_zeta"));
        else
            std::printf("  %-6d %12.4f %20s %10.4f\n", k + 1, f0, "(none)", z0);
    }
}

// Step 5: the model against the measured FRF (msid validate's library call), its report written to
// DIR/validation.json, its verdict printed.
static void validate_model(const DemoArgs &o, const msidfit::ModelFile &mf, const std::string &frf_path)
{
    try {
        const Json frf_doc = msidfrfimport::load_document(frf_path, "");
        const msidfitjob::ValidateOutcome v =
            msidfitjob::validate_frf(mf, msidfrf::parse_frf(frf_doc, frf_path), frf_doc, msidfitjob::ValidateRequest{});
        write_json_file(o.dir + "/validation.json", v.report, false);
        const Json &r = v.report;
        std::printf("validation: weighted cost %.4g, expected %.4g, p-value %.3g: %s\n", r["cost"].get<double>(),
                    r["expected"].get<double>(), r["p_value"].get<double>(),
                    r["consistent_at_5pct"].get<bool>() ? "the model is consistent with the data at 5%"
                                                        : "the model is NOT consistent with the data at 5%");
    } catch (const msidfit::FitError &e) {
        throw Error(e.what());
    }
}

int cmd_demo(int argc, char **argv)
{
    const DemoArgs o = parse_demo(argc, argv);
    const DemoPlant pl;
    StopOnSignal stop_guard;   // Ctrl-C: the simulator is stopped, what was measured is kept
    std::unique_ptr<Devsim> sim = start_simulator(o, pl);
    interrupted_check();
    const std::string uri = fmt("modbus-tcp://127.0.0.1:%d", sim->port());
    if (!o.quiet)
        std::printf("msid demo: msid-devsim serves a 4-state 2x2 plant (modes at %.1f Hz and %.1f Hz) on %s\n"
                    "  with coloured output noise (AR(1) pole %.1f, innovation std %.3g) and input noise (std %.3g);\n"
                    "  2 experiments x %u periods of %u samples, the first skipped (transient), fs %.0f Hz.\n\n",
                    pl.fn(0, FS), pl.fn(1, FS), uri.c_str(), COLOR, SIGMA_Y, SIGMA_U, o.K, PERIOD, FS);
    std::fflush(stdout);

    const MeasureRun run = measure_plant(o, uri, shell_line(argc, argv));
    sim->stop();
    if (!run.m.complete) {
        std::fprintf(stderr, "msid demo: interrupted: %s holds the FRF of the complete periods\n", run.frf.c_str());
        return 128 + measure_stop_signal();
    }
    interrupted_check();

    std::unique_ptr<msidfit::ModelFile> mf;
    if (!run.model.empty()) mf = std::make_unique<msidfit::ModelFile>(msidfit::read_model(run.model));
    const Score s = score_against_truth(run.m.o.doc.is_null() ? msidjob::frf_document(run.m.o.frf) : run.m.o.doc, read_json_file(o.dir + "/truth.json"), mf.get());
    if (mf && !o.quiet) print_poles(run.model, pl);
    std::printf("\n%zu of %zu true FRF values lie inside their 95%% region (expected %.1f +- %.1f).\n", s.inside,
                s.total, s.expected(), s.sd());
    std::printf("FRF error against the true plant: %.3g%% relative RMS (nonparametric estimate)",
                100 * std::sqrt(s.e_frf / s.g_norm));
    if (mf) std::printf(", %.3g%% (fitted model)", 100 * std::sqrt(s.e_model / s.g_norm));
    std::printf("\n");
    if (!run.fit_error.empty()) std::printf("fit: FAILED: %s\n", run.fit_error.c_str());
    if (mf) validate_model(o, *mf, run.frf);
    if (!run.plot_note.empty()) std::printf("%s\n", run.plot_note.c_str());
    std::printf("files: %s/{plant.txt,truth.json,design.json,frf.json%s}\n", o.dir.c_str(),
                mf ? ",model.json,validation.json" : "");
    // the same measurement by hand, as a shell runs it: the binaries by their paths (they need not be
    // on PATH), the sample rate (modes in Hz), and the simulator stopped at the end
    std::printf("measure it yourself (the simulator in the background, msid against it, the simulator stopped):\n"
                "  %s --modbus-tcp 127.0.0.1:1502 --plant %s/plant.txt & %s measure --device modbus-tcp://127.0.0.1:1502 "
                "--design %s/design.json --skip-periods 1 --fs %g --fit ml -o out; kill $!\n",
                find_devsim().c_str(), o.dir.c_str(), self_path().c_str(), o.dir.c_str(), FS);
    int rc = run.fit_error.empty() ? 0 : 1;
    // A demo that misses badly is a failure, not a success.
    if ((double)s.inside + 4 * s.sd() < s.expected()) {
        std::fprintf(stderr, "msid demo: error: coverage far below 95%%\n");
        rc = 1;
    }
    return rc;
}

}  // namespace msidcli
