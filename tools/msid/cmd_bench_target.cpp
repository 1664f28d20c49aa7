// msid bench target: instructions per sample on the emulated Cortex-M4F and
// Cortex-M7 (tests/target/bench_target.c under qemu-system-arm -icount), and
// the object sizes of the cross-built library.
// msid bench wcet: per-sample time of the streaming path on the host
// (msid_gen_next + msid_meas_push of one row), median, p99, p99.9 and max.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_util.hpp"
#include "commands.hpp"
#include "msid/msid.h"

namespace msidcli {
namespace {

std::string run_capture(const std::string &cmd, int &rc)
{
    std::string out;
    FILE *p = popen(cmd.c_str(), "r");
    if (!p) { rc = -1; return out; }
    char buf[1024];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    rc = pclose(p);
    return out;
}

std::string field(const std::string &line, const std::string &key)
{
    const auto k = line.find(" " + key + "=");
    if (k == std::string::npos) return "";
    const auto s = k + key.size() + 2;
    return line.substr(s, line.find(' ', s) - s);
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
    const std::string bdir = MSID_BINARY_DIR;
    std::printf("msid bench target  (msid %s; instructions counted by qemu -icount, not cycles)\n", MSID_VERSION);
    int rc = 0;
    std::string v = run_capture("arm-none-eabi-gcc --version 2>&1 | head -1", rc);
    std::printf("toolchain: %s", v.c_str());
    v = run_capture("qemu-system-arm --version 2>&1 | head -1", rc);
    std::printf("emulator:  %s", v.c_str());
    std::puts("reference: TI SFRA, 103 cycles per sample for one tone (C2000, no uncertainty)");
    const char *cpus[2][2] = {{"cortex-m4f", "mps2-an386"}, {"cortex-m7", "mps2-an500"}};
    int failed = 0;
    for (auto &c : cpus) {
        const std::string elf = bdir + "/target/" + c[0] + "/bench_target.elf";
        const std::string out = run_capture("qemu-system-arm -M " + std::string(c[1]) +
                                                " -nographic -monitor none -serial none -semihosting-config "
                                                "enable=on,target=native -icount shift=0,align=off,sleep=off -kernel '" +
                                                elf + "' 2>&1",
                                            rc);
        if (rc != 0 || out.find("case ") == std::string::npos) {
            std::fprintf(stderr, "msid bench target: %s failed (build the msid_target_%s target first): %s\n",
                         elf.c_str(), c[0], out.substr(0, 300).c_str());
            failed = 1;
            continue;
        }
        std::printf("\n%s (%s)\n", c[0], c[1]);
        std::printf("  %-11s %6s %5s %-9s %-9s %5s %3s %12s %10s %10s %10s\n", "case", "spread", "block", "work", "gen",
                    "lines", "C", "insn/sample", "max insn", "mem_meas", "mem_frf");
        double push1 = 0, push50 = 0, gp1 = 0, bpush1 = 0, bpush50 = 0, bgp1 = 0;
        double fpush1 = 0, fpush50 = 0, fgp1 = 0, fbpush1 = 0, fbpush50 = 0, fbgp1 = 0;
        // per-sample maximum of generation + estimation, one sample per call: [case][spread]
        double mx50[2] = {0, 0}, mxm[2] = {0, 0}, mx1[2] = {0, 0}, mean50[2] = {0, 0};
        double ipush1[2] = {0, 0}, ipush50[2] = {0, 0}, igp1[2] = {0, 0};   // float samples in: [block 1, block 16]
        size_t pos = 0;
        while ((pos = out.find("case ", pos)) != std::string::npos) {
            const std::string line = out.substr(pos - 1, out.find('\n', pos) - pos + 1);
            pos += 5;
            const std::string name = field(line, "name"), work = field(line, "work");
            const double ips = std::atof(field(line, "insn_per_sample").c_str());
            const std::string block = field(line, "block"), spread = field(line, "spread");
            std::printf("  %-11s %6s %5s %-9s %-9s %5s %3s %12.1f %10s %10s %10s\n", name.c_str(), spread.c_str(),
                        block.c_str(), work.c_str(),
                        field(line, "gen").c_str(), field(line, "lines").c_str(), field(line, "channels").c_str(), ips,
                        field(line, "max_insn").c_str(), field(line, "mem_meas").c_str(), field(line, "mem_frf").c_str());
            const bool b1 = block == "1";
            const int sp = spread == "1" ? 1 : 0;
            if (b1 && work == "gen+push") {
                const double mxi = std::atof(field(line, "max_insn").c_str());
                if (name == "siso50") { mx50[sp] = mxi; mean50[sp] = ips; }
                if (name == "mimo2x2_50") mxm[sp] = mxi;
                if (name == "siso1") mx1[sp] = mxi;
            }
            if (sp) continue;   // the slopes below are of the unspread cases
            if (name == "siso1" && work == "push") (b1 ? push1 : bpush1) = ips;
            if (name == "siso1" && work == "gen+push") (b1 ? gp1 : bgp1) = ips;
            if (name == "siso50" && work == "push") (b1 ? push50 : bpush50) = ips;
            if (name == "siso1_f32" && work == "push") (b1 ? fpush1 : fbpush1) = ips;
            if (name == "siso1_f32" && work == "gen+push") (b1 ? fgp1 : fbgp1) = ips;
            if (name == "siso50_f32" && work == "push") (b1 ? fpush50 : fbpush50) = ips;
            if (name == "siso1_f32in" && work == "push") ipush1[b1 ? 0 : 1] = ips;
            if (name == "siso50_f32in" && work == "push") ipush50[b1 ? 0 : 1] = ips;
            if (name == "siso1_f32in" && work == "gen+push") igp1[b1 ? 0 : 1] = ips;
        }
        std::printf("  one-line SISO, generation + estimation: %.1f instructions per sample (SFRA: 103 cycles)\n", gp1);
        std::printf("  per extra line*channel (SISO 1 -> 50 lines, 2 channels): %.1f instructions (goal <= 10 on the M7)\n",
                    (push50 - push1) / (49.0 * 2.0));
        std::printf("  in blocks of 16 samples: one-line SISO %.1f, per extra line*channel %.1f instructions per sample\n",
                    bgp1, (bpush50 - bpush1) / (49.0 * 2.0));
        std::printf("  float32 path (MSID_DFT_STREAM_F32): one-line SISO %.1f (blocks of 16: %.1f), per extra line*channel "
                    "%.1f (blocks: %.1f)\n", fgp1, fbgp1, (fpush50 - fpush1) / 98.0, (fbpush50 - fbpush1) / 98.0);
        std::printf("  float samples in (msid_meas_push_f32, float path): one-line SISO %.1f (blocks of 16: %.1f), per "
                    "extra line*channel %.1f (blocks: %.1f)\n", igp1[0], igp1[1], (ipush50[0] - ipush1[0]) / 98.0,
                    (ipush50[1] - ipush1[1]) / 98.0);
        std::printf("  max per sample (period end included), one sample per call, without -> with spread period end\n"
                    "  (msid_meas_cfg.spread): SISO 1 line %.0f -> %.0f, SISO 50 lines %.0f -> %.0f (%.1fx less; mean %.1f -> "
                    "%.1f), 2x2 50 lines %.0f -> %.0f (%.1fx less)\n",
                    mx1[0], mx1[1], mx50[0], mx50[1], mx50[1] > 0 ? mx50[0] / mx50[1] : 0.0, mean50[0], mean50[1], mxm[0],
                    mxm[1], mxm[1] > 0 ? mxm[0] / mxm[1] : 0.0);
    }
    // flash and RAM per object, from the linker map of the bare-metal example (it links what a firmware needs)
    for (auto &c : cpus) {
        const std::string map = bdir + "/target/" + c[0] + "/msid_baremetal.map";
        const std::string sz =
            run_capture("python3 '" + std::string(MSID_SOURCE_DIR) + "/tests/target/map_sizes.py' '" + map + "' 2>&1", rc);
        std::printf("\nflash and static RAM per object, firmware_sim/baremetal on %s (linker map, -O3, gc-sections):\n%s",
                    c[0], sz.c_str());
        if (rc != 0) failed = 1;
    }
    return failed;
}

// ---------------- msid bench wcet ----------------

struct Wcase { uint32_t P, nu, ny, m, L; const char *name; int spread; };

double now_ns()
{
    timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return 1e9 * (double)t.tv_sec + (double)t.tv_nsec;
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
    const uint64_t N = a.u64("samples", 10000000ull);
    if (N < 100000ull) throw UsageError("msid bench wcet: --samples must be at least 100000");
    std::printf("msid bench wcet  (msid %s, %llu samples per case, per-sample times in ns incl. ~20 ns clock read)\n",
                MSID_VERSION, (unsigned long long)N);
    const Wcase cases[] = {{1000, 1, 1, 1, 1, "SISO 1 line", 0},       {1000, 1, 1, 1, 50, "SISO 50 lines", 0},
                           {1000, 2, 2, 2, 50, "2x2 m=2 50 lines", 0},  {1000, 1, 1, 1, 50, "SISO 50 spread", 1},
                           {1000, 2, 2, 2, 50, "2x2 50 spread", 1}};
    for (const Wcase &c : cases) {
        std::vector<uint32_t> bins(c.L);
        for (uint32_t l = 0; l < c.L; ++l) bins[l] = 1 + 2 * l;
        auto mem = [](size_t n) { return std::aligned_alloc(64, (n + 63) & ~(size_t)63); };
        msid_twiddle tw;
        size_t n = msid_twiddle_mem_size(c.P);
        void *m1 = mem(n);
        msid_twiddle_init(&tw, c.P, m1, n);
        msid_design_cfg dc{};
        dc.period = c.P; dc.n_lines = c.L; dc.bins = bins.data(); dc.n_inputs = c.nu; dc.n_experiments = c.m;
        dc.twiddle = &tw;
        msid_design d;
        n = msid_design_mem_size(&dc);
        void *m2 = mem(n);
        if (msid_design_init(&d, &dc, m2, n) != MSID_OK) throw std::runtime_error("bench wcet: design");
        msid_gen_cfg gc{&d, &tw, 0u, 1};
        msid_gen g;
        n = msid_gen_mem_size(&gc);
        void *m3 = mem(n);
        msid_gen_init(&g, &gc, m3, n);
        msid_meas_cfg mc{};
        mc.period = c.P; mc.n_inputs = c.nu; mc.n_outputs = c.ny; mc.n_experiments = c.m; mc.n_lines = c.L;
        mc.bins = bins.data(); mc.twiddle = &tw; mc.path = MSID_DFT_STREAM;
        mc.spread = c.spread;   // "spread": period-end work one line per sample over the next period
        msid_meas ms;
        n = msid_meas_mem_size(&mc);
        void *m4 = mem(n);
        if (msid_meas_init(&ms, &mc, m4, n) != MSID_OK) throw std::runtime_error("bench wcet: meas");
        msid_meas_begin(&ms, 0);
        // histogram in 1 ns bins up to 100 us, exact max beyond
        std::vector<uint64_t> hist(100000, 0), hend(100000, 0);   // all samples, period-end samples
        double mx = 0, mx_end = 0, mx_first = 0;
        double row[8] = {0};
        for (uint64_t s = 0; s < N; ++s) {
            const double t0 = now_ns();
            msid_gen_next(&g, row);
            for (uint32_t i = 0; i < c.ny; ++i) row[c.nu + i] = 0.5 * row[i % c.nu];
            msid_meas_push(&ms, row, 1);
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
        auto q = [](const std::vector<uint64_t> &h, uint64_t total, double f) {
            const uint64_t want = (uint64_t)(f * (double)total);
            uint64_t acc = 0;
            for (size_t i = 0; i < h.size(); ++i) if ((acc += h[i]) > want) return (double)i;
            return (double)h.size();
        };
        const uint64_t ne = N / c.P;
        std::printf("  %-17s median %5.0f  p99 %5.0f  p99.9 %6.0f  max %9.0f (first 10%%: %9.0f) ns\n", c.name,
                    q(hist, N, 0.5), q(hist, N, 0.99), q(hist, N, 0.999), mx, mx_first);
        std::printf("  %-17s period-end samples (%llu): median %6.0f  p99 %6.0f  max %9.0f ns\n", "",
                    (unsigned long long)ne, q(hend, ne, 0.5), q(hend, ne, 0.99), mx_end);
        std::free(m1); std::free(m2); std::free(m3); std::free(m4);
    }
    std::puts("Wall-clock maxima include operating-system preemption (milliseconds on a shared machine); the\n"
              "library's own per-sample bound is the period-end median here and the instruction count\n"
              "`msid bench target` reads on the emulated Cortex-M (max insn), which no preemption disturbs.");
    return 0;
}

}  // namespace

int cmd_bench_target(int argc, char **argv)
{
    if (argc >= 3 && !std::strcmp(argv[2], "wcet")) return bench_wcet(argc, argv);
    return bench_target(argc, argv);
}

}  // namespace msidcli
