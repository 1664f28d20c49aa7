#!/usr/bin/env python3
"""An independent CAN node described by msid-device/1 and a DBC, written with python-can and cantools.

It reads the description with Python's tomllib following docs/devices.md only, and the DBC with cantools (it
imports nothing of msid: the frames are encoded and decoded by cantools, not by msid's DBC codec). It runs a
discrete-time plant on its own cycle:

    between cycles it takes every command frame (cantools decodes it); the latest value of each drive channel
    is the setpoint applied from the next cycle on; at cycle k (device time k / cycle_hz) it publishes
    y_k = C x_k + D u_k (+ noise) on the output channels, the applied input (+ noise) on the input channels and
    its cycle count (wrapping at the signal's range) on a counter channel, sends each status message once
    (cantools encodes it), then steps x_{k+1} = A x_k + B u_k.

A channel's value is the DBC's physical value times `scale` plus `offset`. The node's clock runs
(1 + ppm 1e-6) times the host's CLOCK_MONOTONIC. The plant file is msid-devsim's format (map_peer_files.py).

usage: dbc_peer.py --map DESC --iface IF --plant FILE [--cycle-hz F] [--clock-ppm X] [--seed N]
                   [--noise-y S] [--noise-u S] [--state FILE] [--idle-exit S]
Ready line on stdout: "dbc_peer: ready on can IF ...". SIGTERM or SIGINT: writes --state (JSON: the setpoints
the node applied last, the commands it took, those that left a drive channel off its safe value since the last
safe one) and exits 0. A bad description or option: one message on stderr, exit 2."""
import argparse
import json
import math
import signal
import sys
import time
import tomllib
from pathlib import Path

import can
import cantools
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "modbus"))
from map_peer_files import Refused, read_plant  # noqa: E402


class Chan:
    def __init__(self, t, kind):
        self.name, self.kind = t["name"], kind
        self.role = t.get("role")
        self.message, self.signal = t["message"], t["signal"]
        self.scale, self.offset = float(t.get("scale", 1.0)), float(t.get("offset", 0.0))
        self.safe = float(t["safe"]) if kind == "drive" else None


def read_description(path):
    d = tomllib.loads(Path(path).read_text())
    if d.get("format") != "msid-device/1" or d.get("transport") != "can":
        raise Refused(f"{path}: not an msid-device/1 CAN description")
    dbc = Path(d["dbc"])
    if not dbc.is_absolute():
        dbc = Path(path).resolve().parent / dbc
    drive = [Chan(t, "drive") for t in d.get("drive", [])]
    meas = [Chan(t, "measure") for t in d.get("measure", [])]
    return drive, meas, cantools.database.load_file(str(dbc))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--map", required=True)
    ap.add_argument("--iface", required=True)
    ap.add_argument("--plant", required=True)
    ap.add_argument("--cycle-hz", type=float, default=100.0)
    ap.add_argument("--clock-ppm", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--noise-y", type=float, default=0.0)
    ap.add_argument("--noise-u", type=float, default=0.0)
    ap.add_argument("--state")
    ap.add_argument("--idle-exit", type=float, default=120.0)
    a = ap.parse_args()
    try:
        drive, meas, db = read_description(a.map)
        A, B, C, D = read_plant(a.plant)
    except (Refused, KeyError, OSError) as e:
        print(f"dbc_peer: error: {e}", file=sys.stderr)
        sys.exit(2)
    rng = np.random.default_rng(a.seed)
    cmd_ids = {db.get_message_by_name(c.message).frame_id for c in drive}
    status_msgs = []
    for c in meas:
        m = db.get_message_by_name(c.message)
        if m not in status_msgs:
            status_msgs.append(m)
    outputs = [c for c in meas if c.role == "output"]
    inputs = [c for c in meas if c.role == "input"]
    u = np.array([c.safe for c in drive])
    x = np.zeros(A.shape[0])
    st = {"commands": 0, "commands_not_safe": 0, "status_cycles": 0}
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    bus = can.Bus(interface="socketcan", channel=a.iface,
                  can_filters=[{"can_id": i, "can_mask": 0x7FF} for i in sorted(cmd_ids)])
    print(f"dbc_peer: ready on can {a.iface} (cycle {a.cycle_hz:g} Hz, clock {a.clock_ppm:+g} ppm)", flush=True)
    t0 = time.monotonic()
    last_cmd = t0
    k = 0
    rate = a.cycle_hz * (1 + 1e-6 * a.clock_ppm)
    pending = u.copy()
    while not stop:
        due = t0 + k / rate
        while not stop:
            w = due - time.monotonic()
            if w <= 0:
                break
            f = bus.recv(timeout=w)
            if f is None or f.is_error_frame or f.arbitration_id not in cmd_ids:
                continue
            vals = db.decode_message(f.arbitration_id, f.data, decode_choices=False)
            for i, c in enumerate(drive):
                if db.get_message_by_name(c.message).frame_id == f.arbitration_id and c.signal in vals:
                    pending[i] = vals[c.signal] * c.scale + c.offset
            st["commands"] += 1
            off = any(abs(pending[i] - c.safe) > 1e-6 * (1 + abs(c.safe)) +
                      0.5 * abs(db.get_message_by_name(c.message).get_signal_by_name(c.signal).scale * c.scale)
                      for i, c in enumerate(drive))
            st["commands_not_safe"] = st["commands_not_safe"] + 1 if off else 0
            last_cmd = time.monotonic()
        if stop:
            break
        # a node woken late runs the cycles it slept through (its counter shows them) and sends the last one's
        # frames, as a timer-driven node that missed its interrupts would; no burst of stale frames
        behind = int(math.floor((time.monotonic() - t0) * rate)) - k
        for _ in range(max(0, behind)):
            x = A @ x + B @ pending
            k += 1
        u = pending.copy()
        y = C @ x + D @ u
        values = {}
        for j, c in enumerate(outputs):
            values[c.name] = y[j] + a.noise_y * rng.standard_normal()
        for i, c in enumerate(inputs):
            values[c.name] = u[i] + a.noise_u * rng.standard_normal()
        for m in status_msgs:
            sig = {}
            for c in meas:
                if c.message != m.name:
                    continue
                s = m.get_signal_by_name(c.signal)
                if c.role == "counter":
                    sig[c.signal] = k % (1 << s.length)
                else:
                    v = (values.get(c.name, u[0]) - c.offset) / c.scale
                    lo, hi = s.minimum, s.maximum
                    if lo is not None and hi is not None and lo < hi:
                        v = min(max(v, lo), hi)
                    sig[c.signal] = v
            for s in m.signals:
                sig.setdefault(s.name, 0)
            data = m.encode(sig, strict=False, scaling=True)
            bus.send(can.Message(arbitration_id=m.frame_id, data=data, is_extended_id=m.is_extended_frame))
        st["status_cycles"] += 1
        x = A @ x + B @ u
        k += 1
        if time.monotonic() - last_cmd > a.idle_exit:
            break
    if a.state:
        st["setpoints"] = {c.name: float(u_i) for c, u_i in zip(drive, pending)}
        st["cycles"] = k
        Path(a.state).write_text(json.dumps(st))
    bus.shutdown()


if __name__ == "__main__":
    main()
