#!/usr/bin/env python3
"""Check every relative link of README.md and the Markdown files under docs/, tools/ and firmware_sim/:
the file must exist, and an anchor (#...) must name a heading of the target page (GitHub's rule: the
heading in lower case, punctuation dropped, spaces as hyphens, a repeated heading numbered -1, -2, ...).

  scripts/check_doc_links.py              check the repository, exit 1 naming every broken link
  scripts/check_doc_links.py --self-test  show that a missing file and a missing anchor are reported
"""
import pathlib
import re
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def slug(heading):
    h = heading.replace("`", "").strip().lower()
    return re.sub(r"[^\w\- ]", "", h).replace(" ", "-")


def anchors(page):
    out, seen, fence = set(), {}, False
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            fence = not fence
            continue
        m = None if fence else re.match(r"#{1,6}\s+(.*)", line)
        if m:
            s = slug(m.group(1))
            n = seen.get(s, 0)
            seen[s] = n + 1
            out.add(s if n == 0 else f"{s}-{n}")
    return out


def pages(root):
    found = [root / "README.md"] if (root / "README.md").exists() else []
    for d in ("docs", "tools", "firmware_sim"):
        found += sorted((root / d).rglob("*.md")) if (root / d).exists() else []
    return found


def broken_links(root):
    """(page, link) for every relative link that does not resolve."""
    bad, cache = [], {}
    for page in pages(root):
        text = re.sub(r"```.*?```", "", page.read_text(encoding="utf-8"), flags=re.S)
        text = re.sub(r"`[^`\n]*`", "", text)   # a link inside a code span is text
        for m in LINK.finditer(text):
            target = m.group(1)
            if re.match(r"[a-z][a-z0-9+.-]*:", target):   # http:, https:, mailto:
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            if not dest.exists():
                bad.append((page, target))
            elif anchor and dest.suffix == ".md":
                if dest not in cache:
                    cache[dest] = anchors(dest)
                if anchor not in cache[dest]:
                    bad.append((page, target))
    return bad


def self_test():
    with tempfile.TemporaryDirectory() as d:
        root = pathlib.Path(d)
        (root / "docs").mkdir()
        (root / "docs" / "a.md").write_text("# A page\n\n## Two words\n")
        (root / "README.md").write_text("[ok](docs/a.md) [ok](docs/a.md#two-words) [ok](#the-top)\n"
                                        "# The top\n[bad](docs/b.md) [bad](docs/a.md#three) `[code](x.md)`\n")
        got = sorted(t for _, t in broken_links(root))
        want = ["docs/a.md#three", "docs/b.md"]
        print("self-test:", "passed" if got == want else f"FAILED: {got} != {want}")
        return 0 if got == want else 1


def main():
    if "--self-test" in sys.argv:
        return self_test()
    bad = broken_links(ROOT)
    for page, target in bad:
        print(f"{page.relative_to(ROOT)}: broken link {target}", file=sys.stderr)
    n = len(pages(ROOT))
    print(f"{n} pages, {len(bad)} broken links" if bad else f"{n} pages: every relative link resolves")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
