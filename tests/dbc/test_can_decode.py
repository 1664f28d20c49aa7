"""`msid can decode --dbc FILE LOG -o signals.csv`: the long-form CSV, what is counted on stderr, and
bad input (one message naming the file and line, non-zero exit, no output file)."""
import csv
import os
import subprocess

import pytest

from dbc_files import MSID_DBC, candump_line

MSID = os.environ.get("MSID_BIN", "msid")

DBC = """BO_ 256 CMD: 8 HOST
 SG_ torque : 0|16@1- (0.001,0) [-30|30] "Nm" ECU
 SG_ flag : 16|1@1+ (1,0) [0|1] "" ECU
BO_ 2566848528 STATUS: 8 ECU
 SG_ mux M : 0|8@1+ (1,0) [0|255] "" HOST
 SG_ speed m0 : 15|16@0- (0.1,-5) [0|0] "rad/s" HOST
 SG_ pos m1 : 8|32@1- (1,0) [0|0] "rad" HOST
BO_ 1792 FD: 64 ECU
 SG_ tail : 504|8@1+ (1,0) [0|0] "" HOST
SIG_VALTYPE_ 2566848528 pos : 1;
"""


def decode(tmp_path, lines, dbc=DBC):
    (tmp_path / "d.dbc").write_text(dbc)
    (tmp_path / "in.log").write_text("".join(lines))
    out = tmp_path / "out.csv"
    r = subprocess.run([MSID, "can", "decode", "--dbc", tmp_path / "d.dbc", tmp_path / "in.log", "-o", out],
                       capture_output=True, text=True, timeout=120)
    rows = list(csv.reader(open(out))) if out.exists() else None
    return r, rows


T = 1700000000 * 1000000


def test_rows_and_counts(tmp_path):
    lines = [
        candump_line(T, 0x100, False, bytes.fromhex("18FC010000000000"), False),    # torque -1.0, flag 1
        candump_line(T + 10, 0x18FF0010, True, bytes.fromhex("00FFFB0000000000"), False),   # mux 0: speed raw -5
        candump_line(T + 20, 0x18FF0010, True, bytes.fromhex("010000C03F000000"), False),   # mux 1: pos 1.5f
        candump_line(T + 30, 0x123, False, bytes(8), False),                        # not in the DBC
        candump_line(T + 40, 0x18FF0011, True, bytes(8), False),                    # not in the DBC either
        "(1700000000.000050) can0 20000004#0000000000000000\n",                    # an error frame
        candump_line(T + 60, 0x100, False, bytes.fromhex("E803"), False),           # short: torque only
        candump_line(T + 70, 0x700, False, bytes(63) + b"\x2a", True),              # FD, 64 bytes
    ]
    r, rows = decode(tmp_path, lines)
    assert r.returncode == 0, r.stderr
    assert rows == [["time", "message", "signal", "value"],
                    ["1700000000.000000", "CMD", "torque", "-1"],
                    ["1700000000.000000", "CMD", "flag", "1"],
                    ["1700000000.000010", "STATUS", "mux", "0"],
                    ["1700000000.000010", "STATUS", "speed", "-5.5"],
                    ["1700000000.000020", "STATUS", "mux", "1"],
                    ["1700000000.000020", "STATUS", "pos", "1.5"],
                    ["1700000000.000060", "CMD", "torque", "1"],
                    ["1700000000.000070", "FD", "tail", "42"]]
    err = r.stderr.strip().splitlines()
    assert len(err) == 1, r.stderr
    assert "2 frame(s) of 2 identifier(s) not in" in err[0] and "0x123" in err[0] and "ext 0x18FF0011" in err[0]
    assert "1 error frame(s)" in err[0]
    assert "1 frame(s) shorter than their message's length, 1 signal value(s) in them not decoded" in err[0]
    assert "wrote" in r.stdout and "8 values from 5 of 8 frames" in r.stdout


def test_values_read_back_bit_for_bit(tmp_path):
    # factor 0.1 and offset -5: each value is raw * 0.1 - 5 in doubles, and its text reads back as that double
    lines = [candump_line(T + k, 0x18FF0010, True, bytes([0, 0, k]) + bytes(5), False) for k in range(1, 40)]
    r, rows = decode(tmp_path, lines)
    assert r.returncode == 0, r.stderr
    vals = [float(v) for _, _, s, v in rows[1:] if s == "speed"]
    assert vals == [k * 0.1 + -5 for k in range(1, 40)]


def test_msid_dbc_decodes_a_status_frame(tmp_path):
    r, rows = decode(tmp_path, [candump_line(T, 0x202, False, bytes.fromhex("0104020078563412"), False)],
                     MSID_DBC.read_text())
    assert r.returncode == 0, r.stderr
    assert rows[1:] == [[rows[1][0], "MSID_STATUS", "mux", "1"], [rows[1][0], "MSID_STATUS", "version", "4"],
                        [rows[1][0], "MSID_STATUS", "n_inputs", "2"], [rows[1][0], "MSID_STATUS", "n_outputs", "0"],
                        [rows[1][0], "MSID_STATUS", "config_crc", str(0x12345678)]]


@pytest.mark.parametrize("case", ["dbc", "log", "missing", "nolog"])
def test_bad_input_writes_nothing(tmp_path, case):
    lines = [candump_line(T, 0x100, False, bytes(8), False)] * 3
    dbc = DBC
    if case == "dbc":
        dbc = DBC.replace(" SG_ flag : 16|1@1+", " SG_ flag : 16|1@1+ (1,0)")
    if case == "log":
        lines = lines + ["not a frame\n"]
    (tmp_path / "out.csv").unlink(missing_ok=True)
    if case in ("missing", "nolog"):
        (tmp_path / "d.dbc").write_text(dbc)
        args = [MSID, "can", "decode", "--dbc", tmp_path / ("none.dbc" if case == "missing" else "d.dbc")]
        if case == "missing":
            (tmp_path / "in.log").write_text("".join(lines))
            args.append(tmp_path / "in.log")
        r = subprocess.run(args + ["-o", tmp_path / "out.csv"], capture_output=True, text=True, timeout=60)
        rows = None
    else:
        r, rows = decode(tmp_path, lines, dbc)
    assert r.returncode != 0 and rows is None and not (tmp_path / "out.csv").exists()
    assert r.stderr.count("\n") == 1, r.stderr
    want = {"dbc": "d.dbc' line 3: expected '[' before the range", "log": "in.log' line 4 is not a candump log line",
            "missing": "none.dbc", "nolog": "give the candump .log to decode"}[case]
    assert want in r.stderr, r.stderr
