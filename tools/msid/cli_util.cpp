#include "cli_util.hpp"

#include <algorithm>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <sys/mman.h>
#include <system_error>
#include <thread>
#include <unistd.h>

namespace msidcli {

Args::Args(int argc, char **argv, int first, const std::vector<std::string> &valued,
           const std::vector<std::string> &flags, const std::vector<std::string> &repeatable)
{
    parse(argc, argv, first, valued, flags, repeatable);
}

Args::Args(int argc, char **argv, int first, const char *help, const std::vector<std::string> &valued,
           const std::vector<std::string> &flags, const std::vector<std::string> &repeatable)
{
    help_if_asked(argc, argv, first, help);
    parse(argc, argv, first, valued, flags, repeatable);
}

void help_if_asked(int argc, char **argv, int first, const char *help)
{
    for (int i = first; i < argc; ++i)
        if (!std::strcmp(argv[i], "--help") || !std::strcmp(argv[i], "-h")) throw HelpRequest{help};
}

// Edit distance of two short words: insertions, deletions, substitutions and swaps of two
// neighbouring letters ("fti" is one swap from "fit"), each counting 1.
static size_t edit_distance(const std::string &a, const std::string &b)
{
    const size_t n = a.size(), m = b.size();
    std::vector<std::vector<size_t>> d(n + 1, std::vector<size_t>(m + 1));
    for (size_t i = 0; i <= n; ++i) d[i][0] = i;
    for (size_t j = 0; j <= m; ++j) d[0][j] = j;
    for (size_t i = 1; i <= n; ++i)
        for (size_t j = 1; j <= m; ++j) {
            d[i][j] = std::min({d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + (a[i - 1] != b[j - 1])});
            if (i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1]) d[i][j] = std::min(d[i][j], d[i - 2][j - 2] + 1);
        }
    return d[n][m];
}

std::string closest_word(const std::string &word, const std::vector<std::string> &words)
{
    std::string best;
    size_t bd = 3;
    for (const std::string &w : words) {
        const size_t d = edit_distance(word, w);
        if (d < bd) {
            bd = d;
            best = w;
        }
    }
    return best;
}

void Args::parse(int argc, char **argv, int first, const std::vector<std::string> &valued,
                 const std::vector<std::string> &flags, const std::vector<std::string> &repeatable)
{
    auto in = [](const std::vector<std::string> &v, const std::string &k) {
        for (auto &x : v) if (x == k) return true;
        return false;
    };
    for (int i = first; i < argc; ++i) {
        std::string a = argv[i];
        if (a.size() > 2 && a[0] == '-' && a[1] == '-') {
            std::string key = a.substr(2), val;
            bool inl = false;
            auto eq = key.find('=');
            if (eq != std::string::npos) { val = key.substr(eq + 1); key = key.substr(0, eq); inl = true; }
            if (in(flags, key)) {
                if (inl) throw UsageError("option --" + key + " takes no value");
                kv_[key].push_back("1");
            } else if (in(valued, key) || in(repeatable, key)) {
                if (!inl) {
                    if (i + 1 >= argc) throw UsageError("option --" + key + " needs a value");
                    val = argv[++i];
                }
                if (kv_.count(key) && !in(repeatable, key))
                    throw UsageError("option --" + key + " is given twice");
                kv_[key].push_back(val);
            } else {   // a misspelt option: the nearest one this command takes
                std::vector<std::string> all(valued);
                all.insert(all.end(), flags.begin(), flags.end());
                all.insert(all.end(), repeatable.begin(), repeatable.end());
                const std::string near = closest_word(key, all);
                throw UsageError("unknown option --" + key + (near.empty() ? "" : " (did you mean --" + near + "?)"));
            }
        } else if (a == "-o") {
            if (i + 1 >= argc) throw UsageError("option -o needs a value");
            if (kv_.count("output")) throw UsageError("option -o is given twice");
            kv_["output"].push_back(argv[++i]);
        } else if (a.size() > 1 && a[0] == '-' && !(a[1] >= '0' && a[1] <= '9')) {
            throw UsageError("unknown option " + a);
        } else {
            pos_.push_back(a);
        }
    }
}

