// Model and plots of `msid measure` (measure_outputs.hpp), and the protocol commands' write path
// (measure.hpp).
#include "measure_outputs.hpp"
#include "cli_util.hpp"
#include "measure.hpp"
#include "commands.hpp"
#include "msid_fit_job.hpp"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <csignal>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace msidcli {

void clear_previous_outputs(const std::string &outdir)
{
    for (const char *f : {"model.json", "bode.png", "bode.svg", "report.html", "validation.json", "reference.json"})
        ::unlink((outdir + "/" + f).c_str());
}

SilenceStdout::SilenceStdout(bool on)
{
    if (!on) return;
    std::fflush(stdout);
    saved_ = dup(STDOUT_FILENO);
    const int null = open("/dev/null", O_WRONLY);
    dup2(null, STDOUT_FILENO);
    close(null);
}

SilenceStdout::~SilenceStdout()
{
    if (saved_ < 0) return;
    std::fflush(stdout);
    dup2(saved_, STDOUT_FILENO);
    close(saved_);
}

std::string fit_model(const std::string &frf, const std::string &model, const std::string &method,
                      const std::string &order, bool quiet)
{
    msidfitjob::FitRequest rq;
    rq.method = method;
    rq.order = order;
    try {
        const msidfrf::FrfData f = msidfrf::read_frf(frf);
        SilenceStdout s(quiet);
        try {
            const int rc = write_fit(msidfitjob::fit_frf(f, rq, print_fit_note), model, msidfitjob::order_is_scan(rq));
            if (rc != 0 && rc != 3) return fmt("msid fit exit status %d", rc);
        } catch (const msidfitjob::Error &e) {
            std::fputs(e.before.c_str(), stdout);   // the order table of a scan that kept no order
            throw;
        }
    } catch (const std::exception &e) {
        return e.what();
    }
    return "";
}

pid_t spawn_piped(const std::vector<std::string> &argv, const std::vector<std::string> &env, bool detach, int *out)
{
    int fd[2];
    if (pipe(fd) != 0) return -1;
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = fork();
    if (pid < 0) { close(fd[0]); close(fd[1]); return -1; }
    if (pid == 0) {
        if (detach) {
            setpgid(0, 0);                      // a terminal's Ctrl-C reaches only the parent
            prctl(PR_SET_PDEATHSIG, SIGTERM);   // and the child ends when the parent dies
        }
        dup2(fd[1], STDOUT_FILENO);
        dup2(fd[1], STDERR_FILENO);
        close(fd[0]);
        close(fd[1]);
        for (const auto &e : env) putenv(strdup(e.c_str()));
        std::vector<char *> av;
        for (const auto &s : argv) av.push_back(const_cast<char *>(s.c_str()));
        av.push_back(nullptr);
        execvp(av[0], av.data());
        std::fprintf(stderr, "cannot run %s: %s\n", av[0], std::strerror(errno));
        _exit(127);
    }
    close(fd[1]);
    *out = fd[0];
    return pid;
}

int run_capture(const std::vector<std::string> &argv, const std::vector<std::string> &env, std::string &out)
{
    int rd = -1;
    const pid_t pid = spawn_piped(argv, env, false, &rd);
    if (pid < 0) return -1;
    char buf[4096];
    ssize_t n;
    while ((n = read(rd, buf, sizeof buf)) > 0 || (n < 0 && errno == EINTR))
        if (n > 0) out.append(buf, (size_t)n);
    close(rd);
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR) {}
    if (WIFEXITED(st)) return WEXITSTATUS(st) == 127 ? -1 : WEXITSTATUS(st);
    return 128 + WTERMSIG(st);
}

std::string python_path()
{
    std::string p = std::string(MSID_SOURCE_DIR) + "/tools/python";
    struct stat st;
    if (::stat(p.c_str(), &st) != 0) p.clear();
    const char *old = std::getenv("PYTHONPATH");
    if (old && *old) p = p.empty() ? std::string(old) : p + ":" + old;
    return p;
}

