#include "frf_io.hpp"

namespace msidcli {

void write_json_file(const std::string &path, const Json &doc)
{
    std::string s = doc.dump(1);
    s += '\n';
    write_file_atomic(path, s);
}

}  // namespace msidcli
