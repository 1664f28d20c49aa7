// JSON documents on disk, shared by every file format of msid (design, FRF, model).
#pragma once
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "frf_text.hpp"
#include "msid_host_util.hpp"

namespace msidfmt {

using msidutil::fmt;
using Json = nlohmann::ordered_json;

// A file's bad contents (ErrorKind::data) or a file that cannot be read (ErrorKind::io).
struct Error : msidutil::Error {
    explicit Error(const std::string &m, msidutil::ErrorKind k = msidutil::ErrorKind::data)
        : msidutil::Error(m, 1, k) {}
};

// Read and parse a JSON file, with the file name in every error.
Json read_json_file(const std::string &path);

// Small JSON accessors with clear messages ("<file>: 'key' must be ...").
const Json &jget(const Json &o, const std::string &key, const std::string &file);
uint64_t juint(const Json &o, const std::string &key, const std::string &file);
uint32_t juint32(const Json &o, const std::string &key, const std::string &file);
double jnum(const Json &v, const std::string &what, const std::string &file);

// The first place ("/key/index...") below `at` where `j` holds a NaN or Inf; "" if none.
std::string nonfinite_at(const Json &j, const std::string &at = "");

// Serialise with a trailing newline and write atomically (no partial file on error);
// `durable` as msidutil::write_file_atomic(). A NaN or Inf anywhere is an error naming its place.
void write_json_file(const std::string &path, const Json &doc, bool durable = true);

}  // namespace msidfmt
