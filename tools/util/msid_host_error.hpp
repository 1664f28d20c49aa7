// The error every host library of msid derives its own error type from: one clear message, and
// what kind of problem it names, so that a caller maps it once (the command line to an exit
// status, the Python extension to ValueError or OSError) without knowing which library threw.
#pragma once
#include "msid_options.hpp"

#include <stdexcept>
#include <string>

namespace msidutil {

// What an error is about.
enum class ErrorKind {
    data,    // bad samples, records or file contents (exit status 1; Python ValueError)
    usage,   // a bad request: option values, conflicting settings (exit status 2; ValueError)
    io,      // a file or device that cannot be opened, read or written (exit status 1; OSError)
};

// The message names options neutrally (MSID_OPT, msid_options.hpp): what() is it in the command line's
// words (flags), the one every caller that only prints it shows; text() keeps the neutral names for a
// front end with words of its own (the Python extension: keywords).
struct Error : std::runtime_error {
    int code;          // the command line's exit status for it
    ErrorKind kind;
    explicit Error(const std::string &m, int c = 1, ErrorKind k = ErrorKind::data)
        : std::runtime_error(render_options(m, OptionWords::flag)), code(c), kind(k),
          neutral_(m.find(OPTION_MARK) == std::string::npos ? std::string() : m) {}
    // the message with its options' neutral names (what() when it names none)
    std::string text() const { return neutral_.empty() ? std::string(what()) : neutral_; }

private:
    std::string neutral_;
};

// A bad request (exit status 2).
struct UsageError : Error {
    explicit UsageError(const std::string &m) : Error(m, 2, ErrorKind::usage) {}
};

// A file or device that cannot be used (exit status 1).
struct IoError : Error {
    explicit IoError(const std::string &m) : Error(m, 1, ErrorKind::io) {}
};

}  // namespace msidutil
