// msid bench fit --cissim-process: the whole `msid fit --method cissim` process on files (start,
// reading, the fit with its default ML refinement and noise covariance, writing the model) against
// the whole run of the authors' code (github wyqy/dcissim) under Octave in the same run, on the
// cases (cissim_cases.hpp: a 2x2 record with 300 lines, a sparse SISO record with 50).
// The authors' code is an optional peer: $MSID_DCISSIM_DIR (a checkout of it) and octave-cli on
// PATH; the driver and the stand-ins it needs under Octave are tools/peers/dcissim. Accuracy: the
// relative H2 error of each model against the true system, and how far the two agree with each
// other (poles, FRF at the lines). Numbers: docs/benchmarks.md.
#include "bench_util.hpp"

#include "cissim_cases.hpp"
#include "model_io.hpp"
#include "msid_host_util.hpp"
#include "msid_records.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>

namespace msidbench {

using namespace msidfit;
using msidutil::Error;
using msidutil::fmt;

namespace {

std::string join(const std::vector<uint32_t> &v, const char *sep)
{
    std::string s;
    for (size_t i = 0; i < v.size(); ++i) s += (i ? sep : "") + std::to_string(v[i]);
    return s;
}

// The reference's output file (msid_dcissim_run.m): "NAME rows cols values..." lines and a
// "seconds read .. setup .. estimate .. covariance .. inside .." line.
struct RefOut {
    std::map<std::string, MatR> m;
    std::map<std::string, double> sec;
};
RefOut read_ref(const std::string &path)
{
    std::ifstream f(path);
    if (!f) throw Error("the reference wrote no '" + path + "'");
    RefOut o;
    std::string line;
    while (std::getline(f, line)) {
        std::istringstream is(line);
        std::string name;
        is >> name;
        if (name == "seconds") {
            std::string k;
            double v;
            while (is >> k >> v) o.sec[k] = v;
            continue;
        }
        Eigen::Index r = 0, c = 0;
        is >> r >> c;
        MatR M(r, c);
        for (Eigen::Index j = 0; j < c; ++j)
            for (Eigen::Index i = 0; i < r; ++i) is >> M(i, j);
        o.m[name] = M;
    }
    return o;
}

// Poles sorted by angle then modulus (a conjugate pair: the member with Im >= 0 first).
std::vector<cd> sorted_poles(const MatR &A)
{
    Eigen::EigenSolver<MatR> es(A, false);
    std::vector<cd> p(es.eigenvalues().data(), es.eigenvalues().data() + A.rows());
    std::sort(p.begin(), p.end(), [](cd a, cd b) {
        return std::abs(std::arg(a)) != std::abs(std::arg(b)) ? std::abs(std::arg(a)) < std::abs(std::arg(b))
                                                              : a.imag() > b.imag();
    });
    return p;
}

std::string poles_text(const MatR &A)
{
    std::string s;
    for (const cd &p : sorted_poles(A))
        if (p.imag() >= 0) s += fmt("%s%.4f@%.4fpi", s.empty() ? "" : " ", std::abs(p), std::arg(p) / M_PI);
    return s;
}

double h2_error(const SSModel &m, const SSModel &truth)
{
    try {
        return ss_distance(m, truth).h2;
    } catch (const FitError &) {
        return -1;   // unstable: no H2 distance
    }
}

// max over the lines of ||G_a - G_b||_F / ||G_truth||_F
double frf_diff(const SSModel &a, const SSModel &b, const SSModel &truth, const std::vector<uint32_t> &lines, uint32_t P)
{
    double w = 0;
    for (uint32_t l : lines) {
        const cd z = std::polar(1.0, 2.0 * M_PI * l / P);
        w = std::max(w, (ss_eval(a, z) - ss_eval(b, z)).norm() / ss_eval(truth, z).norm());
    }
    return w;
}

std::string ms(double t) { return t < 1e29 ? fmt("%8.1f ms", 1e3 * t) : std::string("       - ms"); }

// The authors' code, when it can run here: octave-cli and $MSID_DCISSIM_DIR.
std::string reference_note()
{
    const char *d = std::getenv("MSID_DCISSIM_DIR");
    if (!d || !*d) return "MSID_DCISSIM_DIR is not set (a checkout of github wyqy/dcissim): no reference peer";
    std::string out;
    if (capture("command -v octave-cli 2>/dev/null", out) != 0 || out.empty())
        return "octave-cli is not on PATH (Debian: apt-get install octave): no reference peer";
    return "";
}

void run_case(Writer &w, const CissimProcessCase &c, const std::string &dir, const CissimProcessBenchRequest &rq,
              bool with_ref, CissimProcessBenchRow &row)
{
    const CissimRecord &r = c.rec;
    const uint32_t C = r.nu + r.ny, P = r.period;
    const std::string base = dir + "/" + c.name;
    std::vector<std::string> header;
    for (uint32_t j = 0; j < r.nu; ++j) header.push_back("u" + std::to_string(j + 1));
    for (uint32_t i = 0; i < r.ny; ++i) header.push_back("y" + std::to_string(i + 1));
    std::string cols;
    for (uint32_t k = 0; k < C; ++k) cols += (k ? "," : "") + header[k] + "=" + std::to_string(k + 1);
    write_all(base + ".npy", npy_image(r.rows, r.n_rows, C));
    write_all(base + ".csv", msidrec::format_csv(header, r.rows.data(), r.n_rows, C));
    write_all(base + ".f64", std::string((const char *)r.rows.data(), r.rows.size() * sizeof(double)));
    const std::string lines = join(c.lines, ",");
    const uint64_t K = r.n_rows / P, N = (K - 1) * P;   // the first period skipped, as both do
    const int n = c.order;
    const int lags = std::max<int>((int)std::ceil((double)n * n / ((double)r.ny * r.ny)) + 1,
                                   std::min(50, (int)std::lround(std::cbrt((double)N))));   // msid's default M
    w.print("case %s: %ux%u, order %d, P = %u, %llu periods (%zu samples), %zu lines %u..%u; the first period skipped\n",
            c.name, r.ny, r.nu, n, P, (unsigned long long)K, r.n_rows, c.lines.size(), c.lines.front(), c.lines.back());
    w.print("  true poles (|p|@angle): %s\n", poles_text(c.truth.A).c_str());
    auto msid_args = [&](const std::string &file, const std::string &out, std::vector<std::string> extra) {
        std::vector<std::string> a{"msid", "fit", "--method", "cissim", "--period", std::to_string(P), "--lines", lines,
                                   "--order", std::to_string(n), "--experiment", file};
        if (file.size() > 4 && file.compare(file.size() - 4, 4, ".npy") == 0) a.insert(a.end(), {"--columns", cols});
        a.insert(a.end(), extra.begin(), extra.end());
        a.insert(a.end(), {"-o", out});
        return a;
    };
    const Times tn = time_process(rq.msid_exe, msid_args(base + ".npy", base + ".model.json", {}), rq.min_seconds, true);
    const Times tc = time_process(rq.msid_exe, msid_args(base + ".csv", base + ".csv.model.json", {}), rq.min_seconds, true);
    const Times tr = time_process(rq.msid_exe, msid_args(base + ".npy", base + ".reduced.json", {"--reduced"}),
                                  rq.min_seconds, true);
    const SSModel mm = read_model(base + ".model.json").ss, mrd = read_model(base + ".reduced.json").ss;
    // the paper's estimate on the reference's terms (the lines alone, the published Alg. 4, D = 0):
    // the same algorithm as the authors' code, for the agreement of the two
    time_process(rq.msid_exe,
                 msid_args(base + ".npy", base + ".paper.json",
                           {"--refine", "none", "--reduced", "--unweighted", "--no-d", "--block-rows",
                            std::to_string(2 * n), "--no-covariance"}),
                 0.0, true);
    const SSModel mp = read_model(base + ".paper.json").ss;
    row.name = c.name;
    row.msid_wall_s = tn.wall;
    row.msid_cpu_s = tn.cpu;
    row.msid_csv_wall_s = tc.wall;
    row.msid_h2 = h2_error(mm, c.truth);
    row.paper_h2 = h2_error(mp, c.truth);
    w.print("  %-62s %11s %11s %10s  %s\n", "process", "wall", "CPU", "H2 error", "poles");
    w.print("  %-62s %11s %11s %10.5f  %s\n", "msid fit --method cissim (.npy; default: full set, ML refinement)",
            ms(tn.wall).c_str(), ms(tn.cpu).c_str(), row.msid_h2, poles_text(mm.A).c_str());
    w.print("  %-62s %11s %11s\n", "msid fit --method cissim (CSV)", ms(tc.wall).c_str(), ms(tc.cpu).c_str());
    w.print("  %-62s %11s %11s %10.5f  %s\n", "msid fit --method cissim --reduced (.npy)", ms(tr.wall).c_str(),
            ms(tr.cpu).c_str(), h2_error(mrd, c.truth), poles_text(mrd.A).c_str());
    w.print("  %-62s %11s %11s %10.5f  %s\n", "msid --refine none --reduced --unweighted --no-d (the paper's)", "", "",
            row.paper_h2, poles_text(mp.A).c_str());
    if (with_ref) {
        const std::string drv = peers_dir() + "/dcissim";
        // (built by concatenation: fmt() stops at 1 KB, and the list of lines is longer)
        auto call = [&](const std::string &file) {
            return "msid_dcissim_run('" + file + "', " + std::to_string(r.n_rows) + ", " + std::to_string(r.nu) + ", " +
                   std::to_string(r.ny) + ", " + std::to_string(P) + ", [" + join(c.lines, " ") + "], " +
                   std::to_string(n) + ", " + std::to_string(2 * n) + ", " + std::to_string(lags) + ", '" + base +
                   ".ref.txt')";
        };
        auto octave = [&](const std::string &file) {
            const std::vector<std::string> oa{"octave-cli", "--norc", "--quiet", "--no-history", "--no-window-system",
                                              "--path", drv, "--eval", call(file)};
            return time_process("octave-cli", oa, rq.min_seconds, true);
        };
        const Times toc = octave(base + ".csv");
        const Times to = octave(base + ".f64");   // last: its output file is the one read below
        const RefOut ro = read_ref(base + ".ref.txt");
        SSModel mr;
        mr.domain = Domain::DT;
        mr.A = ro.m.at("A"), mr.B = ro.m.at("B"), mr.C = ro.m.at("C"), mr.D = ro.m.at("D");
        row.ref_wall_s = to.wall;
        row.ref_cpu_s = to.cpu;
        row.ref_csv_wall_s = toc.wall;
        row.ref_estimate_s = ro.sec.count("estimate") ? ro.sec.at("estimate") : -1;
        row.ref_h2 = h2_error(mr, c.truth);
        row.ref_vs_paper_frf = frf_diff(mr, mp, c.truth, c.lines, P);
        row.ref_vs_msid_frf = frf_diff(mr, mm, c.truth, c.lines, P);
        w.print("  %-62s %11s %11s %10.5f  %s\n", "authors' code under Octave, whole run (raw float64)",
                ms(to.wall).c_str(), ms(to.cpu).c_str(), row.ref_h2, poles_text(mr.A).c_str());
        w.print("    inside (last run, tic/toc): read %.1f ms, set-up %.1f ms, estimate %.1f ms, noise covariance "
                "(M = %d) %.1f ms\n",
                1e3 * ro.sec.at("read"), 1e3 * ro.sec.at("setup"), 1e3 * ro.sec.at("estimate"), lags,
                1e3 * ro.sec.at("covariance"));
        w.print("  %-62s %11s %11s\n", "authors' code under Octave, whole run (CSV, dlmread)", ms(toc.wall).c_str(),
                ms(toc.cpu).c_str());
        w.print("  reference whole run / msid: %.1fx wall, %.1fx CPU (binary: .npy / raw); %.1fx wall (CSV / CSV); "
                "target >= 10x\n",
                to.wall / tn.wall, to.cpu / tn.cpu, toc.wall / tc.wall);
        w.print("  agreement, max over the lines of ||G_a - G_b|| / ||G_true||: reference vs the paper's estimate in "
                "msid %.2e, vs msid's default %.2e\n",
                row.ref_vs_paper_frf, row.ref_vs_msid_frf);
    }
    w.print("\n");
}

}  // namespace

CissimProcessBenchResult bench_cissim_process(const CissimProcessBenchRequest &rq, const Sink &sink)
{
    CissimProcessBenchResult res;
    Writer w(sink, res.report);
    w.print("msid bench fit --cissim-process  (msid %s)\nmachine: %s\n", MSID_VERSION, machine().c_str());
    double la[3] = {0, 0, 0};
    if (getloadavg(la, 3) == 3) w.print("load average: %.2f %.2f %.2f\n", la[0], la[1], la[2]);
    const std::string note = rq.peer ? reference_note() : "--no-peer: no reference peer";
    if (!note.empty()) w.print("%s\n", note.c_str());
    w.print("whole processes, best of >= 3 runs lasting >= %.2g s after a warm-up run; wall: elapsed, CPU: user + "
            "system of all threads\n\n",
            rq.min_seconds);
    const std::string dir = rq.keep.empty() ? temp_dir("msid-bench-cissim") : rq.keep;
    for (const CissimProcessCase &c : cissim_process_cases()) {
        CissimProcessBenchRow row;
        run_case(w, c, dir, rq, note.empty(), row);
        res.rows.push_back(row);
    }
    if (rq.keep.empty()) remove_dir(w, dir, "cannot remove ");
    return res;
}

}  // namespace msidbench
