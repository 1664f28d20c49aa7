// msid-devsim as a child process of msid: see devsim_child.hpp.
#include "devsim_child.hpp"

#include "cli_util.hpp"
#include "measure_outputs.hpp"
#include "text_scan.hpp"

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

namespace msidcli {

std::string self_path()
{
    char self[4096];
    const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n <= 0) return "msid";
    self[n] = 0;
    return self;
}

std::string find_devsim()
{
    if (const char *e = std::getenv("MSID_DEVSIM"); e && *e) return e;
    const std::string self = self_path();
    if (self.find('/') != std::string::npos) {
        const std::string dir = self.substr(0, self.rfind('/'));
        for (const std::string &p : {dir + "/msid-devsim", dir + "/../firmware_sim/msid-devsim"}) {
            char real[4096];
            if (access(p.c_str(), X_OK) == 0) return realpath(p.c_str(), real) ? std::string(real) : p;
        }
    }
    return "msid-devsim";
}

// The simulator's first line, "ready on modbus-tcp 127.0.0.1:PORT", read for up to 20 s.
static std::string ready_line(int fd)
{
    std::string text;
    for (int waited = 0; waited < 200 && text.find('\n') == std::string::npos; ++waited) {
        pollfd p{fd, POLLIN, 0};
        if (poll(&p, 1, 100) <= 0) continue;
        char buf[512];
        const ssize_t k = read(fd, buf, sizeof buf);
        if (k <= 0) break;
        text.append(buf, (size_t)k);
    }
    return text.substr(0, text.find('\n'));
}

Devsim::Devsim(const std::vector<std::string> &args)
{
    pid_ = spawn_piped(args, {}, true, &out_);
    if (pid_ < 0) throw Error("cannot start " + args[0] + ": " + std::strerror(errno));
    const std::string line = ready_line(out_);
    static const std::string ready = "ready on modbus-tcp 127.0.0.1:";   // then the port's digits
    const size_t at = line.find(ready);
    size_t i = at == std::string::npos ? 0 : at + ready.size();
    const std::string port = at == std::string::npos ? std::string() : msidfit::scan_digits(line, i);
    if (port.empty()) {
        stop();
        throw Error("msid-devsim (" + args[0] + ") did not start: " + (line.empty() ? "no output in 20 s" : line));
    }
    port_ = std::stoi(port);
}

Devsim::~Devsim() { stop(); }

void Devsim::stop()
{
    if (pid_ > 0) {
        kill(pid_, SIGCONT);
        kill(pid_, SIGTERM);
        int st;
        for (int i = 0; i < 100 && waitpid(pid_, &st, WNOHANG) == 0; ++i) usleep(20000);
        if (waitpid(pid_, &st, WNOHANG) == 0) {
            kill(pid_, SIGKILL);
            waitpid(pid_, &st, 0);
        }
        pid_ = -1;
    }
    if (out_ >= 0) {
        close(out_);
        out_ = -1;
    }
}

}  // namespace msidcli
