"""Interop: int16 CAN samples decode with the DBC's factor exactly as cantools does.

The design uploads the int16 step as a float32 parameter (0.001f = 0.0010000000474974513); the DBC
(daq/can/msid.dbc) and so cantools scale by the decimal 0.001. A candump log of a 1x1 int16 device is
replayed by `msid can replay`; the same frames decoded by cantools go through the independent NumPy
peer (msid_peers.frf_peer). The FRF is scale-free, so the check is on the absolute levels: the noise
covariance (scale^2) and the output spectrum of a detection line agree to 1e-12 — with the float32
value they differ by 9.5e-8 relative (the negative control computes that gap)."""
import json
import math
import struct
import sys

import numpy as np
import pytest
from conftest import ROOT, msid

from msid_peers import frf_peer

sys.path.insert(0, str(ROOT / "tests" / "vcan"))
from test_can_host import _cfg_frames  # noqa: E402  (the design upload of a msid-can/1 log)

cantools = pytest.importorskip("cantools")
P, K, BINS = 64, 4, (1, 3, 5)


def frame(t, fid, data):
    return f"({t:.6f}) vcan0 {fid:03X}#{bytes(data).hex().upper()}"


def test_int16_scale_agrees_with_cantools(tmp_path):
    rng = np.random.default_rng(5)
    t, lines, samples = 1.0, [], []
    for d in _cfg_frames(K, P, BINS, encoding=0):   # 1x1, int16, step 0.001f
        lines.append(frame(t, 0x201, d))
        t += 1e-4
    lines.append(frame(t, 0x202, [1, 1, 1, 1, 0, 0, 0, 0]))
    lines.append(frame(t, 0x202, [0, 3, 0, 0] + list((K * P).to_bytes(4, "little"))))
    for n in range(K * P):
        u = sum(math.cos(2 * math.pi * b * n / P + b) for b in BINS)
        raw = [int(round(u / 0.001)), int(round((0.5 * u + 0.05 * rng.standard_normal()) / 0.001))]
        fl = (0x40 if n % P == 0 else 0) | (0x80 if n == 0 else 0)
        t += 1e-5
        lines.append(frame(t, 0x210, [n & 0xFF, (n >> 8) & 0xFF, n >> 16, fl] + list(struct.pack("<hh", *raw))))
    lines.append(frame(t, 0x202, [0, 4, 0, 0] + list((K * P).to_bytes(4, "little"))))
    log = tmp_path / "run.log"
    log.write_text("\n".join(lines) + "\n")
    msid("can", "replay", "--log", log, "--detect-lines", "2", "-o", tmp_path / "frf.json")
    doc = json.loads((tmp_path / "frf.json").read_text())

    db = cantools.database.load_file(str(ROOT / "daq" / "can" / "msid.dbc"))
    msg = db.get_message_by_frame_id(0x210)
    rows = []
    for ln in lines:
        fid, data = ln.split()[2].split("#")
        if int(fid, 16) == 0x210:
            d = msg.decode(bytes.fromhex(data))
            rows.append((d["ch1"], d["ch2"]))
    rows = np.array(rows, float)
    peer = frf_peer.estimate([frf_peer.Experiment(rows[:, :1], rows[:, 1:])], P, BINS, detect=[2])

    def rel(a, b):
        return abs(a - b) / abs(b)
    nc = doc["noise_cov"]["re"][0][0]
    nc_peer = np.real(np.asarray(peer["noise_cov"]["re"]))[0][0]
    ym = doc["detection_lines"][0]["Y_mean"]
    ym_peer = peer["detection_lines"][0]["Y_mean"]
    g = complex(doc["lines"][0]["G"]["re"][0][0], doc["lines"][0]["G"]["im"][0][0])
    g_peer = complex(peer["lines"][0]["G"]["re"][0][0], peer["lines"][0]["G"]["im"][0][0])
    assert rel(g, g_peer) < 1e-12
    float_gap = (float(np.float32(0.001)) / 0.001) ** 2 - 1         # what the float32 step would give
    assert float_gap > 9e-8                                   # negative control: the test can see it
    assert rel(nc, nc_peer) < 1e-12, (nc, nc_peer, rel(nc, nc_peer))
    y, yp = complex(ym["re"][0][0], ym["im"][0][0]), complex(ym_peer["re"][0][0], ym_peer["im"][0][0])
    assert rel(y, yp) < 1e-12, (y, yp)
