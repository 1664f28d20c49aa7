// msid: multisine system identification on the bench.
#include "cli_util.hpp"
#include "commands.hpp"
#include "stop_signal.hpp"

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace {

// One row per command, as git's builtin table: its name, the summary `msid --help` shows, its
// handler. The usage text and the dispatch are both made from it.
struct Command {
    const char *name;
    const char *summary;
    int (*run)(int argc, char **argv);
};

int cmd_version(int, char **)
{
    std::printf("msid %s\n", MSID_VERSION);
    return 0;
}

const Command COMMANDS[] = {
    {"measure",
     "measure a device (modbus-tcp://, modbus-rtu://, can://): FRF, model, plots in one directory;\n"
     "           --map DEVICE.toml for a device with its own register map (msid-device/1)",
     msidcli::cmd_measure_uri},
    {"excite", "design a multisine (msid-design/1) and optionally write its input samples as CSV", msidcli::cmd_excite},
    {"frf",
     "estimate the MIMO FRF and its covariance from experiment CSVs (msid-frf/1);\n"
     "           --method lpm|etfe for records that are not steady-state multisines",
     msidcli::cmd_frf},
    {"demo", "design, simulate a built-in 2x2 plant, estimate, and compare with the truth", msidcli::cmd_demo},
    {"fit",
     "parametric models from an FRF file: --method subspace | lmfd | ml (msid-model/1)\n"
     "           --method cissim: discrete-cISSIM straight from periodic time records (`msid fit --method cissim --help`)",
     msidcli::cmd_fit},
    {"modes", "natural frequencies, damping ratios, residues of a model with standard deviations", msidcli::cmd_modes},
    {"validate", "a model against an FRF file: weighted residual cost, p-value, verdict", msidcli::cmd_validate},
    {"compare", "relative H2 and Hinf distance between two models", msidcli::cmd_compare},
    {"can", "measure an FRF over SocketCAN from an msid-can/1 device, replay a candump log, or decode one\n"
            "           with a DBC file",
     msidcli::cmd_can},
    {"modbus", "measure an FRF over Modbus TCP or RTU from an msid-modbus/1 device", msidcli::cmd_modbus},
    {"device", "check a described device (msid-device/1): read every channel, write only the safe values",
     msidcli::cmd_device},
    {"plot", "Bode plot of an FRF file with 95% regions, model overlay and residuals (PNG/SVG/PDF)", msidcli::cmd_plot},
    {"export", "an FRF file as CSV or MATLAB .mat (idfrd shape) with standard deviations", msidcli::cmd_export},
    {"import", "an FRF measured by another tool (Touchstone, UFF 58, CSV, idfrd .mat) as msid-frf/1",
     msidcli::cmd_import},
    {"bench", "benchmarks against peers: frf, fit, lpm, io, can, modbus, target, wcet (`msid bench --help`)",
     msidcli::cmd_bench},
    {"version", "print the version", cmd_version},
};

std::string usage()
{
    std::string u = "usage: msid <command> [options]\n\ncommands:\n";
    for (const Command &c : COMMANDS) {
        char name[16];
        std::snprintf(name, sizeof name, "  %-9s", c.name);
        u += name;
        u += c.summary;
        u += '\n';
    }
    u += "\n`msid <command> --help` (or -h) shows the options of a command. See README.md and docs/.\n";
    return u;
}

// " (did you mean 'fit'?)" for a name at most two edits from one command, else "".
std::string did_you_mean(const std::string &name)
{
    std::vector<std::string> names;
    for (const Command &c : COMMANDS) names.push_back(c.name);
    const std::string best = msidcli::closest_word(name, names);
    return best.empty() ? std::string() : " (did you mean '" + best + "'?)";
}

}  // namespace

int main(int argc, char **argv)
{
    if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "help")) {
        std::fputs(usage().c_str(), argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    const std::string cmd = argv[1];
    // -h is --help everywhere, also for the handlers that look for "--help" themselves
    for (int i = 2; i < argc; ++i)
        if (!std::strcmp(argv[i], "-h")) argv[i] = const_cast<char *>("--help");
    // A file size limit (ulimit -f) must end a run with an error, not SIGXFSZ: then write() fails with
    // EFBIG and the temporary file is removed (no out.json.tmp.PID is left behind).
    std::signal(SIGXFSZ, SIG_IGN);
    msidcli::remove_partials_on_fatal_signals();
    try {
        for (const Command &c : COMMANDS)
            if (cmd == c.name) return c.run(argc, argv);
        if (cmd == "--version") return cmd_version(argc, argv);
        std::fprintf(stderr, "msid: error: unknown command '%s'%s (try msid --help)\n", cmd.c_str(),
                     did_you_mean(cmd).c_str());
        return 2;
    } catch (const msidcli::HelpRequest &h) {
        std::fputs(h.text, stdout);
        return 0;
    } catch (const msidcli::Error &e) {
        std::fprintf(stderr, "msid %s: error: %s\n", cmd.c_str(), e.what());
        return e.code;
    } catch (const std::exception &e) {
        std::fprintf(stderr, "msid %s: error: %s\n", cmd.c_str(), e.what());
        return 1;
    }
}
