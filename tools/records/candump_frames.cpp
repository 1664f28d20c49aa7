// The frames of a candump .log, line by line through daq's parser (msid_candump_parse), with the
// line numbers that messages name.
#include "msid_candump_dbc.hpp"
#include "records_detail.hpp"

#include <cstdio>
#include <cstring>

namespace msidrec {

void for_each_candump_frame(const std::string &path,
                            const std::function<bool(const msid_can_frame &, uint64_t line)> &take)
{
    const FileBytes f(path);
    const char *p = f.data(), *end = p + f.size();
    std::string line;
    char iface[64];
    msid_can_frame fr;
    for (uint64_t no = 1; p < end; ++no) {
        const char *nl = static_cast<const char *>(std::memchr(p, '\n', (size_t)(end - p)));
        const char *e = nl ? nl : end;
        line.assign(p, e);
        p = nl ? nl + 1 : end;
        const int st = msid_candump_parse(line.c_str(), &fr, iface, sizeof iface);
        if (st == 1) continue;
        if (st < 0 || std::memchr(line.data(), 0, line.size())) {
            const std::string shown = line.size() > 80 ? line.substr(0, 80) + "..." : line;
            throw Error(fmt("'%s' line %llu is not a candump log line: '%s'", path.c_str(), (unsigned long long)no,
                            shown.c_str()));
        }
        if (!take(fr, no)) return;
    }
}

bool is_candump_line(const std::string &line)
{
    msid_can_frame fr;
    char iface[64];
    return msid_candump_parse(line.c_str(), &fr, iface, sizeof iface) == 0;
}

void refuse_candump_without_dbc(const std::string &path)
{
    if (path.size() < 4 || path.compare(path.size() - 4, 4, ".log")) return;
    std::FILE *f = std::fopen(path.c_str(), "r");
    if (!f) return;
    char line[512];
    bool candump = false;
    while (std::fgets(line, sizeof line, f)) {
        if (line[std::strspn(line, " \t\r\n")] == 0) continue;
        candump = is_candump_line(line);
        break;
    }
    std::fclose(f);
    if (candump)
        throw ColumnSpecError("'" + path + "' is a candump log: give the DBC file that describes its frames (--dbc FILE) "
                              "and the signals of each input and output (" MSID_OPT("columns") " u1=MESSAGE.SIGNAL,...,y1=MESSAGE.SIGNAL)");
}

}  // namespace msidrec
