"""The CANopen drive of the in-VM measurement tests (msid measure --device canopen://vcan0?node=5 --map): its
descriptions, msid-devsim's node as a context manager with its URI, the node's state read by the canopen
package (not by msid), a SYNC listener, and the exact FRF msid must find (the node's plant, docs/devices.md)."""
import contextlib
import json
import shutil
import sys
import time
from pathlib import Path

import numpy as np

import canlib

sys.path.insert(0, str(canlib.SRC / "tests" / "modbus"))
import maplib  # noqa: E402  (one measurement, the element p-values, the binomial check)

EDS = Path(__file__).resolve().parent / "data" / "drive402.eds"
NODE = 5
RATE, P, LINES, BINS = 50, 64, "1:2:31", list(range(1, 32, 2))

PRESET = """format = "msid-device/1"
transport = "canopen"
name = "simulated CiA 402 drive"
preset = "cst"
velocity_scale = 0.001
velocity_unit = "rad/s"
position_scale = 1e-6
position_unit = "rad"
{top}
[[drive]]
safe = {safe}
operating_point = {op}
min = -0.3
max = 0.3
max_step = 0.5
amplitude = 0.2
"""

EXPLICIT = """format = "msid-device/1"
transport = "canopen"
mode = "cst"
rated_torque = 1.0
{top}
[[drive]]
name = "Target torque"
unit = "N m"
object = "{drive}"
type = "int16"
scale = 0.001
safe = 0.0
min = -0.3
max = 0.3

[[measure]]
name = "Torque demand"
role = "input"
object = "0x6074:00"
type = "int16"
scale = 0.001

[[measure]]
name = "Velocity"
unit = "rad/s"
role = "output"
object = "{output}"
type = "int32"
scale = 0.001
"""


def preset(tmp, *, safe=0.0, op=0.0, top="", name="drive.toml"):
    p = Path(tmp) / name
    p.write_text(PRESET.format(safe=safe, op=op, top=top))
    return p


def explicit(tmp, *, drive="0x6071:00", output="0x606C:00", top="", name="explicit.toml"):
    p = Path(tmp) / name
    p.write_text(EXPLICIT.format(drive=drive, output=output, top=top))
    return p


def with_eds(tmp):
    """The description key naming the node's EDS, relative to the description's folder (a copy there)."""
    shutil.copy(EDS, Path(tmp) / "drive402.eds")
    return 'eds = "drive402.eds"\n'


class Drive(canlib.Sim):
    """msid-devsim --canopen 5 on vcan0; `uri` for msid measure, `state()` read by the canopen package."""

    def __init__(self, tmp, *args, node=NODE):
        super().__init__(tmp, "--canopen", NODE, *args)
        self.uri = f"canopen://vcan0?node={node}&timeout=1000"

    def state(self):
        """The node's own statusword 0x6041, target torque 0x6071 and NMT view, by an independent master."""
        with remote_node() as n:
            return {"statusword": n.sdo[0x6041].raw, "target_torque": n.sdo[0x6071].raw,
                    "tpdo1": [n.sdo[0x1A00][i].raw for i in range(1, n.sdo[0x1A00][0].raw + 1)],
                    "rpdo1": [n.sdo[0x1600][i].raw for i in range(1, n.sdo[0x1600][0].raw + 1)]}

    def write(self, index, value):
        """An entry written by the independent master's SDO; the node's value read back."""
        with remote_node() as n:
            n.sdo[index].raw = value
            return n.sdo[index].raw


@contextlib.contextmanager
def package_node(kind="RemoteNode", node=NODE, eds=EDS):
    """A node of the canopen package on vcan0 (RemoteNode: its master's view of the node; LocalNode: a node it
    serves itself), on a network of its own, disconnected after."""
    import canopen
    net = canopen.Network()
    net.connect(interface="socketcan", channel="vcan0")
    try:
        n = getattr(canopen, kind)(node, str(eds))
        net.add_node(n)
        if kind == "RemoteNode":
            n.sdo.RESPONSE_TIMEOUT = 2.0
        yield n
    finally:
        net.disconnect()


def remote_node():
    """The canopen package's RemoteNode of the node on vcan0 (its own network, disconnected after)."""
    return package_node("RemoteNode")


def syncs_within(seconds):
    """SYNC frames (COB-ID 0x080) a python-can listener sees on vcan0 within `seconds`."""
    import can
    bus = can.Bus(interface="socketcan", channel="vcan0",
                  can_filters=[{"can_id": 0x080, "can_mask": 0x7FF, "extended": False}])
    try:
        n, end = 0, time.monotonic() + seconds
        while time.monotonic() < end:
            m = bus.recv(timeout=max(0.0, end - time.monotonic()))
            if m is not None and m.arbitration_id == 0x080:
                n += 1
        return n
    finally:
        bus.shutdown()


