// msid bench: the benchmarks against peers. Each subcommand parses its options into a request of
// msid_bench (tools/bench), runs the benchmark and prints its report as it is written;
// `msid bench can` and `msid bench modbus` run their scripts (cmd_can.cpp, cmd_modbus.cpp).
#include "cli_util.hpp"
#include "commands.hpp"

#include "msid_bench.hpp"

#include <cstdio>
#include <cstring>

namespace msidcli {

namespace {

// The report on stdout as it is written, diagnostics on stderr. `flush`: every piece at once
// (a table whose rows take long each, so that a pipe shows them as they come).
msidbench::Sink console(bool flush = false)
{
    msidbench::Sink s;
    s.out = [flush](const std::string &t) {
        std::fputs(t.c_str(), stdout);
        if (flush) std::fflush(stdout);
    };
    s.err = [](const std::string &t) { std::fputs(t.c_str(), stderr); };
    return s;
}

const char *HELP_FRF =
    "usage: msid bench frf [--quick] [--min-seconds S] [--no-peer] [--measure] [--only 1|2|3]\n"
    "\n"
    "Times the FRF job (line DFT, period statistics, LS FRF with both covariances) on\n"
    "  P=1024, 20 lines, 1x1;  P=4096, 200 lines, 2 inputs x 4 outputs, 2 experiments;\n"
    "  P=65536, 10000 lines, 1 input x 2 outputs\n"
    "for the streaming and FFTW paths, FFTW's own per-period transforms (C real FFTs of\n"
    "length P) as the floor of the FFT path, and a NumPy peer of the same job.\n"
    "--measure plans FFTW with FFTW_MEASURE (default FFTW_ESTIMATE, as `msid frf`).\n";

int bench_frf(int argc, char **argv)
{
    Args a(argc, argv, 3, HELP_FRF, {"min-seconds", "only"}, {"quick", "no-peer", "measure"});
    msidbench::FrfBenchRequest rq;
    rq.only = a.u32("only", rq.only);
    rq.min_seconds = a.f64("min-seconds", rq.min_seconds);
    if (a.has("quick")) rq.min_seconds = 0.1;
    rq.fftw_measure = a.has("measure");
    rq.peer = !a.has("no-peer");
    return msidbench::bench_frf(rq, console()).report.status;
}

const char *HELP_FIT =
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
    "--only modal FRF.json: the order scan of a structure's FRF against LSCF (msid bench fit --only modal -h).\n"
    "Without --only it also runs `msid bench fit --only multi --runs 50` (case M1, multiple experiments)\n"
    "and, last, the cissim benchmark with --quick and the same --systems. --only cissim (or --cissim):\n"
    "discrete-cISSIM, `msid bench fit --cissim --help`. --cissim-process: the whole cissim process against\n"
    "the authors' code under Octave, `msid bench fit --cissim-process --help`.\n";

const char *HELP_MULTI =
    "usage: msid bench fit --only multi [--runs K] [--no-peer]\n"
    "Case M1 (Markovsky & Pintelon §VII): CT order 6, 2 pi {80,130,200} rad/s, damping {0.15,0.1,0.2},\n"
    "ts = 1e-3, SNR 100 (rms amplitude ratio), ring-downs of 60..120 samples with random initial\n"
    "conditions. 1: rms parameter error against N = 1..50 (K runs each, default 200), slope of\n"
    "log error on log N; 2: empirical covariance against the Cramer-Rao bound (fixed initial\n"
    "conditions); 3: time per fit against the SciPy peer (initial conditions as parameters).\n";

const char *HELP_MODAL =
    "usage: msid bench fit --only modal FRF.json [--baseline MSID] [--runs N] [--no-peer]\n"
    "The order scan of a structure's FRF, `msid fit --method ml --domain ct --order auto FRF.json`, as a whole\n"
    "process: the CPU time of the best of N runs (default 1) after one warm-up, the chosen order and its\n"
    "modes; beside it sdypy-EMA's LSCF over its polynomial orders 2..60 on the same FRF (the modes stable\n"
    "over its orders 30-60)\n"
    "and, with --baseline, another msid executable's same scan (a previous build) with the speed ratio.\n";

const char *HELP_CISSIM =
    "usage: msid bench fit --cissim | --only cissim [--systems N] [--quick]\n"
    "Discrete-cISSIM (You et al. 2023): case Y1 (Table 3: N random 4th-order SISO systems, default\n"
    "100, periodic chirp 0 -> 0.4 pi, T = 3000, N = 720000, 30 dB) for cissim full / reduced against\n"
    "subspace and ml on the core FRF of the same samples; the speed of the authors' reference size\n"
    "(24 periods of 3000 samples, 1200 lines); 50 sparse lines at 20 dB on lightly damped systems;\n"
    "the covariance errors of case Y2 at N = 24k, 60k, 240k. --quick: 10 systems, fewer runs.\n"
    "Rows: the published (unweighted) Alg. 4, the weighted one, and the ML refinement (--refine ml);\n"
    "times per system as wall and thread CPU time (the machine may be shared).\n";

const char *HELP_CISSIM_PROCESS =
    "usage: msid bench fit --cissim-process [--min-seconds S] [--no-peer] [--keep DIR]\n"
    "The whole `msid fit --method cissim` process (start, reading, fit with the default ML refinement and\n"
    "noise covariance, writing the model; .npy and CSV) on two cases: a 2x2 record (order 4,\n"
    "P = 2000, 60,000 samples, 300 lines, 30 dB) and a sparse SISO one (lightly damped, 72,000 samples,\n"
    "50 lines, 20 dB), against the whole run of the authors' discrete-cISSIM code under Octave on the same\n"
    "samples when MSID_DCISSIM_DIR names a checkout of it (github wyqy/dcissim) and octave-cli is on PATH\n"
    "(driver and stand-ins: tools/peers/dcissim). Accuracy: relative H2 error against the true system,\n"
    "and the FRF agreement of the reference with msid's paper estimate on the same terms. Best of >= 3\n"
    "runs lasting >= S seconds (default 2); --keep DIR keeps the files.\n";

int bench_cissim_process(int argc, char **argv)
{
    Args a(argc, argv, 3, HELP_CISSIM_PROCESS, {"min-seconds", "keep"}, {"cissim-process", "no-peer"});
    msidbench::CissimProcessBenchRequest rq;
    rq.min_seconds = a.f64("min-seconds", rq.min_seconds);
    rq.peer = !a.has("no-peer");
    rq.keep = a.get("keep", "");
    return msidbench::bench_cissim_process(rq, console(true)).report.status;
}

int bench_fit_multi(int argc, char **argv)
{
    Args a(argc, argv, 3, HELP_MULTI, {"only", "runs"}, {"no-peer"});
    msidbench::MultiBenchRequest rq;
    rq.runs = (int)a.u32("runs", (uint32_t)rq.runs);
    rq.peer = !a.has("no-peer");
    return msidbench::bench_fit_multi(rq, console()).report.status;
}

int bench_fit_modal(int argc, char **argv)
{
    Args a(argc, argv, 3, HELP_MODAL, {"only", "baseline", "runs"}, {"no-peer"});
    if (a.positional().size() != 1) throw UsageError("give one FRF file: msid bench fit --only modal FRF.json");
    msidbench::ModalBenchRequest rq;
    rq.frf = a.positional()[0];
    rq.baseline = a.get("baseline", "");
    rq.runs = a.u32("runs", rq.runs);
    rq.peer = !a.has("no-peer");
    return msidbench::bench_fit_modal(rq, console()).report.status;
}

int bench_cissim(int argc, char **argv)
{
    Args a(argc, argv, 3, HELP_CISSIM, {"systems", "only"}, {"cissim", "quick"});
    msidbench::CissimBenchRequest rq;
    rq.quick = a.has("quick");
    rq.systems = (int)a.u32("systems", rq.quick ? 10 : 100);
    return msidbench::bench_cissim(rq, console()).report.status;
}

// --only multi and --only cissim (or --cissim) are benchmarks of their own, with their own options.
bool only_is(int argc, char **argv, const char *what)
{
    for (int i = 3; i + 1 < argc; ++i)
        if (!std::strcmp(argv[i], "--only") && !std::strcmp(argv[i + 1], what)) return true;
    return false;
}

int bench_fit(int argc, char **argv)
{
    if (only_is(argc, argv, "multi")) return bench_fit_multi(argc, argv);
    if (only_is(argc, argv, "modal")) return bench_fit_modal(argc, argv);
    for (int i = 3; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--cissim")) return bench_cissim(argc, argv);
        if (!std::strcmp(argv[i], "--cissim-process")) return bench_cissim_process(argc, argv);
    }
    if (only_is(argc, argv, "cissim")) return bench_cissim(argc, argv);
    Args a(argc, argv, 3, HELP_FIT, {"systems", "min-seconds", "only", "runs"}, {"no-peer"});
    msidbench::FitBenchRequest rq;
    rq.only = a.u32("only", rq.only);
    rq.systems = (int)a.u32("systems", (uint32_t)rq.systems);
    rq.min_seconds = a.f64("min-seconds", rq.min_seconds);
    rq.runs = a.u32("runs", rq.runs);
    rq.peer = !a.has("no-peer");
    return msidbench::bench_fit(rq, console()).report.status;
}

int bench_lpm(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid bench lpm [--samples N] [--runs K] [--no-peer]\n"
        "Times `msid frf --method lpm` without file I/O (FFTW spectra + local LS at every bin,\n"
        "R = 2, default window) on a simulated 2x2 record of N samples (default 10^6), best of K\n"
        "runs (default 3) with 1 and 2 threads, and the NumPy peer on the same samples.\n";
    Args a(argc, argv, 3, HELP, {"samples", "runs"}, {"no-peer"});
    msidbench::LpmBenchRequest rq;
    rq.samples = a.u64("samples", rq.samples);
    rq.runs = a.u32("runs", rq.runs);
    rq.peer = !a.has("no-peer");
    return msidbench::bench_lpm(rq, console()).report.status;
}

int bench_io(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid bench io [--min-seconds S] [--no-peer] [--keep DIR]\n"
        "\n"
        "Times `msid frf` end to end (process start, reading, FRF job, writing the\n"
        "msid-frf/1 file) on 2 experiments x 262,144 rows x 4 columns (2 inputs, 2\n"
        "outputs; P = 4096, 64 periods, 200 lines) stored as CSV (24 MB), .npy and\n"
        ".mat v5, against pandas.read_csv / numpy.load / scipy.io.loadmat plus the\n"
        "NumPy FRF job of `msid bench frf` on the same files in the same run.\n";
    Args a(argc, argv, 3, HELP, {"min-seconds", "keep"}, {"no-peer"});
    msidbench::IoBenchRequest rq;
    rq.min_seconds = a.f64("min-seconds", rq.min_seconds);
    rq.keep = a.get("keep");
    rq.peer = !a.has("no-peer");
    return msidbench::bench_io(rq, console()).report.status;
}

int bench_target(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid bench target\n"
        "Runs build/target/<cpu>/bench_target.elf on qemu-system-arm -icount shift=0 (one instruction\n"
        "= 1 ns of virtual time, read with SysTick at 25 MHz: 40-instruction resolution for maxima)\n"
        "and prints instructions per sample of generation + streaming estimation, the per-line*channel\n"
        "slope, msid_*_mem_size of the standard configurations and the flash of each lib/ object.\n";
    const Args a(argc, argv, 3, HELP, {}, {});
    if (!a.positional().empty()) throw UsageError("msid bench target: unexpected argument " + a.positional()[0]);
    return msidbench::bench_target(msidbench::TargetBenchRequest{}, console()).report.status;
}

int bench_wcet(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid bench wcet [--samples N]   (default 1e7, at least 1e5)\n"
        "Per-sample time of msid_gen_next + msid_meas_push(1 row) on the host, each sample timed with\n"
        "CLOCK_MONOTONIC: median, p99, p99.9, max, and the max of period-end samples separately;\n"
        "the \"spread\" cases defer the period-end work over the next period (msid_meas_cfg.spread).\n";
    const Args a(argc, argv, 3, HELP, {"samples"}, {});
    if (!a.positional().empty()) throw UsageError("msid bench wcet: unexpected argument " + a.positional()[0]);
    msidbench::WcetBenchRequest rq;
    rq.samples = a.u64("samples", rq.samples);
    return msidbench::bench_wcet(rq, console()).report.status;
}

int bench_crest(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid bench crest [--quick] [--no-peer] [--direct-max P]\n"
        "Design set-up time for large periods: msid_design_init of a 2-input,\n"
        "2-experiment Schroeder multisine with 1000 lines at P = 2^12 ... 2^22, the crest factors\n"
        "computed by FFT (MSID_CREST_FFT, what the host uses) and by direct synthesis\n"
        "(MSID_CREST_DIRECT, only up to --direct-max, default 2^18: it is O(m nu P L)), beside a NumPy\n"
        "peer (one irfft per input) on the same coefficients. Wall and CPU time (the machine may be\n"
        "shared), and the largest relative difference of the crest factors. --quick: P up to 2^16.\n";
    const Args a(argc, argv, 3, HELP, {"direct-max"}, {"quick", "no-peer"});
    msidbench::CrestBenchRequest rq;
    rq.direct_max = a.u64("direct-max", rq.direct_max);
    rq.quick = a.has("quick");
    rq.peer = !a.has("no-peer");
    return msidbench::bench_crest(rq, console(true)).report.status;
}

// msid bench ticks: tests/modbus/bench_ticks.py with this build's msid and msid-devsim; --can: the vcan VM
// (tests/vcan/vm.py) running tests/vcan/in_vm/bench_ticks_can.py
int bench_ticks(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid bench ticks [--rate HZ] [--periods K] [--instructions]\n"
        "       msid bench ticks --can [--rate HZ] [--periods K] [--instructions] [--results DIR]\n"
        "       msid bench ticks --canopen [--rate HZ] [--periods K] [--results DIR]\n"
        "The host tick loop of a described device (msid measure --map) beside the same loop written as a user\n"
        "would without msid, in the same run against the same msid-devsim: ticks, lateness median/p99/max, round\n"
        "trip, CPU per tick. Default: 200 Hz over Modbus TCP on 127.0.0.1, the peer written with pymodbus and\n"
        "time.sleep; --instructions: also the user-space instructions per tick of both loops under valgrind's\n"
        "callgrind, which no load changes. --can: 1 kHz on vcan0 in the qemu VM of tests/vcan/vm.py against\n"
        "msid-devsim's DBC node, the peer written with python-can and cantools, with the command frames' jitter\n"
        "on the bus and that of the kernel's broadcast manager (CAN_BCM) beside them. --canopen: the SYNC loop of\n"
        "a CiA 402 drive in CST (msid measure over canopen://) at 1 kHz in the same VM against msid-devsim's node,\n"
        "the peer written with the canopen package, with the SYNC frames' jitter on the bus and a CAN_BCM SYNC\n"
        "timer's beside them. See docs/benchmarks.md.\n";
    const Args a(argc, argv, 3, HELP, {"rate", "periods", "results"}, {"instructions", "can", "canopen"});
    if (!a.positional().empty()) throw UsageError("msid bench ticks: unexpected argument " + a.positional()[0]);
    const bool canopen = a.has("canopen");
    if (canopen && a.has("can")) throw UsageError("msid bench ticks: --can or --canopen, not both");
    if (canopen && a.has("instructions"))
        throw UsageError("msid bench ticks: --instructions counts the Modbus and CAN loops, not the CANopen one");
    const bool can = a.has("can") || canopen;
    if (!can && a.has("results"))
        throw UsageError("msid bench ticks: --results is the VM's folder: it goes with --can or --canopen");
    const std::string src = MSID_SOURCE_DIR;
    std::vector<std::string> args = {"python3"};
    if (can) {
        args.push_back(src + "/tests/vcan/vm.py");
        if (a.has("results")) {
            args.push_back("--results");
            args.push_back(a.get("results"));
        }
        args.insert(args.end(), {"--", "python3",
                                 src + (canopen ? "/tests/vcan/in_vm/bench_ticks_canopen.py" : "/tests/vcan/in_vm/bench_ticks_can.py")});
    } else {
        args.push_back(src + "/tests/modbus/bench_ticks.py");
    }
    for (const char *k : {"rate", "periods"})
        if (a.has(k)) {
            args.push_back(std::string("--") + k);
            args.push_back(a.get(k));
        }
    if (a.has("instructions")) args.push_back("--instructions");
    return exec_with_build(args);
}

const char *BENCH_HELP =
    "usage: msid bench <name> [options]   (msid bench <name> --help: the options of one)\n"
    "\n"
    "  frf     the FRF job (line DFT, period statistics, LS FRF) on both paths against FFTW and NumPy\n"
    "  fit     subspace, lmfd and ml fits against NumPy and scikit-rf vector fitting\n"
    "  lpm     the local polynomial method against its NumPy peer\n"
    "  io      reading experiment files (CSV, .npy, .mat) against pandas / NumPy / SciPy\n"
    "  can     the highest lossless CAN sample rate over vcan (Debian kernel under qemu)\n"
    "  modbus  the highest lossless sample rate x channels over Modbus from msid-devsim\n"
    "  ticks   the host tick loop of a described device (lateness, CPU per tick) against a pymodbus script\n"
    "  target  instructions per sample of the core on a Cortex-M (qemu)\n"
    "  wcet    per-sample time of generation + streaming estimation on the host\n"
    "  crest   design set-up for large P: crest factors by FFT vs direct synthesis vs NumPy\n"
    "\n"
    "Results with date and machine go to docs/benchmarks.md.\n";

}  // namespace

int cmd_bench(int argc, char **argv)
{
    return dispatch_subcommand(argc, argv, "bench", BENCH_HELP,
                               {{"frf", bench_frf},
                                {"fit", bench_fit},
                                {"lpm", bench_lpm},
                                {"io", bench_io},
                                {"can", cmd_bench_can},
                                {"modbus", cmd_bench_modbus},
                                {"ticks", bench_ticks},
                                {"target", bench_target},
                                {"wcet", bench_wcet},
                                {"crest", bench_crest}},
                               true);
}

}  // namespace msidcli
