// Shared helpers of the msid command line: errors, options, numbers, files.
#pragma once
#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "msid_host_util.hpp"

namespace msidcli {

// The host libraries' error types (tools/util): main() prints the message once and exits with
// its code (1, or 2 for a usage error).
using msidutil::Error;
using msidutil::UsageError;
using msidutil::IoError;
using msidutil::fmt;
using msidutil::check;
using msidutil::write_file_atomic;
using msidutil::Mem;

// `--help` or `-h` was given: main() prints `text` to stdout and exits 0 (thrown by Args).
struct HelpRequest {
    const char *text;
};

// Throws HelpRequest{help} if `--help` or `-h` is among argv[first..] (what Args does first;
// for a command that looks at argv before it builds its Args).
// The word of `words` at most two edits from `word` (insertions, deletions, substitutions, swaps of
// neighbours), the nearest; "" if none is that near. For "did you mean" in messages.
std::string closest_word(const std::string &word, const std::vector<std::string> &words);

void help_if_asked(int argc, char **argv, int first, const char *help);

// One of `names` (UsageError "--what must be a, b or c (got 'v')" otherwise): its index.
using msidutil::parse_enum;

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
using msidutil::parse_double;
using msidutil::parse_u64;
using msidutil::parse_u32;
using msidutil::trim;
// Comma list of unsigned ints with ranges a:b and a:step:b (inclusive).
std::vector<uint32_t> parse_uint_list(const std::string &s, const std::string &what);
std::vector<double> parse_double_list(const std::string &s, const std::string &what);

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
