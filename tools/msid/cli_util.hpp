// Shared helpers of the msid command line: errors, options, numbers, files.
#pragma once
#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

extern "C" {
#include "msid/msid.h"
}

namespace msidcli {

// One clear message; main() prints it once and exits non-zero.
struct Error : std::runtime_error {
    int code;
    explicit Error(const std::string &m, int c = 1) : std::runtime_error(m), code(c) {}
};
struct UsageError : Error {
    explicit UsageError(const std::string &m) : Error(m, 2) {}
};

// Parsed command line: --key value, --key=value, flags, positionals.
class Args {
public:
    Args(int argc, char **argv, int first, const std::vector<std::string> &valued,
         const std::vector<std::string> &flags, const std::vector<std::string> &repeatable = {});
    bool has(const std::string &k) const;
    std::string get(const std::string &k, const std::string &def = "") const;
    const std::vector<std::string> &all(const std::string &k) const;
    const std::vector<std::string> &positional() const { return pos_; }
    std::string require(const std::string &k) const;

private:
    std::map<std::string, std::vector<std::string>> kv_;
    std::vector<std::string> pos_;
};

// Strict number parsing; `what` names the option in messages.
double parse_double(const std::string &s, const std::string &what);
uint64_t parse_u64(const std::string &s, const std::string &what);
uint32_t parse_u32(const std::string &s, const std::string &what);
// Comma list of unsigned ints with ranges a:b and a:step:b (inclusive).
std::vector<uint32_t> parse_uint_list(const std::string &s, const std::string &what);
std::vector<double> parse_double_list(const std::string &s, const std::string &what);

// Throw Error with msid_strerror() when st != MSID_OK.
void check(msid_status st, const std::string &context);

// Write a file atomically: data goes to a temporary next to `path`, then rename.
void write_file_atomic(const std::string &path, const std::string &data);

// Aligned, owned working memory for one msid object.
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

std::string fmt(const char *f, ...) __attribute__((format(printf, 1, 2)));

// `msid <group> <sub> ...`: prints `help` (stdout for --help anywhere, stderr and exit 2 when
// no subcommand is given) or runs the handler named by argv[2]; an unknown name is a usage
// error listing the known ones.
struct Subcommand {
    const char *name;
    int (*run)(int argc, char **argv);
};
int dispatch_subcommand(int argc, char **argv, const char *group, const char *help,
                        const std::vector<Subcommand> &subs);

}  // namespace msidcli
