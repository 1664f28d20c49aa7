// `msid plot`: Bode magnitude and phase with exact 95% regions, model overlay, normalised residuals and
// the stabilisation diagram, drawn by the Python package (tools/python/msid/plot.py, docs/python.md).
// This command finds the package (next to the install, in the source tree, or pip-installed), checks
// that Python can import it and matplotlib (one clear message if not), then runs `python3 -m msid.plot`.
#include "cli_util.hpp"
#include "commands.hpp"
#include "frf_import.hpp"
#include "msid_json_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace msidcli {

static const char *PLOT_HELP =
    "usage: msid plot frf.json [--model model.json] -o bode.png|bode.svg|bode.pdf [--level 0.95] [--known-input]\n"
    "                [--format msid|touchstone|uff|csv|mat]\n"
    "Bode magnitude and phase of every output/input pair with the exact confidence regions of the file's\n"
    "covariance and dof (F(2, 2 dof), docs/statistics.md), the model's response and the normalised\n"
    "residuals per line, and the stabilisation diagram when the model file has one (--order auto).\n"
    "Drawn by the Python package (python3 -m msid.plot, matplotlib); MSID_PYTHON names the interpreter\n"
    "(default python3), MSID_PYTHON_DIR the directory holding the msid package.\n"
    "An FRF measured by another tool (Touchstone, UFF 58, CSV, idfrd .mat: --format, or by its extension)\n"
    "is imported as msid import does; without a covariance it is drawn without regions.\n";

static bool file_exists(const std::string &p) { return access(p.c_str(), R_OK) == 0; }

// The directory holding msid/plot.py: $MSID_PYTHON_DIR, the install (bin/../share/msid/python), the
// source tree; "" when none has it (then only a pip-installed package can serve).
static std::string python_package_dir()
{
    std::vector<std::string> cand;
    if (const char *e = std::getenv("MSID_PYTHON_DIR")) cand.push_back(e);
    char self[4096];
    const ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n > 0) {
        self[n] = 0;
        std::string dir(self);
        dir = dir.substr(0, dir.rfind('/'));
        cand.push_back(dir + "/../share/msid/python");
    }
    cand.push_back(std::string(MSID_SOURCE_DIR) + "/tools/python");
    for (const auto &d : cand)
        if (file_exists(d + "/msid/plot.py")) return d;
    return "";
}

static std::string interpreter()
{
    const char *e = std::getenv("MSID_PYTHON");
    return e && *e ? e : "python3";
}

// Run `python -c code` quietly; its exit status (127: the interpreter could not be started).
static int probe(const std::string &py, const std::string &code)
{
    const pid_t pid = fork();
    if (pid < 0) throw Error(std::string("cannot start ") + py + ": " + std::strerror(errno));
    if (pid == 0) {
        const int fd = open("/dev/null", O_WRONLY);
        if (fd >= 0) { dup2(fd, 1); dup2(fd, 2); }
        execlp(py.c_str(), py.c_str(), "-c", code.c_str(), (char *)nullptr);
        _exit(127);
    }
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR) {}
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

// PYTHONPATH gets the package directory; Python must import `module` and matplotlib. Returns the
// interpreter's name; throws Error with one message naming what is missing.
static std::string prepare_python(const std::string &module)
{
    const std::string py = interpreter(), dir = python_package_dir();
    if (!dir.empty()) {
        const char *old = std::getenv("PYTHONPATH");
        const std::string pp = old && *old ? dir + ":" + old : dir;
        setenv("PYTHONPATH", pp.c_str(), 1);
    }
    const int rc = probe(py, "import sys\ntry:\n import " + module + "\nexcept Exception:\n sys.exit(10)\n"
                             "try:\n import matplotlib\nexcept Exception:\n sys.exit(11)\n");
    const std::string where = dir.empty() ? "no msid/plot.py next to the install or in the source tree"
                                          : "package directory " + dir;
    if (rc == 10)
        throw Error("Python (" + py + ") cannot import " + module + " (" + where +
                    "): pip install ./tools/python, or set MSID_PYTHON_DIR");
    if (rc == 11)
        throw Error("Python (" + py + ") has no matplotlib: apt-get install python3-matplotlib (Debian) or "
                    "pip install matplotlib");
    if (rc != 0)
        throw Error("cannot run Python ('" + py + "', exit status " + std::to_string(rc) +
                    "): install python3 with matplotlib, or set MSID_PYTHON");
    return py;
}

