// The demo build (MSID_DEMO=ON, cmake/msid_demo.cmake) fits an LMFD only: cissim and multi (and
// the sources of tools/fit behind them) are left out; asked for, each is one message naming how to
// get it. The pole-residue ML likewise (fit_poles_left_out.cpp: its own object, which the demo
// msid's tools/msid/left_out.cpp replaces).
#include "fit_job_detail.hpp"

namespace msidfitjob {

[[noreturn]] static void left_out(const char *what)
{
    throw msidutil::Error(std::string("this msid was built by `./bootstrap.sh demo` without `") + what +
                              "`; build everything with `./bootstrap.sh build`",
                          2, msidutil::ErrorKind::usage);
}

void check_cissim(const CissimRequest &) { left_out("fit --method cissim"); }
FitOutcome fit_cissim(const std::vector<Record> &, const CissimRequest &, const Report &) { left_out("fit --method cissim"); }
void check_multi(const MultiRequest &, bool) { left_out("fit --method multi"); }
FitOutcome fit_multi(const std::vector<Record> &, const std::vector<Record> &, const MultiRequest &, const Report &)
{
    left_out("fit --method multi");
}
std::vector<MultiRecord> multi_records(const std::vector<Record> &) { left_out("validate --experiment"); }
ValidateOutcome validate_records(const Json &, const std::string &, const std::vector<Record> &, int, std::optional<bool>)
{
    left_out("validate --experiment");
}
void check_multi_model(const Json &, const std::string &) { left_out("validate --experiment"); }
ModesOutcome modes_of_multi(const Json &, const std::string &) { left_out("modes of a --method multi model"); }

}  // namespace msidfitjob
