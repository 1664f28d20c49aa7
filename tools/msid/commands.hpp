// Subcommands of the msid command line.
#pragma once
#include <string>
namespace msidcli {
int cmd_excite(int argc, char **argv);
int cmd_frf(int argc, char **argv);
int cmd_frf_est(int argc, char **argv);   // --method lpm | etfe
int cmd_demo(int argc, char **argv);
int cmd_measure_uri(int argc, char **argv);   // cmd_measure.cpp: msid measure --device URI
int cmd_bench(int argc, char **argv);
int cmd_bench_lpm(int argc, char **argv);   // msid bench lpm
int cmd_fit(int argc, char **argv);
int cmd_validate(int argc, char **argv);
int cmd_compare(int argc, char **argv);
int cmd_modes(int argc, char **argv);
// cmd_fit_modal.cpp: --order auto|a:b scan, modal parameters of a model document
bool fit_order_is_scan(int argc, char **argv);
int cmd_fit_scan(int argc, char **argv);
int cmd_can(int argc, char **argv);
int cmd_bench_can(int argc, char **argv);
int cmd_modbus(int argc, char **argv);
int cmd_bench_modbus(int argc, char **argv);
int cmd_bench_target(int argc, char **argv);  // msid bench target | wcet
int cmd_bench_io(int argc, char **argv);
}  // namespace msidcli
#include <string>
#include <vector>
#include <nlohmann/json.hpp>
namespace msidcli {
void add_modes(nlohmann::ordered_json &doc, bool print);
// Run a benchmark script with MSID_BIN and MSID_DEVSIM set to this build's binaries (execvp).
int exec_with_build(std::vector<std::string> args);
// The machine line of the benchmarks (CPU, cores, kernel) and the directory of the Python peers.
std::string bench_machine();
std::string bench_python_dir();
}  // namespace msidcli
