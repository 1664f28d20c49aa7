"""Helpers of the described-device tests (msid measure --map, msid device check): descriptions written from
templates, a DT plant file and its exact FRF, msid-devsim --map as a context manager (under SCHED_FIFO where the
machine permits it: a real device is its own hardware, and an unprivileged simulator on a loaded 2-core machine
answers late), the device's own register state read back over Modbus, and one measurement."""
import json
import os
import re
import shutil
import signal
import subprocess
from pathlib import Path

import numpy as np

import mblib
from mblib import DEVSIM, canlib, run

# A two-mass drive as seen from its torque input at the device's cycle rate: a lightly damped mode at 0.06
# cycles per sample (|z| = 0.985, zeta about 4 %) and a better damped one at 0.19, no feedthrough.
def siso_plant():
    r1, t1, r2, t2 = 0.985, 2 * np.pi * 0.06, 0.92, 2 * np.pi * 0.19
    A = np.array([[r1 * np.cos(t1), -r1 * np.sin(t1), 0, 0], [r1 * np.sin(t1), r1 * np.cos(t1), 0, 0],
                  [0, 0, r2 * np.cos(t2), -r2 * np.sin(t2)], [0, 0, r2 * np.sin(t2), r2 * np.cos(t2)]])
    B = np.array([[0.1], [0.05], [0.2], [0.0]])
    C = np.array([[0.5, 0.3, 0.4, 0.2]])
    D = np.zeros((1, 1))
    return A, B, C, D


def write_plant(path, A, B, C, D):
    n, nu, ny = A.shape[0], B.shape[1], C.shape[0]
    def row(M):
        return " ".join(repr(float(x)) for x in np.asarray(M).ravel())
    Path(path).write_text(f"type dt states {n} inputs {nu} outputs {ny}\nA {row(A)}\nB {row(B)}\nC {row(C)}\nD {row(D)}\n")
    return path


def dt_frf(A, B, C, D, bins, P):
    """G(z) = C (zI - A)^-1 B + D at z = exp(j 2 pi b / P) for each bin: [L, ny, nu]."""
    n = A.shape[0]
    return np.array([C @ np.linalg.solve(np.exp(2j * np.pi * b / P) * np.eye(n) - A, B) + D for b in bins])


def held_frf(A, B, C, D, bins, P, M):
    """The FRF a host ticking once per M device cycles sees from the value it writes to the value it reads
    next (docs/devices.md): X_{n+1} = A^M X_n + G_M u_n, y_read[n+1] = C A^(M-1) X_n + (C G_(M-1) + D) u_n,
    G_k = sum_{i<k} A^i B; the read of tick n + 1 answers the write of tick n, one tick later."""
    n = A.shape[0]
    AM = np.linalg.matrix_power(A, M)
    G = lambda k: sum((np.linalg.matrix_power(A, i) @ B for i in range(k)), np.zeros_like(B))
    out = []
    for b in bins:
        z = np.exp(2j * np.pi * b / P)
        H = C @ np.linalg.matrix_power(A, M - 1) @ np.linalg.solve(z * np.eye(n) - AM, G(M)) + C @ G(M - 1) + D
        out.append(H / z)
    return np.array(out)


def element_pvalues(doc, truth):
    """p-value of each element of each line: |G - G0|^2 / v ~ F(2, 2 n) with v = cov[a][a], n = dof (the
    errors-in-variables covariance and its dof: docs/statistics.md)."""
    tl = {l["bin"]: canlib.cplx(l["G"]) for l in truth["lines"]}
    out = []
    for line in doc["lines"]:
        G, G0 = canlib.cplx(line["G"]), tl[line["bin"]]
        V = canlib.cplx(line["cov"])
        ny, nu = G.shape
        for i in range(ny):
            for j in range(nu):
                a = j * ny + i
                q = abs(G[i, j] - G0[i, j]) ** 2 / V[a, a].real
                out.append(canlib.f_sf(q, 2, 2 * line["dof"]))
    return np.array(out)


def covered(pvals, alpha=1e-3):
    inside = int(np.sum(pvals > 0.05))
    lo, hi = canlib.binom_interval(len(pvals), 0.95, alpha)
    assert lo <= inside <= hi, f"{inside}/{len(pvals)} inside their 95% region; Bin({len(pvals)}, 0.95) gives [{lo}, {hi}]"
    return inside


