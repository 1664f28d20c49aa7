"""CAN parts that need no CAN kernel (label integration, run on the host): the DBC against
the protocol header, replay errors, and the clear error where the kernel has no SocketCAN."""
import json
import os
import re
import socket
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tests" / "vcan" / "in_vm"))
import canlib as c  # noqa: E402


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    return c.excite(tmp_path_factory.mktemp("d"), lines="1:2:9", periods=4)


def test_dbc_matches_the_protocol_header():
    import cantools
    db = cantools.database.load_file(str(c.DBC))
    hdr = (ROOT / "daq/include/msid_daq/msid_can_proto.h").read_text()
    k = {n: int(v, 0) for n, v in re.findall(r"#define (MSID_CAN_\w+) (0x[0-9A-F]+|\d+)u", hdr)}
    base = 0x200
    assert db.get_message_by_name("MSID_CTRL").frame_id == base + k["MSID_CAN_ID_CTRL"]
    assert db.get_message_by_name("MSID_STATUS").frame_id == base + k["MSID_CAN_ID_STATUS"]
    for tag, key, n, length, per in (("S16", "MSID_CAN_ID_S16", 16, 8, 2), ("F32", "MSID_CAN_ID_F32", 32, 8, 1),
                                     ("FD_S16", "MSID_CAN_ID_FD_S16", 2, 64, 30),
                                     ("FD_F32", "MSID_CAN_ID_FD_F32", 3, 64, 15)):
        for j in range(n):
            m = db.get_message_by_name(f"MSID_{tag}_{j}")
            assert m.frame_id == base + k[key] + j and m.length == length and m.is_fd == (length == 64)
            assert [s.name for s in m.signals][4:] == [f"ch{j * per + i + 1}" for i in range(per)]
    # a sample frame as msid-devsim builds it: seq 0x030201, experiment 1 + period start, ch1 = 1.0, ch2 invalid
    d = db.get_message_by_name("MSID_S16_0").decode(bytes([1, 2, 3, 0x41, 0xE8, 0x03, 0x00, 0x80]))
    assert d["seq"] == 0x030201 and d["experiment"] == 1 and d["period_start"] == 1 and d["ch1"] == 1.0
    assert str(d["ch2"]) == "invalid"


def test_measure_without_socketcan_or_interface(design, tmp_path):
    try:
        s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
        s.close()
        have = True
    except (OSError, AttributeError):
        have = False
    r = c.run("can", "measure", "--iface", "msidnone0", "--design", design, "-o", tmp_path / "f.json")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1
    assert ("no CAN interface 'msidnone0'" if have else "this kernel has no SocketCAN") in r.stderr
    assert not (tmp_path / "f.json").exists()


def write_log(path, lines):
    Path(path).write_text("".join(l + "\n" for l in lines))


@pytest.mark.parametrize("lines,msg", [
    ([], "no device INFO frame"),
    (["(1.000000) vcan0 202#0101020200000000"], "no complete design upload"),
    (["(1.000000) vcan0 202#0102020200000000"], "protocol version mismatch: the log's device speaks msid-can/2"),
    (["(1.000000) vcan0 202#0101020200000000", "(1.000001) vcan0 212#00"], None),
    (["(1.000000) vcan0 202#0101020200000000", "(1.5) vcan0 2X2#00"], "line 2 is not a candump log line"),
])
def test_replay_errors(tmp_path, lines, msg):
    log = tmp_path / "x.log"
    write_log(log, lines)
    r = c.run("can", "replay", "--log", log, "-o", tmp_path / "f.json")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert msg is None or msg in r.stderr, r.stderr
    assert not (tmp_path / "f.json").exists()


def test_replay_missing_file_and_bad_options(tmp_path):
    r = c.run("can", "replay", "--log", tmp_path / "nope.log", "-o", tmp_path / "f.json")
    assert r.returncode == 1 and "cannot open" in r.stderr
    r = c.run("can", "replay", "--log", tmp_path / "nope.log", "--base", "0x7FF", "-o", tmp_path / "f.json")
    assert r.returncode == 2 and "--base must be a multiple of 0x80" in r.stderr
    r = c.run("can", "frobnicate")
    assert r.returncode == 2 and "unknown subcommand" in r.stderr
    r = c.run("can", "--help")
    assert r.returncode == 0 and "msid can measure" in r.stdout
