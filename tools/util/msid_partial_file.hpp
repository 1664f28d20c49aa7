// The temporary files a command is writing (each is renamed over its result when complete), named
// where a signal handler can find them: a process ended by a signal (Ctrl-C, SIGTERM, a closed pipe)
// removes them instead of leaving OUT.tmp.PID behind. The registry is fixed-size and lock-free, so
// that remove_partial_files() is async-signal-safe.
#pragma once
#include <string>

namespace msidutil {

// One temporary file being written, for its lifetime (construct before the file is created, let it
// go after the rename or the removal). A path of 4096 bytes or more, or more than 32 at once, is
// simply not registered (the write itself is not affected).
class PartialFile {
public:
    explicit PartialFile(const std::string &tmp_path);
    ~PartialFile();
    PartialFile(const PartialFile &) = delete;
    PartialFile &operator=(const PartialFile &) = delete;

private:
    int slot_ = -1;
};

// unlink() every registered temporary file. Async-signal-safe: for a handler of a fatal signal.
void remove_partial_files() noexcept;

}  // namespace msidutil
