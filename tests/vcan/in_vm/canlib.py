"""Helpers of the in-VM CAN tests: the simulator, the CLI, exact F and binomial laws."""
import json
import math
import os
import re
import select
import signal
import subprocess
import time
from pathlib import Path

import numpy as np

MSID = os.environ.get("MSID_BIN", "")
DEVSIM = os.environ.get("MSID_DEVSIM", "")
SRC = Path(__file__).resolve().parents[3]
DBC = SRC / "daq" / "can" / "msid.dbc"


def run(*args, timeout=180, user=None):
    cmd = [MSID] + [str(a) for a in args]
    if user is not None:
        cmd = ["setpriv", f"--reuid={user}", f"--regid={user}", "--clear-groups"] + cmd
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def run_ok(*args, timeout=180):
    r = run(*args, timeout=timeout)
    assert r.returncode == 0, f"msid {' '.join(map(str, args))} failed ({r.returncode}):\n{r.stderr}"
    return r


class Sim:
    """msid-devsim as a context manager; waits for its ready line, stops it with SIGTERM."""

    def __init__(self, tmp, *args, iface="vcan0"):
        self.tmp = Path(tmp)
        self.truth_path = self.tmp / "truth.json"
        self.report_path = self.tmp / "report.json"
        self.args = [DEVSIM, "--iface", iface, "--truth", str(self.truth_path), "--report", str(self.report_path),
                     "--idle-exit", "120"] + [str(a) for a in args]

    def __enter__(self):
        self.start(self.args)
        return self

    def start(self, argv, wait=20):
        """Runs argv and waits (`wait` s at most) for its ready line, which is returned."""
        self.p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        r, _, _ = select.select([self.p.stdout], [], [], wait)
        line = self.p.stdout.readline() if r else ""
        if "ready" not in line:
            self.p.kill()
            raise RuntimeError(f"msid-devsim did not start: {line!r} {self.p.stderr.read()}")
        return line

    def __exit__(self, *exc):
        self.stop(exc[0] is None)
        return False

    def stop(self, check):
        """SIGCONT (a test may have stopped it) and SIGTERM; with check, the exit status must be 0."""
        if self.p.poll() is None:
            self.p.send_signal(signal.SIGCONT)
            self.p.send_signal(signal.SIGTERM)
        try:
            rc = self.p.wait(20)
        except subprocess.TimeoutExpired:
            self.p.kill()
            raise
        self.stderr = self.p.stderr.read()
        if check:
            assert rc == 0, f"msid-devsim exit {rc}: {self.stderr}"

    def report(self):
        return json.loads(self.report_path.read_text())

    def truth(self):
        return json.loads(self.truth_path.read_text())


def interrupt_after(cmd, needle, timeout=120):
    """Run cmd, read its progress (stderr, one line per event without a terminal) until a line holds
    `needle`, then SIGINT: a stop after a given period, not after a sleep. Returns (the exited process,
    the lines seen, the rest of stderr)."""
    p = subprocess.Popen([str(a) for a in cmd], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = []
    for line in p.stderr:
        seen.append(line)
        if needle in line:
            p.send_signal(signal.SIGINT)
            break
    rest = p.stderr.read()
    p.wait(timeout)
    return p, seen, rest


def excite(tmp, period=256, lines="1:120", amp=0.1, periods=8, seed=11, inputs=2, experiments=2, name="design.json"):
    p = Path(tmp) / name
    run_ok("excite", "--period", period, "--lines", lines, "--inputs", inputs, "--experiments", experiments,
           "--periods", periods, "--seed", seed, "--amplitudes", amp, "-o", p)
    return p


def measure(tmp, design, *extra, iface="vcan0", out="frf.json", skip=1, ok=True):
    o = Path(tmp) / out
    r = run("can", "measure", "--iface", iface, "--design", design, "--skip-periods", skip, "--rcvbuf", 4 << 20,
            *extra, "-o", o)
    if ok:
        assert r.returncode == 0, f"msid can measure failed ({r.returncode}):\n{r.stderr}"
        r.doc = json.loads(o.read_text())
    return r


def sim_measure(design, tmp, *sim_args, seed=4, rate=None):
    """One `msid can measure` against a fresh simulator with these options: (its result, the
    simulator's report, its truth). rate: the device's sample rate in Hz (`--rate`; None: unpaced)."""
    with Sim(tmp, "--seed", seed, *sim_args) as sim:
        r = measure(tmp, design, *(("--rate", rate) if rate else ()))
    return r, sim.report(), sim.truth()


def cplx(o):
    return np.asarray(o["re"], float) + 1j * np.asarray(o["im"], float)


# ---- exact laws (no scipy on the test machines) ---------------------------------

def _betacf(a, b, x):
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 400):
        m2 = 2 * m
        aa = m * (b - m) * x / ((a + m2 - 1) * (a + m2))
        d = 1.0 + aa * d; d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c if abs(c) > tiny else 1.0 + aa / tiny
        h *= d * c
        aa = -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1))
        d = 1.0 + aa * d; d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c if abs(c) > tiny else 1.0 + aa / tiny
        de = d * c
        h *= de
        if abs(de - 1.0) < 1e-15:
            break
    return h


