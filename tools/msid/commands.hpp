// Subcommands of the msid command line.
#pragma once
#include <string>
#include <vector>
namespace msidfitjob {
struct FitOutcome;
}
namespace msidcli {
int cmd_excite(int argc, char **argv);
int cmd_frf(int argc, char **argv);
int cmd_frf_est(int argc, char **argv);   // --method lpm | etfe
int cmd_demo(int argc, char **argv);
int cmd_measure_uri(int argc, char **argv);   // cmd_measure.cpp: msid measure --device URI
int cmd_bench(int argc, char **argv);
int cmd_fit(int argc, char **argv);
// cmd_fit.cpp: a fit's model file and what msid prints of it (exit status 0, or 3 when the
// iterations ran out); its notes on stderr as they arise.
int write_fit(const msidfitjob::FitOutcome &o, const std::string &out, bool durable);
void print_fit_note(const std::string &note);
int cmd_validate(int argc, char **argv);
int cmd_compare(int argc, char **argv);
int cmd_modes(int argc, char **argv);
// cmd_fit_cissim.cpp: msid fit --method cissim (time records, You et al. 2023)
bool cissim_requested(int argc, char **argv);
int cmd_fit_cissim(int argc, char **argv);
int cmd_can(int argc, char **argv);
int cmd_bench_can(int argc, char **argv);
int cmd_can_decode(int argc, char **argv);        // msid can decode --dbc FILE LOG (cmd_can_decode.cpp)
int cmd_modbus(int argc, char **argv);
int cmd_device(int argc, char **argv);   // cmd_device.cpp: msid device check (msid-device/1)
int cmd_bench_modbus(int argc, char **argv);
int cmd_modbus_ondevice(int argc, char **argv);   // msid modbus measure --on-device (cmd_ondevice.cpp)
int cmd_can_ondevice(int argc, char **argv);      // msid can measure --on-device (cmd_ondevice.cpp)
int cmd_plot(int argc, char **argv);     // cmd_plot.cpp: wraps python3 -m msid.plot
int cmd_export(int argc, char **argv);   // cmd_export.cpp: FRF as CSV or MATLAB idfrd .mat
int cmd_import(int argc, char **argv);   // cmd_import.cpp: another tool's FRF as msid-frf/1
// Run `python3 -m <module> args...` (execvp) with the msid Python package on PYTHONPATH (installed,
// source tree or $MSID_PYTHON_DIR); throws Error with one clear message if Python, the package or
// matplotlib is missing.
int run_python_module(const std::string &module, const std::vector<std::string> &args);
// The same, but in a child process: returns its exit status (e.g. `msid measure` calling msid.report).
int call_python_module(const std::string &module, const std::vector<std::string> &args);
// cmd_fit_multi.cpp: msid fit --method multi (records with eliminated initial conditions)
bool fit_method_is(int argc, char **argv, const char *method);
int cmd_fit_multi(int argc, char **argv);
bool validate_on_records(int argc, char **argv);   // msid validate model.json --experiment ... (cmd_fit_multi.cpp)
int cmd_validate_multi(int argc, char **argv);
}  // namespace msidcli
#include <string>
#include <vector>
#include <nlohmann/json.hpp>
namespace msidcli {
// Run a benchmark script with MSID_BIN and MSID_DEVSIM set to this build's binaries (execvp).
int exec_with_build(std::vector<std::string> args);
}  // namespace msidcli