def truth_doc(G, bins):
    return {"lines": [{"bin": int(b), "G": {"re": np.real(g).tolist(), "im": np.imag(g).tolist()}}
                      for b, g in zip(bins, G)]}


DRIVE = """
[[drive]]
name = "Torque command"
unit = "N m"
register = "holding:100"
type = "float32"
word_order = "ABCD"
min = {min}
max = {max}
safe = {safe}
{extra_drive}
"""

READBACK = """
[[measure]]
name = "Torque"
unit = "N m"
role = "input"
register = "input:0"
type = "float32"
word_order = "ABCD"
"""

OUTPUT = """
[[measure]]
name = "Speed"
unit = "rad/s"
role = "output"
register = "input:2"
type = "int16"
scale = 0.0005
"""

COUNTER = """
[[measure]]
name = "Cycle"
role = "counter"
register = "input:3"
type = "uint16"
"""


def description(path, *, readback=True, counter=True, clock="host", safe=0.0, lo=-2.0, hi=2.0, extra_top="",
                extra_drive="", cycle_hz=None):
    top = 'format = "msid-device/1"\ntransport = "modbus"\nunit = 1\n'
    if clock != "host":
        top += f'clock = "{clock}"\n'
    if cycle_hz:
        top += f"cycle_hz = {cycle_hz}\n"
    text = top + extra_top + DRIVE.format(min=lo, max=hi, safe=safe, extra_drive=extra_drive)
    if readback:
        text += READBACK
    text += OUTPUT
    if counter:
        text += COUNTER
    Path(path).write_text(text)
    return str(path)


def realtime_prefix(prio=20):
    """chrt -f PRIO where SCHED_FIFO is permitted (root), else nothing."""
    if shutil.which("chrt") and subprocess.run(["chrt", "-f", str(prio), "true"], capture_output=True).returncode == 0:
        return ["chrt", "-f", str(prio)]
    return []


def make_realtime(pid, prio=20):
    """A running process under SCHED_FIFO where the machine permits it: socat, the serial cable between msid and
    the device, relays every byte and would otherwise queue behind the machine's other work."""
    if realtime_prefix(prio):
        subprocess.run(["chrt", "-f", "-p", str(prio), str(pid)], check=True, capture_output=True)


def validate_frf(doc):
    """The FRF document against docs/schemas/msid-frf-1.schema.json (its acquisition block included)."""
    import jsonschema
    schema = json.loads((mblib.SRC / "docs" / "schemas" / "msid-frf-1.schema.json").read_text())
    errs = list(jsonschema.Draft202012Validator(schema).iter_errors(doc))
    assert not errs, [f"{list(e.absolute_path)}: {e.message}" for e in errs[:3]]


class MapSim(mblib.ModbusSim):
    """msid-devsim --map DESC --modbus-tcp 127.0.0.1:0 (or RTU on a socat pty pair); .uri is the device URI."""

    def __init__(self, tmp, desc, *args, rtu=False, baud=115200):
        self.tmp = Path(tmp)
        self.desc = desc
        self.rtu = rtu
        self.baud = baud
        self.report_path = self.tmp / f"report-{os.getpid()}-{id(self)}.json"
        self.args = [str(a) for a in args]
        if "--cycle-hz" not in self.args:   # a device that cycles at the tests' tick rate
            self.args += ["--cycle-hz", "200"]

    def __enter__(self):
        if self.rtu:
            self.pty = mblib.PtyPair().__enter__()
            make_realtime(self.pty.p.pid)
            where = ["--modbus-rtu", self.pty.device, "--baud", str(self.baud)]
        else:
            where = ["--modbus-tcp", "127.0.0.1:0"]
        line = self.start(realtime_prefix() + [DEVSIM, "--map", self.desc, *where, "--report", str(self.report_path),
                                               "--idle-exit", "120", *self.args])
        if self.rtu:
            self.uri = f"modbus-rtu://{self.pty.host}?baud={self.baud}"
        else:
            self.port = int(re.search(r"127\.0\.0\.1:(\d+)", line).group(1))
            self.uri = f"modbus-tcp://127.0.0.1:{self.port}"
        return self


    def holding(self, addr, count):
        """The device's own holding registers, read over Modbus TCP by pymodbus (not by msid)."""
        from pymodbus.client import ModbusTcpClient
        c = ModbusTcpClient("127.0.0.1", port=self.port, timeout=5)
        assert c.connect()
        try:
            r = c.read_holding_registers(addr, count=count, device_id=1)
            assert not r.isError(), r
            return r.registers
        finally:
            c.close()


