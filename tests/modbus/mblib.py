"""Helpers of the Modbus tests: the simulator over TCP or RTU (socat pty pair), the CLI,
and the exact F / binomial coverage check shared with the CAN tests (tests/vcan/in_vm/canlib.py)."""
import json
import os
import re
import select
import subprocess
import sys
import time
from pathlib import Path

SRC = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(SRC / "tests" / "vcan" / "in_vm"))
import canlib  # noqa: E402  (coverage check, F law, binomial interval, lines_equal)
from canlib import check_coverage, cplx, fails, interrupt_after, lines_equal, run, run_ok  # noqa: E402,F401

MSID = os.environ.get("MSID_BIN", "")
DEVSIM = os.environ.get("MSID_DEVSIM", "")
assert MSID and DEVSIM, "MSID_BIN and MSID_DEVSIM must name the built binaries (ctest sets them)"
canlib.MSID = MSID


class PtyPair:
    """socat -d -d pty,raw,echo=0 pty,raw,echo=0: two linked pseudo-terminals (a null-modem cable)."""

    def __enter__(self):
        self.p = subprocess.Popen(["socat", "-d", "-d", "pty,raw,echo=0", "pty,raw,echo=0"],
                                  stderr=subprocess.PIPE, bufsize=0)
        self.paths, text = [], b""
        t0 = time.monotonic()
        while len(self.paths) < 2 and time.monotonic() - t0 < 10:
            r, _, _ = select.select([self.p.stderr], [], [], 1)
            if r:
                text += os.read(self.p.stderr.fileno(), 4096)
                self.paths = re.findall(r"PTY is (\S+)", text.decode(errors="replace"))
        if len(self.paths) < 2:
            self.p.kill()
            raise RuntimeError("socat did not report two ptys")
        self.device, self.host = self.paths
        return self

    def __exit__(self, *exc):
        self.p.terminate()
        self.p.wait(10)
        return False


class ModbusSim(canlib.Sim):
    """An msid-devsim on Modbus TCP or on an RTU pty pair (`rtu`, `pty`): its exit is checked and the pair closed."""

    expect_exit = 0   # the simulator's exit status a test expects (9: --die-after)

    def __exit__(self, *exc):
        try:
            self.stop(exc[0] is None and self.expect_exit == 0)
            if exc[0] is None and self.expect_exit:
                assert self.p.returncode == self.expect_exit, self.p.returncode
        finally:
            if self.rtu:
                self.pty.__exit__(None, None, None)
        return False


class Sim(ModbusSim):
    """msid-devsim --modbus-tcp 127.0.0.1:0 (a free port) or --modbus-rtu <pty>; `link` gives the
    matching msid options. Stops it with SIGTERM."""

    def __init__(self, tmp, *args, rtu=False):
        self.tmp = Path(tmp)
        self.rtu = rtu
        self.truth_path = self.tmp / "truth.json"
        self.report_path = self.tmp / "report.json"
        self.args = [str(a) for a in args]

    def __enter__(self):
        if self.rtu:
            self.pty = PtyPair().__enter__()
            where = ["--modbus-rtu", self.pty.device, "--baud", "115200"]
        else:
            where = ["--modbus-tcp", "127.0.0.1:0"]
        line = self.start([DEVSIM, *where, "--truth", str(self.truth_path), "--report",
                           str(self.report_path), "--idle-exit", "60", *self.args])
        if self.rtu:
            self.link = ["--rtu", self.pty.host, "--baud", "115200"]
        else:
            self.port = int(re.search(r"127\.0\.0\.1:(\d+)", line).group(1))
            self.link = ["--tcp", f"127.0.0.1:{self.port}"]
        return self



excite = canlib.excite


def measure(tmp, sim, design, *extra, out="frf.json", skip=1, ok=True, timeout=300):
    o = Path(tmp) / out
    r = run("modbus", "measure", *sim.link, "--design", design, "--skip-periods", skip, *extra, "-o", o,
            timeout=timeout)
    if ok:
        assert r.returncode == 0, f"msid modbus measure failed ({r.returncode}):\n{r.stderr}"
        r.doc = json.loads(o.read_text())
    return r


def frf_equal(a, b):
    """The FRF parts of two documents are identical (the sources name the link and are left out)."""
    a, b = json.loads(json.dumps(a)), json.loads(json.dumps(b))
    for d in (a, b):
        for e in d["experiments"]:
            e.pop("source")
    return lines_equal(a, b)
