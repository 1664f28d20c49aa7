// What the readers share inside msid_records (not installed).
#pragma once
#include <string>
#include <string_view>

#include "msid_host_util.hpp"
#include "msid_records.hpp"

namespace msidrec {

using msidutil::fmt;
using msidutil::UsageError;

// `v` without leading and trailing spaces and tabs.
std::string trim(std::string_view v);

// The whole file in one buffer, with a '\n' appended so every line ends in one (a pipe).
std::string slurp(const std::string &path);
// A file read with read(2) 1 MiB at a time, each piece handed to `take` (FileError naming the file).
void read_chunks(const std::string &path, const std::function<void(const char *, size_t)> &take);

}  // namespace msidrec
