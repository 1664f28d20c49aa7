// msid: multisine system identification on the bench.
#include "cli_util.hpp"
#include "commands.hpp"

#include <csignal>
#include <cstdio>
#include <cstring>
#include <string>

static const char *USAGE =
    "usage: msid <command> [options]\n"
    "\n"
    "commands:\n"
    "  measure  measure a device (modbus-tcp://, modbus-rtu://, can://): FRF, model, plots in one directory\n"
    "  excite   design a multisine (msid-design/1) and optionally write its input samples as CSV\n"
    "  frf      estimate the MIMO FRF and its covariance from experiment CSVs (msid-frf/1);\n"
    "           --method lpm|etfe for records that are not steady-state multisines\n"
    "  demo     design, simulate a built-in 2x2 plant, estimate, and compare with the truth\n"
    "  fit      parametric models from an FRF file: --method subspace | lmfd | ml (msid-model/1)\n"
    "           --method cissim: discrete-cISSIM straight from periodic time records (`msid fit --method cissim --help`)\n"
    "  modes    natural frequencies, damping ratios, residues of a model with standard deviations\n"
    "  validate a model against an FRF file: weighted residual cost, p-value, verdict\n"
    "  compare  relative H2 and Hinf distance between two models\n"
    "  can      measure an FRF over SocketCAN from an msid-can/1 device, or replay a candump log\n"
    "  modbus   measure an FRF over Modbus TCP or RTU from an msid-modbus/1 device\n"
    "  plot     Bode plot of an FRF file with 95% regions, model overlay and residuals (PNG/SVG/PDF)\n"
    "  export   an FRF file as CSV or MATLAB .mat (idfrd shape) with standard deviations\n"
    "  bench    benchmarks against peers: frf, fit, lpm, io, can, modbus, target, wcet (`msid bench --help`)\n"
    "  version  print the version\n"
    "\n"
    "`msid <command> --help` (or -h) shows the options of a command. See README.md and docs/.\n";

int main(int argc, char **argv)
{
    if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h") || !std::strcmp(argv[1], "help")) {
        std::fputs(USAGE, argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    const std::string cmd = argv[1];
    // -h is --help everywhere, also for the handlers that look for "--help" themselves
    for (int i = 2; i < argc; ++i)
        if (!std::strcmp(argv[i], "-h")) argv[i] = const_cast<char *>("--help");
    // A file size limit (ulimit -f) must end a run with an error, not SIGXFSZ: then write() fails with
    // EFBIG and the temporary file is removed (issue 15 #10: out.json.tmp.PID was left behind).
    std::signal(SIGXFSZ, SIG_IGN);
    try {
        if (cmd == "excite") return msidcli::cmd_excite(argc, argv);
        if (cmd == "frf") return msidcli::cmd_frf(argc, argv);
        if (cmd == "measure") return msidcli::cmd_measure_uri(argc, argv);
        if (cmd == "demo") return msidcli::cmd_demo(argc, argv);
        if (cmd == "bench") return msidcli::cmd_bench(argc, argv);
        if (cmd == "fit") return msidcli::cmd_fit(argc, argv);
        if (cmd == "validate") return msidcli::cmd_validate(argc, argv);
        if (cmd == "compare") return msidcli::cmd_compare(argc, argv);
        if (cmd == "modes") return msidcli::cmd_modes(argc, argv);
        if (cmd == "can") return msidcli::cmd_can(argc, argv);
        if (cmd == "modbus") return msidcli::cmd_modbus(argc, argv);
        if (cmd == "plot") return msidcli::cmd_plot(argc, argv);
        if (cmd == "export") return msidcli::cmd_export(argc, argv);
        if (cmd == "version" || cmd == "--version") {
            std::printf("msid %s\n", MSID_VERSION);
            return 0;
        }
        std::fprintf(stderr, "msid: error: unknown command '%s' (try msid --help)\n", cmd.c_str());
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
