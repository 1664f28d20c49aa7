// Small helpers every host library shares: printf-style messages, the core's status as an
// exception, atomic file writes and aligned working memory for the core's objects.
#pragma once
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "msid_host_error.hpp"

extern "C" {
#include "msid/msid.h"
}

namespace msidutil {

// printf into a std::string (at most 1023 characters).
std::string fmt(const char *f, ...) __attribute__((format(printf, 1, 2)));

// Throw Error("<context>: <msid_strerror(st)>") when st != MSID_OK.
void check(msid_status st, const std::string &context);

// Write a file atomically: data goes to a temporary next to `path`, then rename.
// `durable`: fsync the data before the rename (a crash or power loss right after
// leaves the old file or the whole new one, never an empty one). Off only for
// results that a re-run reproduces from files (msid frf): it saves the wait for
// the disk. The file gets the umask's permissions (mode 0666 less the umask). Throws IoError naming
// the file.
void write_file_atomic(const std::string &path, const std::string &data, bool durable = true);
// The same file from pieces written one after the other (no copy into one buffer).
void write_file_atomic(const std::string &path, const std::vector<std::string_view> &pieces, bool durable = true);

// Aligned (MSID_MEM_ALIGN), zeroed, owned working memory for one msid object.
struct Mem {
    void *p = nullptr;
    size_t n = 0;
    Mem() = default;
    explicit Mem(size_t bytes);
    Mem(const Mem &) = delete;
    Mem &operator=(const Mem &) = delete;
    Mem(Mem &&o) noexcept : p(o.p), n(o.n) { o.p = nullptr; o.n = 0; }
    Mem &operator=(Mem &&o) noexcept;
    ~Mem();
};

// Strict number parsing (the whole text, blanks around it allowed); `what` names the value in the
// UsageError ("--order: 'x' is not a non-negative integer", "... is too large", "... is not finite").
std::string trim(const std::string &s);
double parse_double(const std::string &s, const std::string &what);
uint64_t parse_u64(const std::string &s, const std::string &what);
uint32_t parse_u32(const std::string &s, const std::string &what);
// One of `names` (UsageError "--what must be a, b or c (got 'v')" otherwise): its index.
uint32_t parse_enum(const std::string &value, const std::string &what, const std::vector<std::string> &names);

}  // namespace msidutil
