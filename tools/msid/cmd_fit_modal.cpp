// `msid modes model.json`: the modal parameters of a model file (msidfitjob::modes_of). See
// docs/fitting.md.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "msid_fit_job.hpp"

#include <cstdio>

namespace msidcli {

using namespace msidfit;

int cmd_modes(int argc, char **argv)
{
    static const char *HELP =
        "usage: msid modes model.json [-o modes.json]\n"
        "Natural frequencies, damping ratios and residues of every pole pair of an msid-model/1 file,\n"
        "with standard deviations from its parameter covariance (delta method; ml and unique lmfd\n"
        "models). DT poles are mapped to CT by ln(z)/h.\n";
    Args a(argc, argv, 2, HELP, {"output"}, {});
    if (a.positional().size() != 1) throw UsageError("give one msid-model/1 file");
    try {
        const msidfitjob::ModesOutcome m = msidfitjob::modes_of(read_json(a.positional()[0]), a.positional()[0]);
        std::fputs(m.text.c_str(), stdout);
        if (a.has("output")) write_json_file(a.get("output"), m.report);
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    }
}

}  // namespace msidcli
