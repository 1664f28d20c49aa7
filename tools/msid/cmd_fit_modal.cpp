// `msid modes model.json`: the modal parameters of a model file. See docs/fitting.md.
#include "cli_util.hpp"
#include "commands.hpp"
#include "host_libs.hpp"

#include "modal_io.hpp"
#include "stats.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

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
        const Json j = read_json(a.positional()[0]);
        if (!j.is_object() || j.value("format", "") != "msid-model/1")
            throw FitError("'" + a.positional()[0] + "': not an msid-model/1 file");
        if (j.value("method", "") == "multi")   // poles shared by records, no FRF residues (cmd_fit_multi.cpp)
            return cmd_modes_multi(j, a.positional()[0], a.has("output") ? a.get("output") : std::string());
        const ModalReport r = modal_report(j);
        std::fputs(modal_text(r).c_str(), stdout);
        if (a.has("output")) {
            Json o = modal_json(r);
            o["format"] = "msid-modes/1";
            o["model"] = a.positional()[0];
            write_json_file(a.get("output"), o);
        }
        return 0;
    } catch (const FitError &e) {
        throw Error(e.what());
    } catch (const Json::exception &e) {
        throw Error("'" + a.positional()[0] + "': malformed model file (" + e.what() + ")");
    }
}

}  // namespace msidcli
