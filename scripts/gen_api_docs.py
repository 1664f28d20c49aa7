#!/usr/bin/env python3
"""Generate docs/api/: one page per public C function of lib/ and daq/ (libmodbus
style), from the Doxygen comment in front of each declaration in
lib/include/msid/*.h and daq/include/msid_daq/*.h.

  scripts/gen_api_docs.py            write the pages
  scripts/gen_api_docs.py --check    exit 1 if any page is missing or stale
"""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
INC = ROOT / "lib" / "include" / "msid"
# (include directory, #include prefix, path from the repository root)
INCS = [(INC, "msid", "lib/include/msid"),
        (ROOT / "daq" / "include" / "msid_daq", "msid_daq", "daq/include/msid_daq")]
OUT = ROOT / "docs" / "api"

DECL = re.compile(r"^([A-Za-z_][\w \*]*?\b(msid_\w+))\s*\(([^;{]*)\)\s*;", re.S | re.M)


def clean_comment(c, names):
    """The comment as Markdown; `::msid_x` links to msid_x's page when it has one (a function), else it
    is set as code (a type or an object: no page of its own)."""
    c = re.sub(r"^/\*\*?|\*/$", "", c.strip())
    lines = [re.sub(r"^\s*\* ?", "", ln) for ln in c.splitlines()]
    text = "\n".join(lines).strip()
    text = re.sub(r"@brief\s*", "", text)
    text = re.sub(r"@param\s+(\w+)", r"- `\1`:", text)
    text = re.sub(r"@return\s*", "\nReturns: ", text)
    text = re.sub(r"::(msid_\w+)", lambda m: f"[{m[1]}]({m[1]}.md)" if m[1] in names else f"`{m[1]}`", text)
    return text


def functions():
    out = []
    for h in [h for inc, _, _ in INCS for h in sorted(inc.glob("*.h"))]:
        src = h.read_text()
        for m in DECL.finditer(src):
            name = m.group(2)
            if "(*" in m.group(0) or name.startswith("msid__"):
                continue
            start = m.start()
            before = src[:start].rstrip()
            doc = ""
            if before.endswith("*/"):
                k = before.rfind("/**")
                if k >= 0:
                    doc = before[k:]
            sig = " ".join(m.group(0).split())
            prefix = next(p for inc, p, _ in INCS if h.parent == inc)
            out.append((name, h.name if prefix == "msid" else f"{prefix}/{h.name}", sig, doc))
    names = {n for n, _, _, _ in out}
    return [(n, h, s, clean_comment(d, names) if d else "") for n, h, s, d in out]


def render(name, header, sig, doc):
    inc, path = (header, f"daq/include/{header}") if "/" in header else (f"msid/{header}", f"lib/include/msid/{header}")
    return (f"# {name}\n\n```c\n#include \"{inc}\"\n\n{sig}\n```\n\n"
            f"{doc or '(undocumented)'}\n\nHeader: [`{path}`](../../{path})\n")


def main():
    check = "--check" in sys.argv
    fns = functions()
    pages = {f"{n}.md": render(n, h, s, d) for n, h, s, d in fns}
    index = ("# msid C API\n\nOne page per public function of `libmsid` (and the host-only `libmsid_fftw`), "
             "and of the host acquisition `libmsid_daq` (headers `msid_daq/...`).\n\n")
    by_header = {}
    for n, h, s, d in fns:
        by_header.setdefault(h, []).append(n)
    for h in sorted(by_header):
        index += f"## {h}\n\n" + "".join(f"- [{n}]({n}.md)\n" for n in by_header[h]) + "\n"
    pages["README.md"] = index
    bad = [n for n, _, _, d in fns if not d]
    if bad:
        print("undocumented functions: " + ", ".join(bad), file=sys.stderr)
        return 1
    if check:
        stale = [p for p, t in pages.items() if not (OUT / p).exists() or (OUT / p).read_text() != t]
        extra = [p.name for p in OUT.glob("*.md") if p.name not in pages] if OUT.exists() else []
        if stale or extra:
            print("docs/api is stale; run scripts/gen_api_docs.py: " + ", ".join(stale + extra), file=sys.stderr)
            return 1
        print(f"docs/api up to date ({len(fns)} functions)")
        return 0
    OUT.mkdir(parents=True, exist_ok=True)
    for p in OUT.glob("*.md"):
        if p.name not in pages:
            p.unlink()
    for p, t in pages.items():
        (OUT / p).write_text(t)
    print(f"wrote {len(pages)} pages to {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
