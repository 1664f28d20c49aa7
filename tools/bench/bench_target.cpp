// msid bench target: instructions per sample on the emulated Cortex-M4F and Cortex-M7
// (tests/target/bench_target.c under qemu-system-arm -icount), and the object sizes of the
// cross-built library.
#include "bench_util.hpp"

#include "msid_host_util.hpp"

#include <cstdlib>

namespace msidbench {

namespace {

// The value of " key=value" in a line of bench_target.elf's output ("" if absent).
std::string field(const std::string &line, const std::string &key)
{
    const auto k = line.find(" " + key + "=");
    if (k == std::string::npos) return "";
    const auto s = k + key.size() + 2;
    return line.substr(s, line.find(' ', s) - s);
}

// The instructions per sample the summary lines of one CPU are made of.
struct Summary {
    double push1 = 0, push50 = 0, gp1 = 0, bpush1 = 0, bpush50 = 0, bgp1 = 0;       // double path
    double fpush1 = 0, fpush50 = 0, fgp1 = 0, fbpush1 = 0, fbpush50 = 0, fbgp1 = 0;  // float32 path
    // per-sample maximum of generation + estimation, one sample per call: [case][spread]
    double mx50[2] = {0, 0}, mxm[2] = {0, 0}, mx1[2] = {0, 0}, mean50[2] = {0, 0};
    double ipush1[2] = {0, 0}, ipush50[2] = {0, 0}, igp1[2] = {0, 0};   // float samples in: [block 1, block 16]

