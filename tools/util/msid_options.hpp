// The options of a request by their neutral names, and how each front end words them. A library's
// message names an option as MSID_OPT("skip_periods"); the command line prints it as its flag
// (--skip-periods), the Python extension as its keyword (skip_periods). The library never picks the
// front end's words, so one check serves every caller.
#pragma once
#include <cstring>
#include <string>

namespace msidutil {

// An option in a message: its neutral name between two unit separators (0x1f), a string literal to
// concatenate with the message's other literals: UsageError(MSID_OPT("threads") " must be 1..64").
#define MSID_OPT(id) "\x1f" id "\x1f"
constexpr char OPTION_MARK = '\x1f';

// MSID_OPT of a name known at run time.
inline std::string option_mark(const std::string &id) { return OPTION_MARK + id + OPTION_MARK; }

// The neutral name of a command-line option's name (without its "--"): skip-periods -> skip_periods.
inline std::string option_id(std::string flag_name)
{
    for (char &c : flag_name)
        if (c == '-') c = '_';
    return flag_name;
}

// How a front end names an option.
enum class OptionWords {
    flag,      // the command line: --skip-periods
    keyword,   // Python: skip_periods
};

// The options whose flag and keyword are not the neutral name's plain spelling (the flag: "--", the
// name with '-' for '_'; the keyword: the name itself). Only the options whose words differ are listed.
struct OptionName {
    const char *id;        // neutral name, as in MSID_OPT
    const char *flag;      // the command line's
    const char *keyword;   // Python's
};
inline const OptionName *option_exceptions(size_t &n)
{
    static const OptionName table[] = {
        {"no_realtime", "--no-realtime", "realtime=False"},   // msid measure; msid.measure(realtime=False)
    };
    n = sizeof table / sizeof table[0];
    return table;
}

// The front end's word for option `id`.
inline std::string option_word(const std::string &id, OptionWords w)
{
    size_t n = 0;
    const OptionName *t = option_exceptions(n);
    for (size_t k = 0; k < n; ++k)
        if (id == t[k].id) return w == OptionWords::flag ? t[k].flag : t[k].keyword;
    if (w == OptionWords::keyword) return id;
    std::string f = "--" + id;
    for (size_t k = 2; k < f.size(); ++k)
        if (f[k] == '_') f[k] = '-';
    return f;
}

// A message with its MSID_OPT names in the front end's words (a message without any is returned as it is).
inline std::string render_options(const std::string &m, OptionWords w)
{
    if (m.find(OPTION_MARK) == std::string::npos) return m;
    std::string out;
    out.reserve(m.size() + 16);
    for (size_t i = 0; i < m.size();) {
        const size_t a = m.find(OPTION_MARK, i);
        const size_t b = a == std::string::npos ? a : m.find(OPTION_MARK, a + 1);
        if (b == std::string::npos) {   // an unpaired mark: the rest as it is, without the mark
            for (; i < m.size(); ++i)
                if (m[i] != OPTION_MARK) out += m[i];
            break;
        }
        out.append(m, i, a - i);
        out += option_word(m.substr(a + 1, b - a - 1), w);
        i = b + 1;
    }
    return out;
}

}  // namespace msidutil