def betai(a, b, x):
    """Regularized incomplete beta I_x(a, b)."""
    if x <= 0:
        return 0.0
    if x >= 1:
        return 1.0
    lbt = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    if x < (a + 1) / (a + b + 2):
        return math.exp(lbt) * _betacf(a, b, x) / a
    return 1.0 - math.exp(lbt) * _betacf(b, a, 1.0 - x) / b


def f_sf(x, d1, d2):
    """P(F(d1, d2) > x)."""
    return betai(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * x))


def binom_interval(n, p, alpha):
    """[lo, hi] with P(X < lo) <= alpha/2 and P(X > hi) <= alpha/2 for X ~ Bin(n, p)."""
    pmf = [math.comb(n, k) * p ** k * (1 - p) ** (n - k) for k in range(n + 1)]
    lo, acc = 0, 0.0
    while acc + pmf[lo] <= alpha / 2:
        acc += pmf[lo]
        lo += 1
    hi, acc = n, 0.0
    while acc + pmf[hi] <= alpha / 2:
        acc += pmf[hi]
        hi -= 1
    return lo, hi


def row_pvalues(doc, truth, scale=1.0):
    """p-value of each output row of each line against the true FRF: with the known-input
    covariance block V of the row and its dof n, Q/nu = e V^-1 e^H / nu ~ F(2 nu, 2 n)
    (docs/statistics.md). Rows of one line and the lines are independent here (independent
    white output noise), so the count inside the 95% regions is Bin(N, 0.95)."""
    nu, ny = doc["n_inputs"], doc["n_outputs"]
    tl = {l["bin"]: cplx(l["G"]) * scale for l in truth["lines"]}
    out = []
    for line in doc["lines"]:
        G, G0 = cplx(line["G"]), tl[line["bin"]]
        V = cplx(line["cov_known_input"])
        n = line["dof_known_input"]
        for i in range(ny):
            idx = [i + ny * j for j in range(nu)]
            e = (G[i] - G0[i]).reshape(1, nu)
            Q = float(np.real(e.conj() @ np.linalg.solve(V[np.ix_(idx, idx)], e.T))[0, 0])
            out.append(f_sf(Q / nu, 2 * nu, 2 * n))
    return np.array(out)


def check_coverage(doc, truth, alpha=1e-3, min_fraction=0.90, scale=1.0):
    """Fraction of rows inside their 95% region: inside the two-sided Bin(N, 0.95) interval at
    level alpha (not hand-tuned: it follows from N), and at least `min_fraction`."""
    p = row_pvalues(doc, truth, scale)
    inside = int(np.sum(p > 0.05))
    lo, hi = binom_interval(len(p), 0.95, alpha)
    assert lo <= inside <= hi, f"{inside}/{len(p)} rows inside their 95% region; Bin({len(p)}, 0.95) gives [{lo}, {hi}]"
    assert inside >= min_fraction * len(p), f"{inside}/{len(p)} rows inside their 95% region (< {min_fraction:.0%})"
    return inside, len(p)


def lines_equal(a, b):
    """The FRF parts of two msid-frf/1 documents are identical (bit for bit after JSON round trip)."""
    da, db = dict(a), dict(b)
    da.pop("acquisition", None)
    db.pop("acquisition", None)
    return da == db


PROGRESS = re.compile(r"^msid (measure|can|modbus): experiment \d+/\d+[: ]")


def fails(tmp, r, code, *needles, absent=()):
    """One message on stderr besides the progress lines of `msid can|modbus measure` (one per event
    without a terminal, docs/measure.md), exit status `code`, and neither frf.json, a temporary nor
    any of the files named in `absent` left in `tmp`."""
    tmp = Path(tmp)
    assert r.returncode == code, r.stderr
    lines = [l for l in r.stderr.splitlines() if l.strip() and not PROGRESS.match(l)]
    assert len(lines) == 1, r.stderr
    for n in needles:
        assert n in r.stderr, r.stderr
    assert not (tmp / "frf.json").exists() and not list(tmp.glob("*.tmp.*"))
    for name in absent:
        assert not (tmp / name).exists(), name