// {py, -m, module, args...}, and its char* view (null-terminated, pointing into `av`) for execvp.
static std::vector<std::string> argv_of(const std::string &py, const std::string &module,
                                        const std::vector<std::string> &args)
{
    std::vector<std::string> av = {py, "-m", module};
    av.insert(av.end(), args.begin(), args.end());
    return av;
}

static std::vector<char *> c_argv(std::vector<std::string> &av)
{
    std::vector<char *> cav;
    for (auto &s : av) cav.push_back(s.data());
    cav.push_back(nullptr);
    std::fflush(stdout);
    std::fflush(stderr);
    return cav;
}

int run_python_module(const std::string &module, const std::vector<std::string> &args)
{
    std::vector<std::string> av = argv_of(prepare_python(module), module, args);
    std::vector<char *> cav = c_argv(av);
    execvp(cav[0], cav.data());
    throw Error("cannot run " + av[0] + ": " + std::strerror(errno));
}

int call_python_module(const std::string &module, const std::vector<std::string> &args)
{
    std::vector<std::string> av = argv_of(prepare_python(module), module, args);
    std::vector<char *> cav = c_argv(av);
    const pid_t pid = fork();
    if (pid < 0) throw Error("cannot start " + av[0] + ": " + std::strerror(errno));
    if (pid == 0) {
        execvp(cav[0], cav.data());
        _exit(127);
    }
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR) {}
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

namespace {
// A temporary file removed when it goes out of scope (msid plot of an imported FRF).
struct TempFile {
    std::string path;
    void create()
    {
        const char *t = std::getenv("TMPDIR");
        std::string tmpl = std::string(t && *t ? t : "/tmp") + "/msid-plot-XXXXXX.json";
        const int fd = mkstemps(&tmpl[0], 5);
        if (fd < 0) throw Error("cannot create a temporary file in " + tmpl.substr(0, tmpl.rfind('/')) + ": " +
                                std::strerror(errno));
        close(fd);
        path = tmpl;
    }
    ~TempFile()
    {
        if (!path.empty()) unlink(path.c_str());
    }
};
}  // namespace

int cmd_plot(int argc, char **argv)
{
    Args a(argc, argv, 2, PLOT_HELP, {"model", "output", "level", "format"}, {"known-input"});
    if (a.positional().size() != 1) throw UsageError("give one FRF file (msid plot frf.json -o bode.png)");
    const std::string out = a.get("output");
    if (out.empty()) throw UsageError("give the output file with -o bode.png|bode.svg|bode.pdf");
    const size_t dot = out.rfind('.');
    const std::string ext = dot == std::string::npos ? "" : out.substr(dot);
    if (ext != ".png" && ext != ".svg" && ext != ".pdf")
        throw UsageError("'" + out + "': the output must end in .png, .svg or .pdf");
    // An FRF of another tool (msid import): imported to a temporary msid-frf/1 file first, removed after.
    const std::string in = a.positional()[0];
    const bool other = msidfrfimport::format_of(in, a.get("format")) != msidfrfimport::Format::Msid;
    TempFile tmp;
    if (other) {
        tmp.create();
        msidfmt::write_json_file(tmp.path, msidfrfimport::load_document(in, a.get("format")), false);
    }
    std::vector<std::string> args = {other ? tmp.path : in, "-o", out};
    if (a.has("model")) { args.push_back("--model"); args.push_back(a.get("model")); }
    if (a.has("level")) {
        const double l = parse_double(a.get("level"), "--level");
        if (!(l > 0 && l < 1)) throw UsageError("--level must be in (0, 1)");
        args.push_back("--level"); args.push_back(a.get("level"));
    }
    if (a.has("known-input")) args.push_back("--known-input");
    return other ? call_python_module("msid.plot", args) : run_python_module("msid.plot", args);
}

}  // namespace msidcli
