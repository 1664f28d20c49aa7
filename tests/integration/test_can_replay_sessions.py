"""`msid can replay` sessions and candump direction, with logs written by msid's candump writer.

A session is one design upload (CFG BEGIN..COMMIT) and the experiments run with it (RUNNING .. DONE).
The logs are msid-can/1 sessions of a 1x1 float32 device (the frames of tests/vcan/test_can_host.py:
host CFG upload, device INFO, RUNNING, K P samples, DONE), host frames marked T, then read and written
again by msid's own reader and writer (candump_copy: msid_candump_open/recv -> msid_candump_format).
Checked: the count of sessions, --session N and --since/--until give exactly the FRF of that session's
log alone, sessions of different designs are refused (count and --session named, nothing written),
sessions of one design are pooled, and python-can reads our log (T/R as is_rx) while we read
python-can's log (CanutilsLogWriter) to the same FRF."""
import json
import math
import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

import helpers as h

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "vcan"))
from test_can_host import _cfg_frames  # noqa: E402  (the design upload of a msid-can/1 log)

P = 64


def copier():
    c = os.environ.get("MSID_CANDUMP_COPY")
    if not c:
        pytest.skip("MSID_CANDUMP_COPY not set (ctest sets it)")
    return c


def frame(t, fid, data, tx=False):
    return f"({t:.6f}) vcan0 {fid:03X}#{bytes(data).hex().upper()}" + (" T" if tx else " R")


def session(t0, seed, bins, periods=4, gain=0.5):
    """One session starting at t0 s: (lines, t_end)."""
    t, lines = t0, [frame(t0, 0x202, [1, 1, 1, 1, 0, 0, 0, 0])]       # INFO (identify): v1, 1 in, 1 out
    for d in _cfg_frames(periods, P, bins, seed=seed):
        t += 1e-4
        lines.append(frame(t, 0x201, d, tx=True))
    lines.append(frame(t, 0x200, [1, 0, 0, 0, 0, 0, 0, 0], tx=True))              # START experiment 0
    lines.append(frame(t, 0x202, [0, 3, 0, 0] + list((periods * P).to_bytes(4, "little"))))   # RUNNING
    for n in range(periods * P):
        u = sum(math.cos(2 * math.pi * b * n / P + seed + b) for b in bins)
        row = (u, gain * u + 0.01 * ((n * 7919 + seed) % 13))
        fl = (0x40 if n % P == 0 else 0) | (0x80 if n == 0 else 0)
        for k in range(2):
            t += 1e-5
            lines.append(frame(t, 0x220 + k, [n & 0xFF, (n >> 8) & 0xFF, n >> 16, fl] + list(struct.pack("<f", row[k]))))
    t += 1e-5
    lines.append(frame(t, 0x202, [0, 4, 0, 0] + list((periods * P).to_bytes(4, "little"))))   # DONE
    return lines, t


