// The demo build (MSID_DEMO=ON, `./bootstrap.sh demo`, cmake/msid_demo.cmake) compiles only what
// `msid demo` runs. The handlers it leaves out (every `msid bench`, `fit --method cissim`,
// `fit --method multi` with its validate and modes forms, `fit --method ml --param poles` (the ML of
// pole-residue models; the demo fits an LMFD), `modbus|can measure --on-device`,
// `frf --method lpm|etfe`, and `frf --direct` (tools/frfjob/frf_direct_left_out.cpp),
// and the cissim, multi and tools/est sources behind them) are replaced by these: one message
// naming the command and how to get it, exit status 2.
#include "cli_util.hpp"
#include "commands.hpp"
#include "fit_job_detail.hpp"

#include <string>

namespace msidcli {

[[noreturn]] static void left_out(const char *what)
{
    throw Error(std::string("this msid was built by `./bootstrap.sh demo` without `") + what +
                    "`; build everything with `./bootstrap.sh build`",
                2);
}

int cmd_bench(int, char **) { left_out("bench"); }
int cmd_fit_cissim(int, char **) { left_out("fit --method cissim"); }
int cmd_fit_multi(int, char **) { left_out("fit --method multi"); }
int cmd_validate_multi(int, char **) { left_out("validate --experiment"); }
int cmd_modbus_ondevice(int, char **) { left_out("modbus measure --on-device"); }
int cmd_can_ondevice(int, char **) { left_out("can measure --on-device"); }
int cmd_frf_est(int, char **) { left_out("frf --method lpm|etfe"); }
}  // namespace msidcli

// The pole-residue ML of the fit job: this definition comes first on the link line of the demo
// build's msid, so tools/fitjob/fit_poles.cpp (its only definition there) is not linked.
msidfitjob::PrResult msidfitjob::fit_ml_poles(const FrfData &, Domain, const std::vector<WeightedLine> &, bool,
                                              const PrOptions &)
{
    msidcli::left_out("fit --method ml --param poles");
}
