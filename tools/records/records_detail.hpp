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

}  // namespace msidrec
