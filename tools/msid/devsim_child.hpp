// msid-devsim as a child process of msid (msid demo): found beside this msid, started on a free
// Modbus TCP loopback port, and stopped in every case.
#pragma once
#include <string>
#include <sys/types.h>
#include <vector>

namespace msidcli {

// This msid's own path ("msid" when the system does not say).
std::string self_path();

// msid-devsim: the environment's MSID_DEVSIM, next to msid, in the build tree, or on PATH.
std::string find_devsim();

// The simulator as a child process: its own process group (a terminal's Ctrl-C reaches msid, which
// stops the measurement cleanly first), SIGTERM when msid dies, and the simulator's --idle-exit as
// the last resort. The constructor waits up to 20 s for the ready line that names the port; throws
// Error when it does not come.
class Devsim {
public:
    explicit Devsim(const std::vector<std::string> &args);
    ~Devsim();
    Devsim(const Devsim &) = delete;
    Devsim &operator=(const Devsim &) = delete;
    int port() const { return port_; }
    void stop();   // SIGTERM, then SIGKILL after 2 s; idempotent

private:
    pid_t pid_ = -1;
    int out_ = -1, port_ = 0;
};

}  // namespace msidcli
