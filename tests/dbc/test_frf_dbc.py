"""`msid frf --dbc`: a candump log decoded with a DBC is an experiment record.

A simulated periodic experiment on an ECU-like device: `msid excite --csv` gives a multisine, the
command frame (standard identifier, Intel int16) carries it, a FIR plant responds, and the status
frame (extended identifier) carries the responses, one as a Motorola signed int16 and one as an Intel
float32, with white noise; frames are encoded by cantools and written by python-can's
CanutilsLogWriter. Over several seeds the FRF's exact 95% regions cover the true FRF within the
binomial bounds; a log with dropped command frames gives NaN rows for the missing samples and exactly
the periods they touch rejected; bad input gets one message naming the file, line or column.
"""
import json
import math
import os
import subprocess

import can
import cantools
import numpy as np
import pytest

from msid import read_frf

MSID = os.environ.get("MSID_BIN", "msid")
P, K, SKIP = 128, 10, 1
LINES = list(range(1, 33, 2))
DT_US = 1000

DBC = """VERSION ""
NS_ :
\tCM_
\tBA_DEF_
\tBA_
\tSIG_VALTYPE_

BS_:

BU_: HOST ECU

BO_ 256 CMD: 8 HOST
 SG_ torque_cmd : 0|16@1- (0.001,0) [-30|30] "Nm" ECU
 SG_ counter : 16|8@1+ (1,0) [0|255] "" ECU

BO_ 2566848528 STATUS: 8 ECU
 SG_ speed : 7|16@0- (0.001,0) [-32|32] "rad/s" HOST
 SG_ pos : 16|32@1- (1,0) [-1e6|1e6] "rad" HOST

CM_ BO_ 256 "command; sent every millisecond";
BA_DEF_ BO_ "GenMsgCycleTime" INT 0 65535;
BA_DEF_DEF_ "GenMsgCycleTime" 0;
BA_ "GenMsgCycleTime" BO_ 256 1;
BA_ "GenMsgCycleTime" BO_ 2566848528 1;
SIG_VALTYPE_ 2566848528 pos : 1;
"""
COLUMNS = "u1=CMD.torque_cmd,y1=STATUS.speed,y2=STATUS.pos"
H = [np.array([0.6, 0.3, -0.2, 0.1]), np.array([0.2, -0.5, 0.4, 0.25, -0.1])]   # the FIR plants y1, y2
NOISE = 0.05


def run(*args, ok=True):
    r = subprocess.run([MSID, *map(str, args)], capture_output=True, text=True, timeout=600)
    if ok:
        assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp("frf_dbc")
    (d / "ecu.dbc").write_text(DBC)
    run("excite", "--period", P, "--lines", "1:2:31", "--inputs", 1, "--experiments", 1, "--periods", K,
        "-o", d / "design.json", "--csv", d / "run")
    u = np.loadtxt(d / "run" / "e1.csv", delimiter=",", skiprows=1)
    assert u.shape == (P * K,)
    return d, 2.0 * u / np.max(np.abs(u))


def true_frf():
    k = np.array(LINES)
    return [np.array([np.sum(h * np.exp(-2j * np.pi * np.arange(len(h)) * b / P)) for b in k]) for h in H]


def write_log(path, u, seed, drop=()):
    """The experiment as a candump log: per sample n, STATUS(y[n]) then CMD(u[n]); CMD frames in `drop` left out."""
    db = cantools.database.load_string(DBC, database_format="dbc")
    cmd, st = db.get_message_by_name("CMD"), db.get_message_by_name("STATUS")
    rng = np.random.default_rng(seed)
    # the device applies the command as the frame carries it (int16 of 0.001 Nm)
    uq = np.array([cmd.decode(cmd.encode({"torque_cmd": float(x), "counter": 0}))["torque_cmd"] for x in u])
    y = [np.convolve(uq, h)[:len(u)] + NOISE * rng.standard_normal(len(u)) for h in H]
    t0 = 1700000000.0
    with can.CanutilsLogWriter(str(path), channel="can0") as w:
        for n in range(len(u)):
            t = t0 + n * DT_US * 1e-6
            w.on_message_received(can.Message(timestamp=t, arbitration_id=st.frame_id, is_extended_id=True,
                                              data=st.encode({"speed": float(y[0][n]), "pos": float(y[1][n])})))
            if n not in drop:
                w.on_message_received(can.Message(timestamp=t + 0.0005, arbitration_id=cmd.frame_id,
                                                  is_extended_id=False,
                                                  data=cmd.encode({"torque_cmd": float(u[n]), "counter": n % 256})))


def frf(d, log, out, *extra):
    return run("frf", "--dbc", d / "ecu.dbc", "--columns", COLUMNS, "--period", P, "--lines", "1:2:31",
               "--skip-periods", SKIP, "--experiment", log, "-o", out, *extra)


def binomial_bounds(n, p, tail=0.001):
    """[lo, hi] holding Binomial(n, p) with probability >= 1 - 2 tail."""
    pmf = [math.comb(n, k) * p ** k * (1 - p) ** (n - k) for k in range(n + 1)]
    lo, c = 0, 0.0
    while c + pmf[lo] < tail:
        c += pmf[lo]
        lo += 1
    hi, c = n, 0.0
    while c + pmf[hi] < tail:
        c += pmf[hi]
        hi -= 1
    return lo, hi


