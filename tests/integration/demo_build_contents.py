#!/usr/bin/env python3
"""ctest demo_build_contents (label integration): what the demo build (`./bootstrap.sh demo`, MSID_DEMO=ON,
cmake/msid_demo.cmake) compiles for `msid` and `msid-devsim`, read from its Ninja commands without building
anything (docs/benchmarks.md "Demo build from a fresh clone"):

- no source of what `msid demo` never runs: the bench procedures, tools/est (LPM, ETFE, direct), the
  cissim, multi and pole-residue fits, the on-device and lpm/etfe handlers, the Python extension;
- every C++ host library as one unity source (at most MAX_CXX_UNITS C++ compiles in all: each compile
  instantiates nlohmann-json and Eigen again, 3-6 s of CPU, so a library split into per-file objects is
  what made the demo build slow), every C++ compile at MSID_DEMO_OPT, not -O3;
- msid's link line without libmsid_est.a or libmsid_bench.a.

usage: demo_build_contents.py SOURCE_DIR WORK_DIR [FULL_BUILD_DIR]
WORK_DIR is configured as a demo build (configure only). FULL_BUILD_DIR, a Ninja build of the default
configuration, is the negative control: its msid must fail the same checks. Exit 77 (skipped) without
Ninja."""
import os
import re
import shlex
import shutil
import subprocess
import sys

# What the demo never runs: these sources must not be compiled for msid or msid-devsim in the demo build.
LEFT_OUT = [
    r"tools/est/", r"tools/bench/", r"tools/python/",
    r"tools/fit/(poleres|poleres_(problem|normal|bound)|multi[a-z_]*|cissim[a-z_]*|real_dft)\.cpp",
    r"tools/acquire/ondevice\.cpp",
    r"tools/fitjob/(fit_poles|fit_cissim|fit_multi|multi_model|modes_multi|validate_records)\.cpp",
    r"tools/frfjob/(frf_direct|frf_est)\.cpp",
    r"tools/msid/(cmd_bench|cmd_fit_cissim|cmd_fit_multi|cmd_ondevice|cmd_frf_est)\.cpp",
]
# C++ compiles of the demo build: one unity source per host library, the explicit Eigen instantiations
# (tools/fit/eigen_inst_*.cpp) and the command line's groups, with a little room.
MAX_CXX_UNITS = 24
LIBS_LEFT_OUT = ["libmsid_est.a", "libmsid_bench.a"]
TARGETS = ["msid_cli", "msid_devsim"]


def ninja(build, *args):
    r = subprocess.run(["ninja", "-C", build, *args], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"demo_build_contents: ninja {' '.join(args)} failed in {build}:\n{r.stderr}")
    return r.stdout


def demo_opt(build):
    """MSID_DEMO_OPT of a configured build directory (cmake/msid_demo.cmake)."""
    with open(os.path.join(build, "CMakeCache.txt"), encoding="utf-8") as f:
        for line in f:
            if line.startswith("MSID_DEMO_OPT:"):
                return line.split("=", 1)[1].strip()
    sys.exit(f"demo_build_contents: no MSID_DEMO_OPT in {build}/CMakeCache.txt")


def unity_members(path, src):
    """The sources a CMake unity source includes (relative to src); none for an ordinary source. A left-out
    source compiled inside a library's unity source is compiled all the same."""
    if not re.search(r"unity_[0-9a-z_]*\.cxx$", path):
        return []
    with open(path, encoding="utf-8") as f:
        inc = re.findall(r'^#include\s+"([^"]+)"', f.read(), re.M)
    return [os.path.relpath(os.path.realpath(i), src) for i in inc]


def problems(build, src, opt):
    """Everything the demo build of `build` compiles or links that it should not (C++ not at `opt`)."""
    out = []
    cmds = [c for c in ninja(build, "-t", "commands", *TARGETS).splitlines() if c.strip()]
    compiles = []
    for c in cmds:
        w = shlex.split(c)
        if "-c" not in w:
            continue
        source = os.path.relpath(os.path.realpath(w[w.index("-c") + 1]), src)
        compiles.append((source, w))
    cxx = [(s, w) for s, w in compiles if not s.endswith(".c")]
    sources = [s for s, _ in compiles]
    for s, _ in compiles:
        sources += unity_members(os.path.join(src, s), src)
    for pat in LEFT_OUT:
        hit = [s for s in sources if re.search(pat, s)]
        if hit:
            out.append(f"compiles what the demo never runs: {', '.join(hit)}")
    if len(cxx) > MAX_CXX_UNITS:
        units = ", ".join(s for s, _ in cxx)
        out.append(f"{len(cxx)} C++ compiles (at most {MAX_CXX_UNITS}: one unity source per host library): {units}")
    for s, w in cxx:
        levels = [a for a in w if re.fullmatch(r"-O[0-3sgz]?", a)]
        if not levels or levels[-1] != opt:
            out.append(f"{s} is compiled at {levels[-1] if levels else 'no -O'}, not the demo build's {opt}")
    links = [c for c in cmds if re.search(r"(^|\s)-o\s+\S*tools/msid(\s|$)", c)]
    if not links:
        out.append("no link command of tools/msid")
    for lib in LIBS_LEFT_OUT:
        if any(lib in c for c in links):
            out.append(f"msid links {lib}")
    return out, len(cxx)


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    src, work = os.path.realpath(sys.argv[1]), sys.argv[2]
    full = sys.argv[3] if len(sys.argv) == 4 else None
    if not shutil.which("ninja"):
        print("demo_build_contents: skipped: no ninja")
        return 77
    shutil.rmtree(work, ignore_errors=True)
    r = subprocess.run(["cmake", "-S", src, "-B", work, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
                        "-DMSID_BUILD_TESTS=OFF", "-DMSID_DEMO=ON"], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"demo_build_contents: the demo configure failed:\n{r.stdout}\n{r.stderr}")
    opt = demo_opt(work)
    bad, n = problems(work, src, opt)
    if bad:
        sys.exit("demo_build_contents: the demo build\n  " + "\n  ".join(bad))
    if full:   # negative control: the default build's msid compiles and links what the demo leaves out
        bad_full, n_full = problems(full, src, opt)
        if not bad_full:
            sys.exit(f"demo_build_contents: negative control: the full build in {full} passed the demo's checks")
        print(f"demo_build_contents: negative control: the full build fails them ({len(bad_full)} findings, "
              f"{n_full} C++ compiles)")
    shutil.rmtree(work, ignore_errors=True)
    print(f"demo_build_contents: ok ({n} C++ compiles, none of what the demo never runs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