# CiA 402 states by the statusword's bits 0..3, 5, 6 (CiA 402 table 30)
def state_name(sw):
    x = sw & 0x6F
    for mask, val, name in ((0x4F, 0x40, "switch on disabled"), (0x6F, 0x21, "ready to switch on"),
                            (0x6F, 0x23, "switched on"), (0x6F, 0x27, "operation enabled"),
                            (0x6F, 0x07, "quick stop active"), (0x4F, 0x0F, "fault reaction active"),
                            (0x4F, 0x08, "fault")):
        if x & mask == val:
            return name
    return "not ready to switch on"


def plant_ab(ts=1e-3, jm=1e-4, jl=2e-4, k=50.0, dmp=2e-3, bm=1e-4, bl=1e-4):
    """A, B of the node's plant (docs/devices.md): the zero-order hold of the two-mass model over the SYNC
    period ts, by scipy's matrix exponential of the augmented system (independent of the node's C)."""
    import scipy.linalg
    f = np.array([[0, 1, 0, 0], [-k / jm, -(dmp + bm) / jm, k / jm, dmp / jm], [0, 0, 0, 1],
                  [k / jl, dmp / jl, -k / jl, -(dmp + bl) / jl]])
    m = np.zeros((5, 5))
    m[:4, :4] = f
    m[:4, 4] = [0, 1 / jm, 0, 0]
    e = scipy.linalg.expm(m * ts)
    return e[:4, :4], e[:4, 4]


def loop_parts(rate, bins, period):
    """The node's velocity loop in CSV at the bins of a period of `period` samples (docs/devices.md, "The simulated
    drive"), as arrays over the bins: z = e^(j 2 pi bin / period), the plant Gp = e2' (zI - A)^-1 B from the
    demand tau[k] to the velocity w[k+1] it leads to, and the drive's PI C(z) = kp + ki T z / (z - 1) at the SYNC
    period T = 1 / rate (wc = min(2 pi 20, 0.2 / T), kp = J wc, ki = J wc^2 / 4, J = 3e-4)."""
    T = 1.0 / rate
    A, b = plant_ab(T)
    J = 3e-4
    wc = min(2 * np.pi * 20.0, 0.2 / T)
    kp, ki = J * wc, J * wc * wc / 4.0
    z = np.exp(2j * np.pi * np.asarray(bins) / period)
    gp = np.array([np.linalg.solve(zk * np.eye(4) - A, b)[1] for zk in z])
    return z, gp, kp + ki * T * z / (z - 1)


def velocity_truth(rate=RATE, bins=BINS):
    """The FRF msid must find from the torque demand to the velocity, both from the TPDO of one SYNC: the node's
    TPDO of SYNC k carries the demand tau[k-1] held over the period before it and omega[k] (docs/devices.md), so
    the pair is H(z) = z e2' (zI - A)^-1 B = e2' A (zI - A)^-1 B + e2' B (rad/s per N m)."""
    A, b = plant_ab(1.0 / rate)
    B = b.reshape(4, 1)
    e2 = np.array([[0.0, 1.0, 0.0, 0.0]])
    return maplib.dt_frf(A, B, e2 @ A, e2 @ B, bins, P)


def row_pvalues(doc, truth, output):
    """p-value of each line's element (output named `output`, the one input) against truth [L, 1, 1]:
    |G - G0|^2 / v ~ F(2, 2 n) (docs/statistics.md)."""
    names = doc["output_names"]
    i = names.index(output)
    ny = len(names)
    out = []
    for line, g0 in zip(doc["lines"], truth):
        G = canlib.cplx(line["G"])
        V = canlib.cplx(line["cov"])
        q = abs(G[i, 0] - g0[0, 0]) ** 2 / V[i, i].real   # a = j * ny + i with j = 0
        out.append(canlib.f_sf(q, 2, 2 * line["dof"]))
    assert len(out) == len(truth) == len(doc["lines"]) and ny >= 1
    return np.array(out)


def measure(tmp, sim, desc, *extra, ok=True, slower=False, **kw):
    """One msid measure --map over canopen:// at this file's design and rate (maplib.measure, whose runs refused
    for too few usable periods are made again). A run whose round-trip probe met a node that did not answer within
    a second (msid-devsim stalled by a loaded VM: the probe's exchanges must all succeed) is made again too, up to
    3 times; any other failure is not. With `slower`, runs still refused for too few usable periods are made once
    more at half the rate (the node samples on SYNC, so the same node serves; the caller takes its truth at the
    result's fs_hz): a VM starved by its host's other work for more than a tick now and then loses fewer."""
    for k, v in (("period", P), ("lines", LINES), ("periods", 6), ("skip", 2), ("rate", RATE), ("timeout", 600)):
        kw.setdefault(k, v)
    rate = kw.pop("rate")

    def attempt(k, hz, last):
        for _ in range(3):
            r = maplib.measure(tmp, sim, desc, *extra, ok=False, attempts=3 if ok and k == 0 else 1, rate=hz, **kw)
            if r.returncode == 0 or "one tick's exchange failed" not in r.stderr:
                return r
        return r
    r = maplib.until_usable([rate, rate / 2] if slower else [rate], attempt)
    if ok:
        assert r.returncode == 0, f"msid measure --map failed ({r.returncode}):\n{r.stderr}"
    return r
