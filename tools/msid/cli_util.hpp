// Shared helpers of the msid command line: errors, options, numbers, files.
#pragma once
#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
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

// `--help` or `-h` was given: main() prints `text` to stdout and exits 0 (thrown by Args).
struct HelpRequest {
    const char *text;
};

// Throws HelpRequest{help} if `--help` or `-h` is among argv[first..] (what Args does first;
// for a command that looks at argv before it builds its Args).
void help_if_asked(int argc, char **argv, int first, const char *help);

// One of `names` (UsageError "--what must be a, b or c (got 'v')" otherwise): its index.
uint32_t parse_enum(const std::string &value, const std::string &what, const std::vector<std::string> &names);

// Parsed command line: --key value, --key=value, flags, positionals.
class Args {
public:
    Args(int argc, char **argv, int first, const std::vector<std::string> &valued,
         const std::vector<std::string> &flags, const std::vector<std::string> &repeatable = {});
    // The same with the command's help text: `--help` or `-h` anywhere from argv[first] on
    // throws HelpRequest{help} before anything else is parsed (each command states its help once).
    Args(int argc, char **argv, int first, const char *help, const std::vector<std::string> &valued,
         const std::vector<std::string> &flags, const std::vector<std::string> &repeatable = {});
    bool has(const std::string &k) const;
    std::string get(const std::string &k, const std::string &def = "") const;
    const std::vector<std::string> &all(const std::string &k) const;
    const std::vector<std::string> &positional() const { return pos_; }
    std::string require(const std::string &k) const;

    // Typed values of --k with a default when absent; a bad value is a UsageError naming --k.
    uint32_t u32(const std::string &k, uint32_t def) const;
    uint64_t u64(const std::string &k, uint64_t def) const;
    double f64(const std::string &k, double def) const;
    // The same, and the value must lie in [lo, hi] ("--k must be lo..hi" otherwise).
    uint32_t u32(const std::string &k, uint32_t def, uint32_t lo, uint32_t hi) const;
    // --k as one of `names` (default `def`), returned as the value paired with it.
    template <class E> E enum_(const std::string &k, E def, const std::vector<std::pair<std::string, E>> &names) const
    {
        if (!has(k)) return def;
        std::vector<std::string> n;
        for (const auto &x : names) n.push_back(x.first);
        return names[parse_enum(get(k), "--" + k, n)].second;
    }
    // --k as the index of one of `names` (default: the index of `def`).
    uint32_t enum_index(const std::string &k, const std::string &def, const std::vector<std::string> &names) const
    {
        return parse_enum(get(k, def), "--" + k, names);
    }

private:
    void parse(int argc, char **argv, int first, const std::vector<std::string> &valued,
               const std::vector<std::string> &flags, const std::vector<std::string> &repeatable);

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
// `durable`: fsync the data before the rename (a crash or power loss right after
// leaves the old file or the whole new one, never an empty one). Off only for
// results that a re-run reproduces from files (msid frf): it saves the wait for
// the disk.
void write_file_atomic(const std::string &path, const std::string &data, bool durable = true);
// The same file from pieces written one after the other (no copy into one buffer).
void write_file_atomic(const std::string &path, const std::vector<std::string_view> &pieces, bool durable = true);

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

// `msid <group> <sub> ...`: prints `help` (stdout for --help/-h, stderr and exit 2 when no
// subcommand is given) or runs the handler named by argv[2]; an unknown name is a usage
// error listing the known ones. With `sub_help` a --help after the subcommand goes to the
// subcommand (its own Args help); otherwise `help` answers it too.
struct Subcommand {
    const char *name;
    int (*run)(int argc, char **argv);
};
int dispatch_subcommand(int argc, char **argv, const char *group, const char *help,
                        const std::vector<Subcommand> &subs, bool sub_help = false);

}  // namespace msidcli
