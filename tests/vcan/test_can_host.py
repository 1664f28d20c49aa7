"""CAN parts that need no CAN kernel (label integration, run on the host): the DBC against
the protocol header, replay errors, the clear error where the kernel has no SocketCAN, and `msid device
check` of a canopen:// node on an interface that is not CAN."""
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


def test_device_check_of_a_canopen_node_on_an_interface_that_is_not_can():
    # the check reads the bus's bit rate before it opens a socket: lo is named as no CAN interface, nothing sent
    r = c.run("device", "check", "--device", "canopen://lo?node=5")
    assert r.returncode == 2, r.stdout + r.stderr
    assert "canopen://lo?node=5: lo is not a CAN interface (it has no link kind)" in r.stderr, r.stderr
    assert r.stdout == ""


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


# ---- hostile logs: a msid-can/1 log written here, frame by frame ----

def _frame(t, fid, data):
    return f"({t:.6f}) vcan0 {fid:03X}#{bytes(data).hex().upper()}"


def _cfg_frames(periods, P=64, bins=(1, 3, 5), seed=7, encoding=1):
    import struct
    import zlib
    recs = [(0x01, 1, 0), (0x02, 0, P), (0x03, 0, len(bins)), (0x04, 0, 1), (0x05, 0, 1), (0x06, 0, 0),
            (0x07, 0, 0), (0x08, 0, seed & 0xFFFFFFFF), (0x08, 1, seed >> 32)]
    recs += [(0x09, l, b) for l, b in enumerate(bins)]
    recs += [(0x10, 0, encoding), (0x11, 0, struct.unpack("<I", struct.pack("<f", 0.001))[0]), (0x12, 0, 0), (0x13, 0, 0),
             (0x14, 0, periods)]
    out, crc = [], 0
    for p, idx, v in recs:
        d = bytes([p, idx & 0xFF, (idx >> 8) & 0xFF, idx >> 16]) + v.to_bytes(4, "little")
        crc = zlib.crc32(d, crc)
        out.append(d)
    out.append(bytes([0x7F, 0, 0, 0]) + crc.to_bytes(4, "little"))
    return out


def _hostile_log(path, periods=4, done=None, P=64):
    """Host CFG upload, device INFO, RUNNING(0), K P samples of a 1-input 1-output device (float32 classic,
    2 frames per sample), DONE(0, done or K P)."""
    import math
    import struct
    t, lines = 1.0, []
    for d in _cfg_frames(periods, P):
        lines.append(_frame(t, 0x201, d))
        t += 1e-4
    lines.append(_frame(t, 0x202, [1, 1, 1, 1, 0, 0, 0, 0]))
    lines.append(_frame(t, 0x202, [0, 3, 0, 0] + list((periods * P).to_bytes(4, "little"))))
    for n in range(periods * P):
        u = math.cos(2 * math.pi * n / P) + math.cos(2 * math.pi * 3 * n / P + 1) + math.cos(2 * math.pi * 5 * n / P + 2)
        row = (u, 0.5 * u + 0.01 * ((n * 7919) % 13))
        fl = (0x40 if n % P == 0 else 0) | (0x80 if n == 0 else 0)
        for k in range(2):
            t += 1e-5
            lines.append(_frame(t, 0x220 + k, [n & 0xFF, (n >> 8) & 0xFF, n >> 16, fl] + list(struct.pack("<f", row[k]))))
    lines.append(_frame(t, 0x202, [0, 4, 0, 0] + list((done if done is not None else periods * P).to_bytes(4, "little"))))
    write_log(path, lines)


def test_replay_done_beyond_the_design_is_bounded(tmp_path):
    """Hardening finding 1 (docs/reliability.md): a DONE claiming 0xFFFFFFFF samples made replay run ~50 s and exit 0 with 4.29e9 missing samples.
    It is closed at the design's K P now: a note, nothing missing, the same FRF as the honest log."""
    _hostile_log(tmp_path / "ok.log")
    _hostile_log(tmp_path / "bad.log", done=0xFFFFFFFF)
    ok = c.run("can", "replay", "--log", tmp_path / "ok.log", "--skip-periods", 1, "-o", tmp_path / "ok.json")
    assert ok.returncode == 0, ok.stderr
    r = c.run("can", "replay", "--log", tmp_path / "bad.log", "--skip-periods", 1, "-o", tmp_path / "bad.json")
    assert r.returncode == 0, r.stderr
    assert "announced more samples than the design" in r.stderr and "0 missing" in r.stdout, r.stdout + r.stderr
    a, b = json.loads((tmp_path / "ok.json").read_text()), json.loads((tmp_path / "bad.json").read_text())
    assert a["lines"] == b["lines"] and b["acquisition"]["samples_lost"] == 0
    assert b["acquisition"]["malformed"] == 1


def test_replay_upload_asking_for_absurd_periods(tmp_path):
    """Hardening finding 4 (docs/reliability.md): an upload asking for 5,000,000 periods (valid CRC) made replay take 4.58 GB: it is not a
    complete design upload now (2..100000 periods), one clear error, nothing written."""
    _hostile_log(tmp_path / "big.log", periods=4)
    lines = (tmp_path / "big.log").read_text().splitlines()
    cfg = _cfg_frames(5000000)
    lines[:len(cfg)] = [_frame(1.0 + 1e-4 * i, 0x201, d) for i, d in enumerate(cfg)]
    write_log(tmp_path / "big.log", lines)
    r = c.run("can", "replay", "--log", tmp_path / "big.log", "-o", tmp_path / "f.json")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "no complete design upload" in r.stderr
    assert not (tmp_path / "f.json").exists()


def test_on_device_bad_options_and_no_bus(design, tmp_path):
    """`msid can measure --on-device`: options refused before the bus is opened (exit 2), and a missing
    interface or SocketCAN as for the streaming host (exit 1); one message, no file."""
    out = tmp_path / "f.json"
    base = ["can", "measure", "--on-device", "--iface", "msidnone0", "--design", design, "-o", out]
    for extra, msg in ((["--detect-lines", 4], "--detect-lines is not available with --on-device"),
                       (["--stream-check", tmp_path / "h.json", "--bitrate", 500000], "--stream-check streams every sample"),
                       (["--stream-check", out], "different files"),
                       (["--base", "0x7FF"], "--base must be a multiple of 0x80"),
                       (["--skip-periods", 70000], "--skip-periods")):
        r = c.run(*base, *extra)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and msg in r.stderr, (extra, r.stderr)
    r = c.run(*base)
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "msidnone0" in r.stderr or "SocketCAN" in r.stderr, r.stderr
    assert not out.exists() and not (tmp_path / "h.json").exists()
    r = c.run("can", "measure", "--help")
    assert r.returncode == 0 and "--on-device" in r.stdout