bool Args::has(const std::string &k) const { return kv_.count(k) != 0; }
std::string Args::get(const std::string &k, const std::string &def) const
{
    auto it = kv_.find(k);
    return it == kv_.end() ? def : it->second.back();
}
const std::vector<std::string> &Args::all(const std::string &k) const
{
    static const std::vector<std::string> none;
    auto it = kv_.find(k);
    return it == kv_.end() ? none : it->second;
}
std::string Args::require(const std::string &k) const
{
    if (!has(k)) throw UsageError(k == "output" ? "missing -o <file>" : "missing --" + k);
    return get(k);
}

uint32_t Args::u32(const std::string &k, uint32_t def) const { return has(k) ? parse_u32(get(k), "--" + k) : def; }
uint64_t Args::u64(const std::string &k, uint64_t def) const { return has(k) ? parse_u64(get(k), "--" + k) : def; }
double Args::f64(const std::string &k, double def) const { return has(k) ? parse_double(get(k), "--" + k) : def; }

uint32_t Args::u32(const std::string &k, uint32_t def, uint32_t lo, uint32_t hi) const
{
    const uint32_t v = u32(k, def);
    if (v < lo || v > hi) throw UsageError(fmt("--%s must be %u..%u", k.c_str(), lo, hi));
    return v;
}


static std::vector<std::string> split(const std::string &s, char sep)
{
    std::vector<std::string> out;
    size_t a = 0;
    for (;;) {
        size_t b = s.find(sep, a);
        out.push_back(s.substr(a, b == std::string::npos ? std::string::npos : b - a));
        if (b == std::string::npos) break;
        a = b + 1;
    }
    return out;
}

std::vector<uint32_t> parse_uint_list(const std::string &s, const std::string &what)
{
    std::vector<uint32_t> out;
    if (trim(s).empty()) throw UsageError(what + ": empty list");
    for (auto &item : split(s, ',')) {
        auto parts = split(item, ':');
        if (parts.size() == 1) {
            out.push_back(parse_u32(parts[0], what));
        } else if (parts.size() == 2 || parts.size() == 3) {
            uint32_t a = parse_u32(parts[0], what), b = parse_u32(parts.back(), what);
            uint32_t st = parts.size() == 3 ? parse_u32(parts[1], what) : 1;
            if (st == 0 || b < a) throw UsageError(what + ": bad range '" + item + "'");
            if ((uint64_t)(b - a) / st > 50000000ull) throw UsageError(what + ": range '" + item + "' is too long");
            for (uint64_t k = a; k <= b; k += st) out.push_back((uint32_t)k);
        } else {
            throw UsageError(what + ": bad item '" + item + "'");
        }
    }
    return out;
}

std::vector<double> parse_double_list(const std::string &s, const std::string &what)
{
    std::vector<double> out;
    if (trim(s).empty()) throw UsageError(what + ": empty list");
    for (auto &item : split(s, ',')) out.push_back(parse_double(item, what));
    return out;
}

int dispatch_subcommand(int argc, char **argv, const char *group, const char *help,
                        const std::vector<Subcommand> &subs, bool sub_help)
{
    const std::string sub = argc > 2 ? argv[2] : "";
    if (sub.empty() || sub == "--help" || sub == "-h") {
        std::fputs(help, sub.empty() ? stderr : stdout);
        return sub.empty() ? 2 : 0;
    }
    if (!sub_help) help_if_asked(argc, argv, 3, help);
    std::string names;
    for (const Subcommand &s : subs) {
        if (sub == s.name) return s.run(argc, argv);
        names += (names.empty() ? "" : ", ") + std::string(s.name);
    }
    throw UsageError("unknown subcommand '" + std::string(group) + " " + sub + "' (" + names + ")");
}

}  // namespace msidcli
