#!/usr/bin/env python3
"""The host libraries' stages in order: the FRF stage (records, formats, FRF files, the FRF statistics,
the estimators, the FRF job, the imports, the acquisition) never depends on the fit stage (tools/fit,
tools/fitjob). Fails when a source of an FRF-stage folder includes a header of a fit-stage folder, or
when an FRF-stage folder's CMakeLists.txt links a fit-stage library.

    check_stages.py [ROOT]       check the tree (default: this script's repository)
    check_stages.py --self-test  show that an include and a link across the stages are reported
"""
import os
import re
import sys
import tempfile
from pathlib import Path

# folders of tools/ by stage (the fit stage may use everything of the FRF stage)
FRF_STAGE = ["util", "records", "formats", "frffile", "frfstat", "est", "frfjob", "frfimport", "acquire"]
FIT_STAGE = ["fit", "fitjob"]
FIT_LIBS = ["msid_fit", "msid_fitjob"]

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
LINK = re.compile(r"target_link_libraries\s*\(([^)]*)\)", re.S)


def violations(root):
    tools = Path(root) / "tools"
    fit_headers = {}
    for d in FIT_STAGE:
        for h in (tools / d).glob("**/*.hpp"):
            fit_headers.setdefault(h.name, h.relative_to(root))
    out = []
    for d in FRF_STAGE:
        folder = tools / d
        if not folder.is_dir():
            continue
        own = {p.name for p in folder.glob("**/*") if p.is_file()}
        for src in sorted(folder.glob("**/*")):
            if src.suffix not in (".cpp", ".hpp", ".c", ".h"):
                continue
            for inc in INCLUDE.findall(src.read_text(errors="replace")):
                name = os.path.basename(inc)
                # a header of the folder's own (or beside the source) is not the other stage's
                if name in fit_headers and name not in own and not (src.parent / inc).exists():
                    out.append(f"{src.relative_to(root)} includes {inc} ({fit_headers[name]}, the fit stage)")
        cm = folder / "CMakeLists.txt"
        if cm.exists():
            text = re.sub(r"#[^\n]*", "", cm.read_text())
            for args in LINK.findall(text):
                for lib in FIT_LIBS:
                    if re.search(rf"(^|\s){lib}(\s|$)", args.split(None, 1)[1] if len(args.split(None, 1)) > 1 else ""):
                        out.append(f"{cm.relative_to(root)} links {lib} (the fit stage)")
    return out


def self_test():
    with tempfile.TemporaryDirectory() as t:
        root = Path(t)
        (root / "tools/fit").mkdir(parents=True)
        (root / "tools/frfjob").mkdir(parents=True)
        (root / "tools/fit/stats.hpp").write_text("#pragma once\n")
        (root / "tools/frfjob/job.cpp").write_text('#include "job.hpp"\n')
        (root / "tools/frfjob/job.hpp").write_text("#pragma once\n")
        (root / "tools/frfjob/CMakeLists.txt").write_text(
            "# msid_fit in a comment is not a link\ntarget_link_libraries(msid_frfjob PUBLIC msid)\n")
        if violations(root):
            print("self-test: a clean tree was reported:", violations(root))
            return 1
        (root / "tools/frfjob/job.cpp").write_text('#include "job.hpp"\n#include "stats.hpp"\n')
        (root / "tools/frfjob/CMakeLists.txt").write_text(
            "target_link_libraries(msid_frfjob PUBLIC msid\n  PRIVATE msid_fit)\n")
        v = violations(root)
        want = ["tools/frfjob/job.cpp includes stats.hpp", "tools/frfjob/CMakeLists.txt links msid_fit"]
        missing = [w for w in want if not any(x.startswith(w) for x in v)]
        if missing:
            print("self-test: not reported:", missing, "got", v)
            return 1
    print("self-test: an include and a link of the fit stage from the FRF stage are reported")
    return 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    root = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parent.parent
    v = violations(root)
    for x in v:
        print(x)
    if v:
        print(f"{len(v)} dependence(s) of the FRF stage on the fit stage")
        return 1
    print("the FRF stage (tools/" + ", ".join(FRF_STAGE) + ") neither includes nor links the fit stage")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
