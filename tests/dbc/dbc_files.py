"""The DBC files tests/dbc compares msid with cantools on, and small helpers both test files share.

The files are not in the repository: cantools' own test DBCs come from its source distribution and
the production DBCs from the opendbc wheel, both at the versions scripts/deps.sh pins, fetched with
pip into a cache ($MSID_DBC_CACHE, default /var/cache/msid-dbc, else ~/.cache/msid-dbc) once.
"""
import os
import pathlib
import re
import subprocess
import sys
import tarfile
import zipfile

ROOT = pathlib.Path(__file__).resolve().parents[2]
MSID_DBC = ROOT / "daq" / "can" / "msid.dbc"


def pinned(name):
    """The version scripts/deps.sh pins (CANTOOLS=, OPENDBC=)."""
    m = re.search(rf"^{name}=(\S+)$", (ROOT / "scripts" / "deps.sh").read_text(), re.M)
    assert m, f"scripts/deps.sh pins no {name}"
    return m.group(1)


def cache_dir():
    for d in (os.environ.get("MSID_DBC_CACHE"), "/var/cache/msid-dbc",
              os.path.join(os.path.expanduser("~"), ".cache", "msid-dbc")):
        if not d:
            continue
        p = pathlib.Path(d)
        try:
            p.mkdir(parents=True, exist_ok=True)
            if os.access(p, os.W_OK) or any(p.iterdir()):
                return p
        except OSError:
            continue
    raise OSError("no writable cache directory for the DBC files (set MSID_DBC_CACHE)")


def _fetch(cache, pattern, args):
    got = sorted(cache.glob(pattern))
    if got:
        return got[0]
    subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "-d", str(cache)] + args,
                   check=True, timeout=900)
    got = sorted(cache.glob(pattern))
    assert got, f"pip download {args} left no {pattern} in {cache}"
    return got[0]


def _unpack(archive, members, dest):
    """The .dbc members under `members` of a tar or zip archive, into dest (once)."""
    done = dest / ".done"
    if done.exists():
        return sorted(dest.glob("*.dbc"))
    dest.mkdir(parents=True, exist_ok=True)
    if archive.suffix == ".whl":
        with zipfile.ZipFile(archive) as z:
            for n in z.namelist():
                if n.startswith(members) and n.endswith(".dbc") and "/" not in n[len(members):]:
                    (dest / pathlib.Path(n).name).write_bytes(z.read(n))
    else:
        with tarfile.open(archive) as t:
            for m in t.getmembers():
                rel = m.name.split("/", 1)[-1]
                if m.isfile() and rel.startswith(members) and rel.endswith(".dbc") and "/" not in rel[len(members):]:
                    (dest / pathlib.Path(rel).name).write_bytes(t.extractfile(m).read())
    done.write_text("")
    return sorted(dest.glob("*.dbc"))


def corpora():
    """[(corpus name, [paths])]: cantools' test files, opendbc's production files, msid's own."""
    cache = cache_dir()
    ct, od = pinned("CANTOOLS"), pinned("OPENDBC")
    sdist = _fetch(cache, f"cantools-{ct}.tar.gz", ["--no-binary", ":all:", f"cantools=={ct}"])
    wheel = _fetch(cache, f"opendbc-{od}-*.whl", [f"opendbc=={od}"])
    return [(f"cantools {ct} tests/files/dbc", _unpack(sdist, "tests/files/dbc/", cache / f"cantools-{ct}-dbc")),
            (f"opendbc {od} opendbc/dbc", _unpack(wheel, "opendbc/dbc/", cache / f"opendbc-{od}-dbc")),
            ("msid daq/can/msid.dbc", [MSID_DBC])]


def candump_line(t_us, frame_id, extended, data, fd):
    """One candump -l line (as python-can's CanutilsLogWriter writes it, T/R direction included)."""
    ident = f"{frame_id:08X}" if extended else f"{frame_id:03X}"
    sep = "##1" if fd else "#"
    return f"({t_us // 1000000:010d}.{t_us % 1000000:06d}) can0 {ident}{sep}{bytes(data).hex().upper()} R\n"
