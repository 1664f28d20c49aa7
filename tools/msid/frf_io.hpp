// msid-frf/1 and other JSON documents on disk.
#pragma once
#include "design_io.hpp"

namespace msidcli {

// Serialise with a trailing newline and write atomically (no partial file on error).
void write_json_file(const std::string &path, const Json &doc);

}  // namespace msidcli
