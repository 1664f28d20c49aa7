"""Peak RSS of msid on huge inputs (docs/reliability.md), by hand (not a ctest: minutes of CPU):
    MSID_BIN=build/tools/msid python3 tests/soak/peak_rss.py [--rows 10000000] [--frames 10000000]
1. a CSV of ROWS rows (u1, y1; a 1000-sample multisine period through a first-order filter plus noise)
   through `msid frf`;
2. a msid-can/1 candump log of FRAMES frames (the design upload, INFO, RUNNING, FRAMES/2 float32 samples
   of 2 frames each, DONE) through `msid can replay`.
Each under /usr/bin/time -v: peak RSS (VmHWM), wall and CPU time, against the input's size. The
files are written to a temporary directory under /tmp and deleted afterwards."""
import argparse
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import scipy.signal

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "vcan"))
MSID = os.environ["MSID_BIN"]


def timed(*args):
    r = subprocess.run(["/usr/bin/time", "-v", MSID, *map(str, args)], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"msid {args[0]} failed: {r.stderr[-2000:]}")
    g = lambda k: re.search(k + r":\s*(\S+)", r.stderr).group(1)  # noqa: E731
    return int(g("Maximum resident set size \\(kbytes\\)")), g("Elapsed \\(wall clock\\) time \\(h:mm:ss or m:ss\\)"), \
        float(g("User time \\(seconds\\)")) + float(g("System time \\(seconds\\)"))


def csv_case(d, rows, P=1000):
    subprocess.run([MSID, *map(str, ("excite", "--period", P, "--lines", "1:7:400", "--inputs", 1, "--experiments", 1,
                                     "--periods", 2, "--seed", 3, "-o", d / "design.json", "--csv", d))],
                   check=True, capture_output=True)
    u1 = np.loadtxt(d / "e1.csv", delimiter=",", skiprows=1, max_rows=P)
    rng = np.random.default_rng(1)
    path = d / "big.csv"
    with open(path, "w") as f:
        f.write("u1,y1\n")
        zi, chunk = np.zeros(1), 1_000_000
        for s in range(0, rows, chunk):
            n = min(chunk, rows - s)
            u = u1[(np.arange(s, s + n)) % P]
            yy, zi = scipy.signal.lfilter([0.1], [1, -0.9], u, zi=zi)   # y(t) = 0.9 y(t-1) + 0.1 u(t)
            yy = yy + 0.01 * rng.standard_normal(n)
            f.write("\n".join(f"{a:.9g},{b:.9g}" for a, b in zip(u, yy)) + "\n")
    size = path.stat().st_size
    hwm, wall, cpu = timed("frf", "--design", d / "design.json", "--experiment", path, "--skip-periods", 1, "-o", d / "frf.json")
    return size, hwm, wall, cpu


def can_case(d, frames, P=1000):
    from test_can_host import _cfg_frames, _frame
    samples = frames // 2
    periods = samples // P
    bins = tuple(range(1, 400, 7))
    k = np.arange(P)
    up = sum(np.cos(2 * np.pi * b * k / P + 0.1 * b * b) for b in bins) / math.sqrt(len(bins))   # one period
    path = d / "big.log"
    with open(path, "w") as f:
        t = 1.0
        for c in _cfg_frames(periods, P, bins=bins):
            f.write(_frame(t, 0x201, c) + "\n")
            t += 1e-4
        f.write(_frame(t, 0x202, [1, 1, 1, 1, 0, 0, 0, 0]) + "\n")
        f.write(_frame(t, 0x202, [0, 3, 0, 0] + list((periods * P).to_bytes(4, "little"))) + "\n")
        out = []
        for n in range(periods * P):
            u = float(up[n % P])
            fl = (0x40 if n % P == 0 else 0) | (0x80 if n == 0 else 0)
            for k, v in enumerate((u, 0.5 * u + 0.01 * ((n * 7919) % 13))):
                t += 1e-5
                out.append(f"({t:.6f}) vcan0 {0x220 + k:03X}#{n & 0xFF:02X}{(n >> 8) & 0xFF:02X}{n >> 16:02X}{fl:02X}"
                           f"{struct.pack('<f', v).hex().upper()}")
            if len(out) >= 200000:
                f.write("\n".join(out) + "\n")
                out = []
        f.write("\n".join(out) + ("\n" if out else ""))
        f.write(_frame(t, 0x202, [0, 4, 0, 0] + list((periods * P).to_bytes(4, "little"))) + "\n")
    size = path.stat().st_size
    hwm, wall, cpu = timed("can", "replay", "--log", path, "--skip-periods", 1, "-o", d / "can.json")
    return size, hwm, wall, cpu


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rows", type=int, default=10_000_000)
    ap.add_argument("--frames", type=int, default=10_000_000)
    a = ap.parse_args()
    d = Path(tempfile.mkdtemp(prefix="msid-peak-rss-", dir="/tmp"))
    try:
        if a.rows:
            size, hwm, wall, cpu = csv_case(d, a.rows)
            print(f"msid frf, CSV of {a.rows} rows ({size / 1e6:.0f} MB): VmHWM {hwm / 1024:.0f} MiB "
                  f"({hwm * 1024 / size:.2f} x the file), wall {wall}, CPU {cpu:.1f} s", flush=True)
            for f in d.glob("*.csv"):
                f.unlink()
        if a.frames:
            size, hwm, wall, cpu = can_case(d, a.frames)
            print(f"msid can replay, candump log of {a.frames} frames ({size / 1e6:.0f} MB): VmHWM "
                  f"{hwm / 1024:.0f} MiB, wall {wall}, CPU {cpu:.1f} s", flush=True)
    finally:
        shutil.rmtree(d)


if __name__ == "__main__":
    main()
