// msid_bench: the benchmarks of `msid bench` (docs/benchmarks.md). Each one builds its own data, times
// msid's host and core paths on it, runs the independent peer of the same job (Python scripts of
// tools/peers, started as processes) where there is one, and writes a report of fixed tables.
// A benchmark takes a request (the command line's defaults in its fields) and returns its measured
// numbers with the report; the report's text also goes to a Sink while the benchmark runs, because
// benchmarks take seconds to many minutes.
// Times are in seconds unless a name says otherwise. Errors: msidutil::UsageError (a bad request),
// msidutil::Error (a temporary file that cannot be made, a process that cannot be started).
// No command-line types.
#pragma once
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace msidbench {

/// Where a report goes while its benchmark runs; either function may be empty.
struct Sink {
    std::function<void(const std::string &)> out;   ///< report text, in pieces as written (lines end in '\n')
    std::function<void(const std::string &)> err;   ///< diagnostics, one '\n'-terminated line each
};

/// What every benchmark writes besides its numbers.
struct Report {
    std::string text;                  ///< the whole report, as handed to Sink::out
    std::vector<std::string> errors;   ///< the diagnostics, as handed to Sink::err
    int status = 0;                    ///< 0, or 1 when a part of the benchmark could not run
};

// ---------------- frf: the FRF job on both DFT paths, FFTW's floor, the NumPy peer ----------------

/// `msid bench frf`.
struct FrfBenchRequest {
    double min_seconds = 1.0;    ///< each time is the best of runs lasting at least this long [s]
    bool fftw_measure = false;   ///< plan FFTW with FFTW_MEASURE (default FFTW_ESTIMATE, as `msid frf`)
    bool peer = true;            ///< run the NumPy peer of the same job
    uint32_t only = 0;           ///< 1, 2 or 3: that configuration only; 0: all three
};

/// One configuration's times.
struct FrfBenchRow {
    std::string config;          ///< e.g. "P=1024 L=20 1x1"
    double stream_s = 0;         ///< whole job on the streaming path [s]
    double fft_s = 0;            ///< whole job on the FFT path [s]
    double fftw_period_s = 0;    ///< FFTW's own r2c transforms of one period as stored [s]
    double peer_s = -1;          ///< the NumPy peer's job [s]; -1: not run or failed
};

struct FrfBenchResult {
    std::vector<FrfBenchRow> rows;
    Report report;
};

FrfBenchResult bench_frf(const FrfBenchRequest &rq, const Sink &sink = {});

// ---------------- fit: subspace, lmfd and ml against NumPy and scikit-rf ----------------

/// `msid bench fit` (without --only multi or cissim).
struct FitBenchRequest {
    uint32_t only = 0;           ///< 1 SISO, 2 2x2, 3 structures, 4 whole process; 0: all, then multi and cissim
    int systems = 50;            ///< random systems for the accuracy (at least 1)
    double min_seconds = 0.5;    ///< each time is the best of runs lasting at least this long [s]
    uint32_t runs = 3;           ///< Monte Carlo noise seeds of the structures (0: none; at most 1000)
    bool peer = true;            ///< run the NumPy and scikit-rf peers
    std::string msid_exe = "/proc/self/exe";   ///< the msid executable whose `fit` part 4 times
};

/// One of the SISO and 2x2 configurations.
struct FitBenchRow {
    std::string config;          ///< e.g. "SISO n=4, 1000 lines"
    double subspace_s = 0, lmfd_s = 0, ml_s = 0;   ///< best time of one fit [s]
    double peer_s = -1;          ///< the NumPy peer's median time per fit [s]; -1: not run or failed
    double subspace_h2_mean = 0, ml_h2_mean = 0;   ///< relative H2 error against the true system, mean
};

struct FitBenchResult {
    std::vector<FitBenchRow> rows;
    double process_msid_s = -1, process_peer_s = -1;   ///< part 4: wall time of the whole processes [s]
    Report report;
};

FitBenchResult bench_fit(const FitBenchRequest &rq, const Sink &sink = {});

/// `msid bench fit --only multi`: the multiple-experiment ML on case M1 (tools/fit/multi.hpp).
struct MultiBenchRequest {
    int runs = 200;              ///< runs per number of records (at least 10)
    bool peer = true;            ///< run the SciPy peer
};

struct MultiBenchResult {
    Report report;
};

MultiBenchResult bench_fit_multi(const MultiBenchRequest &rq, const Sink &sink = {});

/// `msid bench fit --only modal FRF`: the order scan a modal engineer runs on a structure's FRF,
/// `msid fit --method ml --domain ct --order auto FRF`, as a whole process (CPU time), beside
/// sdypy-EMA's LSCF over its polynomial orders 2..60 on the same FRF (tools/peers/msid_peers/lscf_peer.py)
/// and, with a baseline, another msid executable's same scan in the same run.
struct ModalBenchRequest {
    std::string frf;                           ///< the msid-frf/1 file (CT lines: --fs or a CT design)
    std::string baseline;                      ///< another msid executable ("": none)
    bool peer = true;                          ///< run the LSCF peer
    uint32_t runs = 1;                         ///< timed runs of each process after one warm-up (>= 1)
    std::string msid_exe = "/proc/self/exe";   ///< the msid executable timed
};

struct ModalBenchResult {
    double msid_cpu_s = -1, baseline_cpu_s = -1, peer_cpu_s = -1;   ///< best CPU time of each process [s]
    Report report;
};

ModalBenchResult bench_fit_modal(const ModalBenchRequest &rq, const Sink &sink = {});

/// `msid bench fit --cissim`: discrete-cISSIM beside subspace and ml (cases Y1, Y2).
struct CissimBenchRequest {
    int systems = 100;           ///< random systems of case Y1 (at least 1; the command line's --quick: 10)
    bool quick = false;          ///< fewer timing runs and Y2 runs
};

struct CissimBenchResult {
    Report report;
};

CissimBenchResult bench_cissim(const CissimBenchRequest &rq, const Sink &sink = {});

/// `msid bench fit --cissim-process`: the whole `msid fit --method cissim` process on files against the
/// whole run of the authors' code under Octave (optional: $MSID_DCISSIM_DIR and octave-cli), cases of
/// msidfit::cissim_process_cases.
struct CissimProcessBenchRequest {
    double min_seconds = 2.0;    ///< each time is the best of >= 3 runs lasting at least this long [s]
    bool peer = true;            ///< run the authors' code when it is there
    std::string keep;            ///< directory for the files, kept afterwards; "": a temporary one, removed
    std::string msid_exe = "/proc/self/exe";   ///< the msid executable whose `fit` is timed
};

/// One case.
struct CissimProcessBenchRow {
    std::string name;
    double msid_wall_s = 0, msid_cpu_s = 0, msid_csv_wall_s = 0;   ///< best whole-process times, .npy and CSV [s]
    double ref_wall_s = -1, ref_cpu_s = -1;   ///< the reference's whole Octave run on raw float64 [s]; -1: not run
    double ref_csv_wall_s = -1;               ///< the same reading the CSV file (dlmread) [s]
    double ref_estimate_s = -1;               ///< its estimation step alone (tic/toc inside) [s]
    double msid_h2 = -1, paper_h2 = -1, ref_h2 = -1;   ///< relative H2 errors against the truth (-1: unstable / not run)
    double ref_vs_paper_frf = -1, ref_vs_msid_frf = -1;   ///< max FRF difference at the lines over ||G_true||
};

struct CissimProcessBenchResult {
    std::vector<CissimProcessBenchRow> rows;
    Report report;
};

CissimProcessBenchResult bench_cissim_process(const CissimProcessBenchRequest &rq, const Sink &sink = {});

// ---------------- lpm: the local polynomial method against its NumPy peer ----------------

/// `msid bench lpm`.
struct LpmBenchRequest {
    size_t samples = 1000000;    ///< samples of the simulated 2x2 record (at least 64)
    unsigned runs = 3;           ///< runs per thread count; the best counts (at least 1)
    bool peer = true;            ///< run the NumPy peer
};

struct LpmBenchResult {
    double wall_1thread_s = 0, wall_2threads_s = 0, wall_spectra_s = 0;   ///< best wall times [s]
    double cpu_1thread_s = 0, cpu_2threads_s = 0, cpu_spectra_s = 0;      ///< best process CPU times [s]
    double peer_wall_s = -1, peer_cpu_s = -1;   ///< the peer's times [s]; -1: not run or failed
    double max_rel_diff = -1;    ///< max |G_msid - G_peer| / |G_peer| at the compared bins; -1: no peer
    Report report;
};

LpmBenchResult bench_lpm(const LpmBenchRequest &rq, const Sink &sink = {});

// ---------------- io: `msid frf` end to end on CSV, .npy and .mat ----------------

/// `msid bench io`.
struct IoBenchRequest {
    double min_seconds = 2.0;    ///< each time is the best of >= 3 runs lasting at least this long [s]
    bool peer = true;            ///< run the pandas / NumPy / SciPy peer
    std::string keep;            ///< directory for the files, kept afterwards; "": a temporary one, removed
    std::string msid_exe = "/proc/self/exe";   ///< the msid executable whose `frf` is timed
};

/// One input format.
struct IoBenchRow {
    std::string format;          ///< "csv", "npy" or "mat"
    double msid_wall_s = 0, msid_cpu_s = 0;     ///< best times of the whole `msid frf` process [s]
    double peer_wall_s = -1, peer_cpu_s = -1;   ///< the peer's [s]; -1: not run or failed
};

struct IoBenchResult {
    std::vector<IoBenchRow> rows;
    Report report;
};

IoBenchResult bench_io(const IoBenchRequest &rq, const Sink &sink = {});

// ---------------- target, wcet: per-sample cost of the core ----------------

/// `msid bench target`: instructions per sample on the emulated Cortex-M4F and M7 (qemu -icount).
struct TargetBenchRequest {
    std::string build_dir;       ///< the build holding target/<cpu>/; "": this build
    std::string source_dir;      ///< the source tree (tests/target/map_sizes.py); "": this one
};

struct TargetBenchResult {
    Report report;               ///< status 1 when a CPU's run or a map's sizes failed
};

TargetBenchResult bench_target(const TargetBenchRequest &rq, const Sink &sink = {});

/// `msid bench wcet`: per-sample time of generation + streaming estimation on the host.
struct WcetBenchRequest {
    uint64_t samples = 10000000;   ///< samples per case (at least 100000)
};

/// One case's per-sample times [ns].
struct WcetBenchRow {
    std::string name;
    double median_ns = 0, p99_ns = 0, p999_ns = 0, max_ns = 0;
    double period_end_median_ns = 0, period_end_max_ns = 0;
};

struct WcetBenchResult {
    std::vector<WcetBenchRow> rows;
    Report report;
};

WcetBenchResult bench_wcet(const WcetBenchRequest &rq, const Sink &sink = {});

// ---------------- crest: the design's set-up for large periods ----------------

/// `msid bench crest`.
struct CrestBenchRequest {
    bool quick = false;              ///< periods up to 2^16 (default 2^22)
    bool peer = true;                ///< run the NumPy peer
    uint64_t direct_max = 1u << 18;  ///< the largest period timed by direct synthesis
};

/// One period's set-up times.
struct CrestBenchRow {
    uint32_t period = 0, lines = 0;
    double fft_wall_s = 0, fft_cpu_s = 0;   ///< msid_design_init with MSID_CREST_FFT [s]
};

struct CrestBenchResult {
    std::vector<CrestBenchRow> rows;
    Report report;
};

CrestBenchResult bench_crest(const CrestBenchRequest &rq, const Sink &sink = {});

}  // namespace msidbench
