// msid bench io: `msid frf` end to end (process start, reading the experiment files, FRF job,
// writing msid-frf/1) on CSV, .npy and .mat records of 2 experiments x 262,144 rows x 4 columns
// (2 inputs, 2 outputs), against a pandas/NumPy/SciPy peer reading the same files in the same run
// (tools/peers/msid_peers/bench_io_peer.py).
#include "bench_util.hpp"

#include "matio_dl.hpp"   // libmatio on first use (tools/records)
#include "msid_host_util.hpp"
#include "msid_records.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <unistd.h>
#include <vector>

namespace msidbench {

using msidrec::matio;
using msidrec::Matio;
using msidutil::Error;
using msidutil::fmt;

namespace {

constexpr uint32_t P = 4096, K = 64, L = 200, M = 2;   // period, periods, lines, experiments
constexpr size_t N = (size_t)P * K, C = 4;            // rows, columns per experiment

void write_mat(const std::string &path, const std::vector<double> &x, size_t n, size_t cols, const char *const *names)
{
    const Matio &Mt = matio();
    mat_t *m = Mt.CreateVer(path.c_str(), nullptr, MAT_FT_MAT5);
    if (!m) throw Error("cannot create '" + path + "'");
    std::vector<double> col(n);
    for (size_t c = 0; c < cols; ++c) {
        for (size_t i = 0; i < n; ++i) col[i] = x[i * cols + c];
        size_t dims[2] = {n, 1};
        matvar_t *v = Mt.VarCreate(names[c], MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, col.data(), 0);
        if (!v || Mt.VarWrite(m, v, MAT_COMPRESSION_NONE) != 0) { Mt.Close(m); throw Error("cannot write '" + path + "'"); }
        Mt.VarFree(v);
    }
    Mt.Close(m);
}

double json_num(const std::string &out, const char *key)
{
    const std::string k = std::string("\"") + key + "\": ";
    const size_t p = out.find(k);
    return p == std::string::npos ? -1 : std::atof(out.c_str() + p + k.size());
}

// The experiment files in `dir`: e1, e2 as .csv, .npy and .mat, and bins.txt. Data: a
// random-phase multisine per input on L seeded bins (one period repeated), small input noise;
// outputs a static 2x2 mix plus noise. Returns the line list and the CSV bytes.
std::string write_records(const std::string &dir, double &bytes_csv)
{
    msid_rng r;
    msid_rng_seed(&r, 2026);
    std::vector<uint32_t> all;
    for (uint32_t b = 1; 2 * b < P; ++b) all.push_back(b);
    for (size_t i = all.size() - 1; i > 0; --i) std::swap(all[i], all[msid_rng_u64(&r) % (i + 1)]);
    std::vector<uint32_t> bins(all.begin(), all.begin() + L);
    std::sort(bins.begin(), bins.end());
    std::string lines;
    for (size_t l = 0; l < L; ++l) lines += (l ? "," : "") + std::to_string(bins[l]);
    write_all(dir + "/bins.txt", lines);
    const char *names[4] = {"u1", "u2", "y1", "y2"};
    std::vector<double> x(N * C);
    bytes_csv = 0;
    for (uint32_t e = 0; e < M; ++e) {
        std::vector<double> per(2 * P, 0.0);
        for (uint32_t j = 0; j < 2; ++j)
            for (uint32_t b : bins) {
                const double ph = 2 * M_PI * msid_rng_uniform(&r);
                for (uint32_t t = 0; t < P; ++t)
                    per[j * P + t] += std::cos(2 * M_PI * (double)((uint64_t)b * t % P) / P + ph) / std::sqrt((double)L);
            }
        for (size_t i = 0; i < N; ++i) {
            // values rounded to 9 significant digits, as a logger writes them
            auto r9 = [](double v) { char b[32]; std::snprintf(b, sizeof b, "%.9g", v); return std::strtod(b, nullptr); };
            const double u1 = per[i % P] + 1e-3 * msid_rng_normal(&r), u2 = per[P + i % P] + 1e-3 * msid_rng_normal(&r);
            x[i * C + 0] = r9(u1);
            x[i * C + 1] = r9(u2);
            x[i * C + 2] = r9(0.5 * u1 + 0.2 * u2 + 0.01 * msid_rng_normal(&r));
            x[i * C + 3] = r9(u1 - u2 + 0.01 * msid_rng_normal(&r));
        }
        const std::string base = dir + "/e" + std::to_string(e + 1);
        const std::string csv = msidrec::format_csv({"u1", "u2", "y1", "y2"}, x.data(), N, C);
        bytes_csv += (double)csv.size();
        write_all(base + ".csv", csv);
        write_all(base + ".npy", npy_image(x, N, C));
        write_mat(base + ".mat", x, N, C, names);
    }
    return lines;
}

struct Fmt { const char *name, *ext, *cols; };
const Fmt FORMATS[] = {{"csv", ".csv", nullptr}, {"npy", ".npy", "u1=1,u2=2,y1=3,y2=4"}, {"mat", ".mat", nullptr}};

// The peer's output (a JSON object of times), or "" with `note` saying why not.
std::string run_peer(const std::string &dir, double min_s, std::string &note)
{
    const std::string cmd = "python3 '" + peers_dir() + "/msid_peers/bench_io_peer.py' '" + dir + "' " +
                            std::to_string(P) + " '" + dir + "/bins.txt' " + std::to_string(M) + " " +
                            fmt("%g", min_s) + " 2>&1";
    std::string out;
    const int rc = capture(cmd, out);
    if (rc == -1) note = "cannot start python3";
    else if (rc != 0) { note = "peer failed: " + out.substr(0, 300); out.clear(); }
    return out;
}

void print_table(Writer &w, const std::vector<IoBenchRow> &rows, const std::string &out, const std::string &note)
{
    const char *peer_name[3] = {"pandas.read_csv + NumPy", "numpy.load + NumPy", "scipy.io.loadmat + NumPy"};
    w.print("%-5s %12s %12s %8s %12s %12s %8s %12s   %s\n", "input", "msid wall", "peer wall", "x peer", "msid cpu",
            "peer cpu", "x peer", "x CSV peer", "peer");
    const double csv_wall = out.empty() ? -1 : json_num(out, "csv"), csv_cpu = out.empty() ? -1 : json_num(out, "csv_cpu");
    auto ms = [](double t) { return t > 0 ? fmt("%9.1f ms", 1e3 * t) : std::string("        -   "); };
    auto ratio = [](double num, double den) { return num > 0 && den > 0 ? fmt("%8.2f", num / den) : std::string("       -"); };
    for (size_t k = 0; k < rows.size(); ++k) {
        const IoBenchRow &x = rows[k];
        w.print("%-5s %12s %12s %s %12s %12s %s %7s/%-4s   %s\n", x.format.c_str(), ms(x.msid_wall_s).c_str(),
                ms(x.peer_wall_s).c_str(), ratio(x.peer_wall_s, x.msid_wall_s).c_str(), ms(x.msid_cpu_s).c_str(),
                ms(x.peer_cpu_s).c_str(), ratio(x.peer_cpu_s, x.msid_cpu_s).c_str(),
                ratio(csv_wall, x.msid_wall_s).c_str() + 3, ratio(csv_cpu, x.msid_cpu_s).c_str() + 4, peer_name[k]);
    }
    if (!out.empty()) {
        const size_t v = out.find('{');
        w.print("\npeer: %s", v == std::string::npos ? out.c_str() : out.substr(v).c_str());
    }
    if (!note.empty()) w.print("\n%s\n", note.c_str());
    w.print("wall: elapsed time; cpu: user + system time of all threads. msid times include process start and\n"
            "writing the FRF file; the peer's are inside Python (no interpreter start-up, no output file).\n"
            "x CSV peer: the pandas CSV peer's time over msid's on this input (wall/cpu).\n");
}

}  // namespace

IoBenchResult bench_io(const IoBenchRequest &rq, const Sink &sink)
{
    IoBenchResult res;
    Writer w(sink, res.report);
    const std::string dir = rq.keep.empty() ? temp_dir("msid-bench-io") : rq.keep;
    double bytes_csv = 0;
    const std::string lines = write_records(dir, bytes_csv);
    w.print("msid bench io  (msid %s)\nmachine: %s\n", MSID_VERSION, machine().c_str());
    w.print("job: msid frf on %u experiments x %zu rows x %zu columns (P = %u, %u periods, %u lines); CSV %.1f MB; "
            "best of >= 3 runs lasting >= %.2g s\n\n",
            M, N, C, P, K, L, bytes_csv / 1e6, rq.min_seconds);
    for (const Fmt &f : FORMATS) {
        std::vector<std::string> args{"msid", "frf", "--period", std::to_string(P), "--lines", lines};
        for (uint32_t e = 0; e < M; ++e) { args.push_back("--experiment"); args.push_back(dir + "/e" + std::to_string(e + 1) + f.ext); }
        if (f.cols) { args.push_back("--columns"); args.push_back(f.cols); }
        args.push_back("-o");
        args.push_back(dir + "/frf.json");
        const Times t = time_process(rq.msid_exe, args, rq.min_seconds);
        IoBenchRow row;
        row.format = f.name;
        row.msid_wall_s = t.wall;
        row.msid_cpu_s = t.cpu;
        res.rows.push_back(row);
    }
    std::string note;
    const std::string out = rq.peer ? run_peer(dir, rq.min_seconds, note) : "";
    for (IoBenchRow &row : res.rows) {
        row.peer_wall_s = out.empty() ? -1 : json_num(out, row.format.c_str());
        row.peer_cpu_s = out.empty() ? -1 : json_num(out, (row.format + "_cpu").c_str());
    }
    print_table(w, res.rows, out, note);
    if (rq.keep.empty()) {
        for (const char *f : {"e1.csv", "e2.csv", "e1.npy", "e2.npy", "e1.mat", "e2.mat", "bins.txt", "frf.json"})
            std::remove((dir + "/" + f).c_str());
        rmdir(dir.c_str());
    }
    return res;
}

}  // namespace msidbench