    void add(const std::string &name, const std::string &work, const std::string &block, const std::string &spread,
             double ips, double max_insn)
    {
        const bool b1 = block == "1";
        const int sp = spread == "1" ? 1 : 0;
        if (b1 && work == "gen+push") {
            if (name == "siso50") { mx50[sp] = max_insn; mean50[sp] = ips; }
            if (name == "mimo2x2_50") mxm[sp] = max_insn;
            if (name == "siso1") mx1[sp] = max_insn;
        }
        if (sp) return;   // the slopes are of the unspread cases
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

    void print(Writer &w) const
    {
        w.print("  one-line SISO, generation + estimation: %.1f instructions per sample (SFRA: 103 cycles)\n", gp1);
        w.print("  per extra line*channel (SISO 1 -> 50 lines, 2 channels): %.1f instructions (goal <= 10 on the M7)\n",
                (push50 - push1) / (49.0 * 2.0));
        w.print("  in blocks of 16 samples: one-line SISO %.1f, per extra line*channel %.1f instructions per sample\n", bgp1,
                (bpush50 - bpush1) / (49.0 * 2.0));
        w.print("  float32 path (MSID_DFT_STREAM_F32): one-line SISO %.1f (blocks of 16: %.1f), per extra line*channel "
                "%.1f (blocks: %.1f)\n", fgp1, fbgp1, (fpush50 - fpush1) / 98.0, (fbpush50 - fbpush1) / 98.0);
        w.print("  float samples in (msid_meas_push_f32, float path): one-line SISO %.1f (blocks of 16: %.1f), per "
                "extra line*channel %.1f (blocks: %.1f)\n", igp1[0], igp1[1], (ipush50[0] - ipush1[0]) / 98.0,
                (ipush50[1] - ipush1[1]) / 98.0);
        w.print("  max per sample (period end included), one sample per call, without -> with spread period end\n"
                "  (msid_meas_cfg.spread): SISO 1 line %.0f -> %.0f, SISO 50 lines %.0f -> %.0f (%.1fx less; mean %.1f -> "
                "%.1f), 2x2 50 lines %.0f -> %.0f (%.1fx less)\n",
                mx1[0], mx1[1], mx50[0], mx50[1], mx50[1] > 0 ? mx50[0] / mx50[1] : 0.0, mean50[0], mean50[1], mxm[0],
                mxm[1], mxm[1] > 0 ? mxm[0] / mxm[1] : 0.0);
    }
};

const char *const CPUS[2][2] = {{"cortex-m4f", "mps2-an386"}, {"cortex-m7", "mps2-an500"}};

// One CPU: its table of cases and the summary; false if its run failed.
bool bench_cpu(Writer &w, const std::string &bdir, const char *const *c)
{
    const std::string elf = bdir + "/target/" + c[0] + "/bench_target.elf";
    std::string out;
    const int rc = capture("qemu-system-arm -M " + std::string(c[1]) +
                               " -nographic -monitor none -serial none -semihosting-config "
                               "enable=on,target=native -icount shift=0,align=off,sleep=off -kernel '" +
                               elf + "' 2>&1",
                           out);
    if (rc != 0 || out.find("case ") == std::string::npos) {
        w.error(std::string("msid bench target: ") + elf + " failed (build the msid_target_" + c[0] +
                " target first): " + out.substr(0, 300));
        return false;
    }
    w.print("\n%s (%s)\n", c[0], c[1]);
    w.print("  %-11s %6s %5s %-9s %-9s %5s %3s %12s %10s %10s %10s\n", "case", "spread", "block", "work", "gen", "lines",
            "C", "insn/sample", "max insn", "mem_meas", "mem_frf");
    Summary s;
    size_t pos = 0;
    while ((pos = out.find("case ", pos)) != std::string::npos) {
        const std::string line = out.substr(pos - 1, out.find('\n', pos) - pos + 1);
        pos += 5;
        const std::string name = field(line, "name"), work = field(line, "work");
        const double ips = std::atof(field(line, "insn_per_sample").c_str());
        const std::string block = field(line, "block"), spread = field(line, "spread");
        w.print("  %-11s %6s %5s %-9s %-9s %5s %3s %12.1f %10s %10s %10s\n", name.c_str(), spread.c_str(), block.c_str(),
                work.c_str(), field(line, "gen").c_str(), field(line, "lines").c_str(), field(line, "channels").c_str(), ips,
                field(line, "max_insn").c_str(), field(line, "mem_meas").c_str(), field(line, "mem_frf").c_str());
        s.add(name, work, block, spread, ips, std::atof(field(line, "max_insn").c_str()));
    }
    s.print(w);
    return true;
}

}  // namespace

TargetBenchResult bench_target(const TargetBenchRequest &rq, const Sink &sink)
{
    TargetBenchResult res;
    Writer w(sink, res.report);
    const std::string bdir = rq.build_dir.empty() ? MSID_BINARY_DIR : rq.build_dir;
    const std::string sdir = rq.source_dir.empty() ? MSID_SOURCE_DIR : rq.source_dir;
    w.print("msid bench target  (msid %s; instructions counted by qemu -icount, not cycles)\n", MSID_VERSION);
    std::string v;
    capture("arm-none-eabi-gcc --version 2>&1 | head -1", v);
    w.print("toolchain: %s", v.c_str());
    v.clear();
    capture("qemu-system-arm --version 2>&1 | head -1", v);
    w.print("emulator:  %s", v.c_str());
    w.print("reference: TI SFRA, 103 cycles per sample for one tone (C2000, no uncertainty)\n");
    for (auto &c : CPUS)
        if (!bench_cpu(w, bdir, c)) w.fail();
    // flash and RAM per object, from the linker map of the bare-metal example (it links what a firmware needs)
    for (auto &c : CPUS) {
        const std::string map = bdir + "/target/" + c[0] + "/msid_baremetal.map";
        std::string sz;
        const int rc = capture("python3 '" + sdir + "/tests/target/map_sizes.py' '" + map + "' 2>&1", sz);
        w.print("\nflash and static RAM per object, firmware_sim/baremetal on %s (linker map, -O3, gc-sections):\n%s",
                c[0], sz.c_str());
        if (rc != 0) w.fail();
    }
    return res;
}

}  // namespace msidbench