def write_msid_log(tmp, name, lines):
    """The lines through msid's reader and writer: a log as msid writes it."""
    src, out = tmp / (name + ".in"), tmp / name
    src.write_text("".join(l + "\n" for l in lines))
    r = subprocess.run([copier(), str(src), str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return out


def replay(tmp, log, *args, out="f.json"):
    return h.run("can", "replay", "--log", log, *args, "-o", tmp / out)


def frf_lines(path):
    return json.loads(Path(path).read_text())["lines"]


A, B = dict(seed=7, bins=(1, 3, 5)), dict(seed=9, bins=(2, 4, 7))


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("logs")
    a, ta = session(1.0, **A)
    b, tb = session(ta + 2.0, **B)
    a2, _ = session(tb + 2.0, **A)
    return {"tmp": tmp, "t_b": (ta + 2.0, tb),
            "a": write_msid_log(tmp, "a.log", a), "b": write_msid_log(tmp, "b.log", session(50.0, **B)[0]),
            "ab": write_msid_log(tmp, "ab.log", a + b), "aa": write_msid_log(tmp, "aa.log", a + a2),
            "aba": write_msid_log(tmp, "aba.log", a + b + a2)}


def test_the_log_says_how_many_sessions(logs, tmp_path):
    r = h.run("can", "replay", "--log", logs["ab"], "--list")
    assert r.returncode == 0, r.stderr
    assert "2 session(s)" in r.stdout and r.stdout.count("  session ") == 2, r.stdout
    r = replay(tmp_path, logs["a"])
    assert r.returncode == 0 and "(session 1 of 1)" in r.stdout, r.stdout + r.stderr
    acq = json.loads((tmp_path / "f.json").read_text())["acquisition"]
    assert acq["sessions_in_log"] == 1 and [s["session"] for s in acq["sessions"]] == [1]


def test_different_designs_are_refused_naming_the_count_and_session(logs, tmp_path):
    for log, n in ((logs["ab"], 2), (logs["aba"], 3)):
        r = replay(tmp_path, log)
        assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert f"holds {n} sessions of 2 different designs" in r.stderr and "--session N" in r.stderr, r.stderr
        assert not (tmp_path / "f.json").exists()
    r = replay(tmp_path, logs["ab"], "--session", 3)
    assert r.returncode == 1 and "holds 2 session(s): there is no session 3" in r.stderr
    r = replay(tmp_path, logs["ab"], "--session", 1, "--since", "1.0")
    assert r.returncode == 2 and not (tmp_path / "f.json").exists()


def test_session_selects_exactly_that_session(logs, tmp_path):
    """--session N gives the FRF of that session's log alone, bit for bit (negative control: the other
    session's FRF differs)."""
    assert replay(tmp_path, logs["a"], out="a.json").returncode == 0
    assert replay(tmp_path, logs["b"], out="b.json").returncode == 0
    for n, want in ((1, "a.json"), (2, "b.json"), (3, "a.json")):
        r = replay(tmp_path, logs["aba"], "--session", n, out=f"s{n}.json")
        assert r.returncode == 0 and f"(session {n} of 3)" in r.stdout, r.stdout + r.stderr
        got, ref = frf_lines(tmp_path / f"s{n}.json"), frf_lines(tmp_path / want)
        assert [l["G"] for l in got] == [l["G"] for l in ref] and [l["cov"] for l in got] == [l["cov"] for l in ref]
        # the decoder saw that session's frames, its INFO before the upload included, as the log alone
        ga, ra = (json.loads((tmp_path / x).read_text())["acquisition"] for x in (f"s{n}.json", want))
        for k in ("frames", "status_frames", "host_frames", "sample_frames", "samples"):
            if k in ra:
                assert ga[k] == ra[k], k
    assert [l["bin"] for l in frf_lines(tmp_path / "a.json")] != [l["bin"] for l in frf_lines(tmp_path / "b.json")]


def test_since_until_select_by_log_time(logs, tmp_path):
    t0, t1 = logs["t_b"]
    t0 += 1e-4   # the upload's BEGIN (the INFO before it is at t0)
    # the second session's first and last timestamps, as the log writes them
    r = replay(tmp_path, logs["aba"], "--since", f"{t0:.6f}", "--until", f"({t1:.6f})", out="w.json")
    assert r.returncode == 0 and "(session 2 of 3)" in r.stdout, r.stdout + r.stderr
    assert replay(tmp_path, logs["b"], out="b.json").returncode == 0
    assert [l["G"] for l in frf_lines(tmp_path / "w.json")] == [l["G"] for l in frf_lines(tmp_path / "b.json")]
    # from the second session on: two designs again, refused with the count in range
    r = replay(tmp_path, logs["aba"], "--since", f"{t0:.6f}", out="x.json")
    assert r.returncode == 1 and "holds 2 sessions of 2 different designs in the selected range" in r.stderr
    # a window between sessions selects nothing: one message, no file
    r = replay(tmp_path, logs["aba"], "--since", f"{t1 + 0.5:.6f}", "--until", f"{t1 + 1:.6f}", out="y.json")
    assert r.returncode == 1 and "holds 3 session(s), none from" in r.stderr and not (tmp_path / "y.json").exists()
    r = replay(tmp_path, logs["aba"], "--since", "yesterday", out="z.json")
    assert r.returncode == 2 and "not a log timestamp" in r.stderr


def test_sessions_of_one_design_are_pooled(logs, tmp_path):
    r = replay(tmp_path, logs["aa"], "--skip-periods", 1, out="aa.json")
    assert r.returncode == 0 and "2 of 2 sessions" in r.stdout, r.stdout + r.stderr
    assert "2 sessions of the same design pooled" in r.stderr
    one = replay(tmp_path, logs["aa"], "--skip-periods", 1, "--session", 1, out="a1.json")
    assert one.returncode == 0
    pooled, single = (json.loads((tmp_path / n).read_text()) for n in ("aa.json", "a1.json"))
    assert pooled["periods_used"] == 2 * single["periods_used"] > 0


def test_direction_python_can_reads_ours_and_we_read_theirs(logs, tmp_path):
    can = pytest.importorskip("can")
    text = Path(logs["a"]).read_text().splitlines()
    assert all(l.endswith(" T") for l in text if " 201#" in l or " 200#" in l)
    assert all(l.endswith(" R") for l in text if " 201#" not in l and " 200#" not in l)
    msgs = list(can.CanutilsLogReader(str(logs["a"])))
    assert len(msgs) == len(text)
    assert all(m.is_rx == (m.arbitration_id not in (0x200, 0x201)) for m in msgs)
    # python-can writes the same messages (T/R from is_rx); we replay its log to the same FRF and copy it
    # back to the same frames and directions
    theirs = tmp_path / "pycan.log"
    w = can.CanutilsLogWriter(str(theirs), channel="vcan0")
    for m in msgs:
        w.on_message_received(m)
    w.stop()
    assert sum(l.endswith(" T") for l in theirs.read_text().splitlines()) == sum(not m.is_rx for m in msgs) > 0
    assert replay(tmp_path, logs["a"], out="ours.json").returncode == 0
    r = replay(tmp_path, theirs, out="theirs.json")
    assert r.returncode == 0, r.stderr
    assert frf_lines(tmp_path / "ours.json") == frf_lines(tmp_path / "theirs.json")
    back = tmp_path / "back.log"
    assert subprocess.run([copier(), str(theirs), str(back)]).returncode == 0
    strip = [l.split(" ", 1)[1] for l in back.read_text().splitlines()]
    assert strip == [l.split(" ", 1)[1] for l in text]        # same frames and directions, timestamps aside
    # lines without direction read as before (received)
    plain = tmp_path / "plain.log"
    plain.write_text("".join(l[:-2] + "\n" for l in text))
    assert replay(tmp_path, plain, out="plain.json").returncode == 0
    assert frf_lines(tmp_path / "plain.json") == frf_lines(tmp_path / "ours.json")
