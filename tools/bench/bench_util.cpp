// The shared parts of msid_bench (bench_util.hpp).
#include "bench_util.hpp"

#include "msid_host_error.hpp"
#include "msid_host_util.hpp"

#include <chrono>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <sys/utsname.h>
#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace msidbench {

void Writer::print(const char *f, ...)
{
    va_list ap, ap2;
    va_start(ap, f);
    va_copy(ap2, ap);
    const int n = std::vsnprintf(nullptr, 0, f, ap);
    va_end(ap);
    std::string s(n > 0 ? (size_t)n : 0, '\0');
    if (n > 0) std::vsnprintf(&s[0], s.size() + 1, f, ap2);
    va_end(ap2);
    report_.text += s;
    if (sink_.out) sink_.out(s);
}

void Writer::error(const std::string &line)
{
    report_.errors.push_back(line);
    if (sink_.err) sink_.err(line + "\n");
}

double wall_s()
{
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double process_cpu_s() { return (double)std::clock() / CLOCKS_PER_SEC; }

double thread_cpu_s()
{
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

std::string machine()
{
    std::string cpu = "unknown cpu";
    std::ifstream f("/proc/cpuinfo");
    std::string line;
    while (std::getline(f, line))
        if (line.rfind("model name", 0) == 0) { cpu = line.substr(line.find(':') + 2); break; }
    struct utsname u;
    uname(&u);
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return cpu + ", " + std::to_string(n) + " cores, " + u.sysname + " " + u.release;
}

std::string peers_dir()
{
    const char *env = std::getenv("MSID_PEERS_DIR");
    return env ? env : std::string(MSID_SOURCE_DIR) + "/tools/peers";
}

int capture(const std::string &cmd, std::string &out)
{
    FILE *p = popen(cmd.c_str(), "r");
    if (!p) return -1;
    char buf[4096];
    while (std::fgets(buf, sizeof buf, p)) out += buf;
    return pclose(p);
}

double process_time(const std::string &cmd, int reps)
{
    std::vector<double> t;
    for (int k = 0; k < reps; ++k) {
        const double t0 = wall_s();
        if (std::system((cmd + " >/dev/null 2>&1").c_str()) != 0) return -1;
        t.push_back(wall_s() - t0);
    }
    std::sort(t.begin(), t.end());
    return t[t.size() / 2];
}

void write_all(const std::string &path, const std::string &s)
{
    FILE *f = std::fopen(path.c_str(), "wb");
    if (!f || std::fwrite(s.data(), 1, s.size(), f) != s.size() || std::fclose(f) != 0)
        throw msidutil::Error("cannot write '" + path + "'");
}

std::string npy_image(const std::vector<double> &x, size_t n, size_t cols)
{
    std::string h = msidutil::fmt("{'descr': '<f8', 'fortran_order': False, 'shape': (%zu, %zu), }", n, cols);
    while ((10 + h.size() + 1) % 64) h += ' ';
    h += '\n';
    std::string s = "\x93NUMPY";
    s += '\x01';
    s += '\x00';
    s += (char)(h.size() & 0xff);
    s += (char)(h.size() >> 8);
    s += h;
    s.append((const char *)x.data(), x.size() * sizeof(double));
    return s;
}

Times time_process(const std::string &exe, const std::vector<std::string> &args, double min_s, bool quiet,
                   int min_runs, bool exit3_ok)
{
    std::vector<char *> av;
    for (const auto &s : args) av.push_back(const_cast<char *>(s.c_str()));
    av.push_back(nullptr);
    struct Actions {   // stdout of every start to /dev/null, and stderr when quiet
        posix_spawn_file_actions_t fa;
        explicit Actions(bool quiet)
        {
            if (posix_spawn_file_actions_init(&fa) != 0) throw msidutil::Error("posix_spawn_file_actions failed");
            if (posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0) != 0 ||
                (quiet && posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0) != 0)) {
                posix_spawn_file_actions_destroy(&fa);
                throw msidutil::Error("posix_spawn_file_actions failed");
            }
        }
        ~Actions() { posix_spawn_file_actions_destroy(&fa); }
    } act(quiet);
    auto once = [&](Times &best) {
        const double t0 = wall_s();
        pid_t pid;
        if (posix_spawnp(&pid, exe.c_str(), &act.fa, nullptr, av.data(), environ) != 0)
            throw msidutil::Error("cannot start " + exe + " for the benchmark");
        int st = 0;
        struct rusage ru;
        wait4(pid, &st, 0, &ru);
        const double wall = wall_s() - t0;
        if (!WIFEXITED(st) || (WEXITSTATUS(st) != 0 && !(exit3_ok && WEXITSTATUS(st) == 3)))
            throw msidutil::Error(args[0] + " " + (args.size() > 1 ? args[1] : "") + " failed in the benchmark");
        const double cpu = ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + 1e-6 * (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
        best.wall = std::min(best.wall, wall);
        best.cpu = std::min(best.cpu, cpu);
    };
    Times warm, best;
    once(warm);
    const double t_end = wall_s() + min_s;
    for (int reps = 0; reps < min_runs || wall_s() < t_end; ++reps) once(best);
    return best;
}

std::string temp_dir(const char *prefix)
{
    std::string tmpl = std::string("/tmp/") + prefix + "-XXXXXX";
    if (!mkdtemp(&tmpl[0])) throw msidutil::Error("cannot create a temporary directory");
    return tmpl;
}

void remove_dir(Writer &w, const std::string &dir, const char *note)
{
    if (std::system(("rm -rf '" + dir + "'").c_str()) != 0) w.error(std::string(note) + dir);
}

}  // namespace msidbench
