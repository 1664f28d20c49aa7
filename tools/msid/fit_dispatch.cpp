// Which form of a command was asked for, from its arguments alone: the dispatch of `msid fit` and
// `msid validate` (cmd_fit.cpp) to the cissim and multi handlers, which a demo build leaves out
// (left_out.cpp), so these tests live apart from them.
#include "commands.hpp"

#include <cstring>

namespace msidcli {

bool cissim_requested(int argc, char **argv)
{
    for (int i = 2; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--method") && i + 1 < argc && !std::strcmp(argv[i + 1], "cissim")) return true;
        if (!std::strcmp(argv[i], "--method=cissim")) return true;
    }
    return false;
}

bool fit_method_is(int argc, char **argv, const char *method)
{
    for (int i = 2; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--method") && i + 1 < argc && !std::strcmp(argv[i + 1], method)) return true;
        if (!std::strncmp(argv[i], "--method=", 9) && !std::strcmp(argv[i] + 9, method)) return true;
    }
    return false;
}

bool validate_on_records(int argc, char **argv)
{
    for (int i = 2; i < argc; ++i)
        if (!std::strcmp(argv[i], "--experiment") || !std::strncmp(argv[i], "--experiment=", 13)) return true;
    return false;
}

}  // namespace msidcli