static std::string last_line(const std::string &s)
{
    std::string t = s;
    while (!t.empty() && (t.back() == '\n' || t.back() == ' ')) t.pop_back();
    const size_t nl = t.rfind('\n');
    return nl == std::string::npos ? t : t.substr(nl + 1);
}

std::string shell_line(int argc, char **argv)
{
    std::string line;
    for (int i = 0; i < argc; ++i) {
        const std::string a = i == 0 ? "msid" : argv[i];
        const bool plain = !a.empty() && a.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                               "0123456789-_./:=,@%+") == std::string::npos;
        std::string q = "'";
        for (char c : a) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
        line += (i ? " " : "") + (plain ? a : q + "'");
    }
    return line;
}

std::string make_plots(const std::string &outdir, const std::string &frf, const std::string &model,
                       const std::string &command_line)
{
    const std::vector<std::string> env = {"PYTHONPATH=" + python_path(), "MPLBACKEND=Agg"};
    std::string out;
    const int have = run_capture({"python3", "-c",
                                  "import importlib.util as u, sys\n"
                                  "ok = u.find_spec('msid') is not None and u.find_spec('msid.plot') is not None "
                                  "and u.find_spec('msid.report') is not None\n"
                                  "sys.exit(0 if ok else 3)"},
                                 env, out);
    if (have == -1) return "plots skipped: python3 is not installed";
    if (have == 3) return "plots skipped: the Python package msid (tools/python) has no msid.plot/msid.report modules";
    if (have != 0) return "plots skipped: python3 cannot look for the msid package: " + last_line(out);
    std::vector<std::string> wrote;
    for (const char *ext : {"png", "svg"}) {
        const std::string dst = outdir + "/bode." + ext;
        const std::string tmp = outdir + "/.bode.tmp." + std::to_string(getpid()) + "." + ext;
        std::vector<std::string> av = {"python3", "-m", "msid.plot", frf};
        if (!model.empty()) { av.push_back("--model"); av.push_back(model); }
        av.push_back("-o");
        av.push_back(tmp);
        out.clear();
        const int rc = run_capture(av, env, out);
        if (rc != 0 || std::rename(tmp.c_str(), dst.c_str()) != 0) {
            ::unlink(tmp.c_str());
            return fmt("plots skipped: python3 -m msid.plot failed (exit status %d): %s", rc, last_line(out).c_str());
        }
        wrote.push_back(dst);
    }
    out.clear();
    std::vector<std::string> rep = {"python3", "-m", "msid.report", outdir};
    if (!command_line.empty()) { rep.push_back("--command"); rep.push_back(command_line); }
    const int rc = run_capture(rep, env, out);
    if (rc != 0)
        return fmt("wrote %s and %s; report skipped: python3 -m msid.report failed (exit status %d): %s",
                   wrote[0].c_str(), wrote[1].c_str(), rc, last_line(out).c_str());
    return fmt("wrote %s, %s and %s/report.html", wrote[0].c_str(), wrote[1].c_str(), outdir.c_str());
}

int write_measure_result(MeasureResult &R, const std::string &out, const std::string &cmd)
{
    // a complete run keeps the historic file: no completeness members (R is written once, at the end)
    if (R.complete)
        for (const char *k : {"complete", "experiments_completed", "experiments_planned"}) R.o.tail().erase(k);
    msidjob::write_outcome(out, R.o);
    for (const auto &n : R.o.notes) std::fprintf(stderr, "msid %s: note: %s\n", cmd.c_str(), n.c_str());
    std::printf("wrote %s: %s\n", out.c_str(), R.summary.c_str());
    if (R.complete) return 0;
    std::fprintf(stderr, "msid %s: interrupted: %s is the FRF of the complete periods (\"complete\": false)\n",
                 cmd.c_str(), out.c_str());
    return 128 + (R.stop_reason ? R.stop_reason : SIGINT);
}

}  // namespace msidcli