def test_regions_cover_the_true_frf(bench):
    d, u = bench
    G0 = true_frf()
    inside = total = 0
    seeds = range(12)
    for seed in seeds:
        log, out = d / f"s{seed}.log", d / f"s{seed}.json"
        write_log(log, u, seed)
        r = frf(d, log, out)
        assert "lost" not in r.stderr, r.stderr
        f = read_frf(str(out))
        assert f.n_inputs == 1 and f.n_outputs == 2
        rad = f.radius(0.95)
        for i in range(2):
            inside += int(np.sum(np.abs(f.G[:, i, 0] - G0[i]) <= rad[:, i, 0]))
            total += len(LINES)
    doc = json.loads(out.read_text())
    # names and units from the DBC
    assert doc["input_names"] == ["torque_cmd"] and doc["output_names"] == ["speed", "pos"], doc.get("input_names")
    assert doc["input_units"] == ["Nm"] and doc["output_units"] == ["rad/s", "rad"]
    lo, hi = binomial_bounds(total, 0.95)
    print(f"\n95% regions: {inside} of {total} true FRF values inside (bounds {lo}..{hi})")
    assert lo <= inside <= hi


def test_lost_frames_reject_the_periods_they_touch(bench):
    d, u = bench
    # period 2 loses one frame; period 5 three in a row; period 7 one at its first and one at its last sample
    drop = {2 * P + 40, 5 * P + 3, 5 * P + 4, 5 * P + 5, 7 * P, 8 * P - 1}
    log, out = d / "drop.log", d / "drop.json"
    write_log(log, u, 99, drop)
    r = frf(d, log, out)
    assert "6 frame(s) lost in 4 gap(s)" in r.stderr, r.stderr
    assert "rejected, never interpolated" in r.stderr
    doc = json.loads(out.read_text())
    assert doc["periods_rejected"] == 3, doc["periods_rejected"]
    assert doc["periods_used"] == K - SKIP - 3
    # the same log without the losses uses every period
    write_log(d / "full.log", u, 99)
    frf(d, d / "full.log", d / "full.json")
    full = json.loads((d / "full.json").read_text())
    assert full["periods_rejected"] == 0 and full["periods_used"] == K - SKIP


def test_bad_input_is_named(bench, tmp_path):
    d, u = bench
    log = d / "s0.log"
    if not log.exists():
        write_log(log, u, 0)
    base = ["frf", "--period", P, "--lines", "1:2:31", "-o", tmp_path / "x.json"]

    def fails(args, *want, code=None):
        r = run(*base, *args, ok=False)
        assert r.returncode != 0 and all(w in r.stderr for w in want), r.stderr
        assert r.stderr.count("\n") == 1, r.stderr
        assert not (tmp_path / "x.json").exists()
        if code is not None:
            assert r.returncode == code

    dbc = d / "ecu.dbc"
    fails(["--dbc", dbc, "--columns", "u1=CMD.torque,y1=STATUS.speed", "--experiment", log],
          "--columns u1=CMD.torque", "has no signal torque", "torque_cmd", code=2)
    fails(["--dbc", dbc, "--columns", "u1=CMDX.torque_cmd,y1=STATUS.speed", "--experiment", log], "no message CMDX")
    fails(["--dbc", dbc, "--columns", "u1=torque_cmd,y1=STATUS.speed", "--experiment", log],
          "--columns u1=torque_cmd", "MESSAGE.SIGNAL")
    fails(["--dbc", dbc, "--experiment", log], "--dbc needs --columns")
    # a log without the row message
    lines = [ln for ln in log.read_text().splitlines(True) if " 100#" not in ln]
    (tmp_path / "nocmd.log").write_text("".join(lines))
    fails(["--dbc", dbc, "--columns", COLUMNS, "--experiment", tmp_path / "nocmd.log"], "nocmd.log", "no frame of message CMD",
          "u1=CMD.torque_cmd")
    # a .log that is not candump format, and a broken line inside one
    (tmp_path / "notes.log").write_text("u1,y1\n0.5,1.0\n")
    fails(["--dbc", dbc, "--columns", COLUMNS, "--experiment", tmp_path / "notes.log"],
          "notes.log' line 1 is not a candump log line")
    text = log.read_text().splitlines(True)
    text[10] = "(1700000000.010000) can0 100#zz R\n"
    (tmp_path / "broken.log").write_text("".join(text))
    fails(["--dbc", dbc, "--columns", COLUMNS, "--experiment", tmp_path / "broken.log"], "broken.log' line 11")
    # a DBC with a bad line
    (tmp_path / "bad.dbc").write_text(DBC.replace("0|16@1-", "0|16@2-"))
    fails(["--dbc", tmp_path / "bad.dbc", "--columns", COLUMNS, "--experiment", log], "bad.dbc' line 13", "byte order")
    # a candump log given without --dbc, to the periodic estimator and to --method lpm
    fails(["--experiment", log], "is a candump log", "--dbc FILE", code=2)
    r = run("frf", "--method", "lpm", "--experiment", log, "-o", tmp_path / "x.json", ok=False)
    assert r.returncode == 2 and "is a candump log" in r.stderr and r.stderr.count("\n") == 1, r.stderr
