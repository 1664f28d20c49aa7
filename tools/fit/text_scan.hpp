// Scanners for the short fixed patterns of option values and parameter names (`--pin D1[1,2]=0.5`,
// `--order a:step:b`, LMFD coefficient names): in place of <regex>, whose templates are compiled
// again in every file that uses it. Each advances the position `i` in `s`
// past what it accepted and leaves it where it stopped otherwise.
#pragma once
#include <cctype>
#include <cstring>
#include <string>

namespace msidfit {

// The run of decimal digits at s[i..] (regex \d+); empty if s[i] is not a digit.
inline std::string scan_digits(const std::string &s, size_t &i)
{
    const size_t b = i;
    while (i < s.size() && std::isdigit((unsigned char)s[i])) ++i;
    return s.substr(b, i - b);
}

// The run of characters of `set` at s[i..] (regex [set]+); empty if s[i] is not one of them.
inline std::string scan_set(const std::string &s, size_t &i, const char *set)
{
    const size_t b = i;
    while (i < s.size() && s[i] != '\0' && std::strchr(set, s[i])) ++i;
    return s.substr(b, i - b);
}

// True (i advanced) if s[i] is c.
inline bool scan_char(const std::string &s, size_t &i, char c)
{
    if (i < s.size() && s[i] == c) {
        ++i;
        return true;
    }
    return false;
}

// Skips white space (regex \s*, the C locale's isspace).
inline void scan_spaces(const std::string &s, size_t &i)
{
    while (i < s.size() && std::isspace((unsigned char)s[i])) ++i;
}

}  // namespace msidfit