def float32_of(regs):
    import struct
    return struct.unpack(">f", struct.pack(">HH", *regs))[0]


def interrupt_after_periods(cmd, after, timeout=120):
    """Run cmd (msid measure), SIGINT after `after` progress lines of acquired periods (a stop after a given
    period, not after a sleep). Returns (the exit status, stderr)."""
    p = subprocess.Popen([str(a) for a in cmd], stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    seen = 0
    for line in p.stderr:
        if "periods acquired" in line:
            seen += 1
            if seen >= after:
                p.send_signal(signal.SIGINT)
                break
    _, err = p.communicate(timeout=timeout)
    return p.returncode, err


def rated(desc, hz, cycles_per_tick=1, where=None):
    """The description `desc` (a file) for a run at `hz` ticks a second: a copy in `where` (desc's folder unless
    told) whose cycle_hz, where it has one, is cycles_per_tick * hz. A device whose cycles keep their ratio to the
    ticks has the same FRF per cycle at every rate."""
    src = Path(desc)
    text = re.sub(r"(?m)^cycle_hz = .*$", f"cycle_hz = {cycles_per_tick * hz:g}", src.read_text())
    out = Path(where or src.parent) / f"{src.stem}-{hz:g}hz{src.suffix}"
    out.write_text(text)
    return str(out)


def halving_rates(rate, floor):
    """rate, rate / 2, ... down to no less than floor: the rates a run refused for lost samples is made again at.
    A machine that loses samples at one rate (its scheduler or a neighbour stalled the host or the device for
    more than a tick now and then) loses fewer at half of it, and a test of what msid does with the samples must
    not depend on how idle the machine is."""
    out = [rate]
    while out[-1] / 2 >= floor:
        out.append(out[-1] // 2 if out[-1] % 2 == 0 else out[-1] / 2)
    return out


def until_usable(rates, attempt, refused=("usable period(s)",)):
    """attempt(k, hz, last) at each of `rates` in turn (halving_rates), each on a device of its own, until a run is
    not refused for lost samples: its result (returncode, stderr), the last attempt's when every rate was refused.
    `refused` names the refusals that call for a slower run; any other failure ends the attempts. `last` tells the
    final attempt, whose failure is the caller's to report. The one place the tests meet a machine that loses
    samples: the runs they keep are counted and checked as any other."""
    for k, hz in enumerate(rates):
        r = attempt(k, hz, k == len(rates) - 1)
        if r.returncode == 0 or not any(w in r.stderr for w in refused):
            return r
    return r


def measure(tmp, sim, desc, *extra, period=64, lines="1:2:31", periods=8, skip=1, rate=200, seed=1, ok=True,
            out="out", timeout=300, attempts=None, retry_on=("usable period(s)", "do not excite line")):
    """One msid measure --map. With attempts > 1 a run that msid refuses for too few usable periods (a loaded
    machine lost a sample in most of them: counted, never a wrong result) is made again, and so is one refused
    for a line whose read-back input varied from period to period (a link error or a late exchange on a loaded
    machine left one period's input apart); any other failure is not. `retry_on` names the refusals made again.
    A run expected to succeed gets 3 attempts unless told; one expected to fail gets 1 (its device may be the
    fault that left the periods unusable, and a second run would meet a device in another state)."""
    if attempts is None:
        attempts = 3 if ok else 1
    o = Path(tmp) / out
    for k in range(attempts):
        r = run("measure", "--device", sim.uri, "--map", desc, "--period", period, "--lines", lines, "--periods",
                periods, "--skip-periods", skip, "--rate", rate, "--seed", seed, "--no-plots", *extra, "-o", o,
                timeout=timeout)
        if r.returncode == 0 or not any(w in r.stderr for w in retry_on):
            break
    if ok:
        assert r.returncode == 0, f"msid measure --map failed ({r.returncode}):\n{r.stderr}"
    if r.returncode == 0:
        r.doc = checked_doc(o, periods, period)
    return r


def checked_doc(out, periods, period):
    """The frf.json in `out`, once every sample of its measured periods is found in the estimate or counted as
    lost, whatever lost it."""
    doc = json.loads((Path(out) / "frf.json").read_text())
    a = doc["acquisition"]
    per_experiment = int(periods) * int(period)
    total = a["samples"] + a["samples_lost"]
    assert total >= per_experiment and total % per_experiment == 0, (a["samples"], a["samples_lost"])
    return doc
