// msid bench: placeholder until the benchmark lands.
#include "commands.hpp"
#include "cli_util.hpp"
namespace msidcli {
int cmd_bench(int, char **) { throw UsageError("bench: not yet available"); }
}  // namespace msidcli
