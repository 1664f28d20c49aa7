"""The described CAN node of the in-VM tests (msid measure --device can://vcan0 --map): its DBC and description,
msid-devsim's DBC node and the independent python-can + cantools node (dbc_peer.py) as context managers, and one
measurement. The node cycles at the tick rate with a counter signal unless a test says otherwise, so that the FRF is
its DT plant G(z) (maplib.dt_frf)."""
import json
import sys
from pathlib import Path

import pytest

import canlib
from canlib import DEVSIM

sys.path.insert(0, str(canlib.SRC / "tests" / "modbus"))
import maplib  # noqa: E402  (the plant, its exact FRF, the coverage check)

RATE, P, LINES, BINS = 100, 64, "1:2:31", list(range(1, 32, 2))
PEER_RATE = 50   # the Python peer's cycle: cantools and numpy per cycle on the VM's emulated CPU

DBC = """VERSION ""
NS_ :
\tSIG_VALTYPE_
BS_:
BU_: HOST DRIVE
BO_ 257 DriveCmd: 8 HOST
 SG_ TorqueCmd : 0|16@1- (0.0001,0) [-3|3] "N m" DRIVE
 SG_ Mode : 16|8@1+ (1,0) [0|0] "" DRIVE
BO_ 385 DriveStatus: 8 DRIVE
 SG_ TorqueAct : 0|32@1- (1,0) [0|0] "N m" HOST
 SG_ Speed : 39|16@0- (0.001,0) [0|0] "rad/s" HOST
 SG_ Cycle : 48|16@1+ (1,0) [0|0] "" HOST
SIG_VALTYPE_ 385 TorqueAct : 1;
"""

DRIVE = """
[[drive]]
name = "Torque command"
unit = "N m"
message = "DriveCmd"
signal = "TorqueCmd"
min = -2.0
max = 2.0
safe = {safe}
"""

READBACK = """
[[measure]]
name = "Torque"
unit = "N m"
role = "input"
message = "DriveStatus"
signal = "TorqueAct"
"""

OUTPUT = """
[[measure]]
name = "Speed"
unit = "rad/s"
role = "output"
message = "DriveStatus"
signal = "Speed"
"""

COUNTER = """
[[measure]]
name = "Cycle"
role = "counter"
message = "DriveStatus"
signal = "Cycle"
"""


def description(tmp, *, readback=True, counter=True, safe=0.0, drive=None, extra=""):
    (Path(tmp) / "drive.dbc").write_text(DBC)
    text = 'format = "msid-device/1"\ntransport = "can"\ndbc = "drive.dbc"\n' + extra
    text += (drive if drive is not None else DRIVE).format(safe=safe)
    text += (READBACK if readback else "") + OUTPUT + (COUNTER if counter else "")
    path = Path(tmp) / "dev.toml"
    path.write_text(text)
    return str(path)


@pytest.fixture(scope="module")
def plant(tmp_path_factory):
    A, B, C, D = maplib.siso_plant()
    path = maplib.write_plant(tmp_path_factory.mktemp("plant") / "plant.txt", A, B, C, D)
    return str(path), (A, B, C, D)


class CanMapSim(canlib.Sim):
    """msid-devsim --map DESC --iface vcan0 under SCHED_FIFO where permitted (a node is its own hardware)."""

    def __init__(self, tmp, desc, *args):
        self.tmp = Path(tmp)
        self.report_path = self.tmp / f"report-{id(self)}.json"
        self.args = maplib.realtime_prefix() + [DEVSIM, "--map", desc, "--iface", "vcan0", "--report",
                                                str(self.report_path), "--idle-exit", "120",
                                                "--cycle-hz", str(RATE)] + [str(a) for a in args]
        self.uri = "can://vcan0"

    expect_exit = 0   # the simulator's exit status a test expects (9: --die-after)

    def __enter__(self):
        self.start(self.args)
        return self

    def __exit__(self, *exc):
        self.stop(exc[0] is None and self.expect_exit == 0)
        if exc[0] is None and self.expect_exit:
            assert self.p.returncode == self.expect_exit, self.p.returncode
        return False


def measure(tmp, sim, desc, *extra, **kw):
    """One msid measure --map over can://vcan0 at this file's design and rate (maplib.measure: a run refused for
    too few usable periods is made again)."""
    for k, v in (("period", P), ("lines", LINES), ("periods", 6), ("skip", 1), ("rate", RATE), ("timeout", 600)):
        kw.setdefault(k, v)
    return maplib.measure(tmp, sim, desc, *extra, **kw)


PEER = Path(__file__).resolve().parent / "dbc_peer.py"


class PeerSim(canlib.Sim):
    """dbc_peer.py --map DESC --iface vcan0; .state() is the peer's own record (its applied setpoints)."""

    def __init__(self, tmp, desc, *args):
        self.tmp = Path(tmp)
        self.state_path = self.tmp / f"state-{id(self)}.json"
        self.args = maplib.realtime_prefix() + [sys.executable, str(PEER), "--map", desc, "--iface", "vcan0",
                                                "--state", str(self.state_path), "--cycle-hz", str(PEER_RATE)]
        self.args += [str(a) for a in args]
        self.uri = "can://vcan0"

    def __enter__(self):
        self.start(self.args, wait=180)   # python-can, cantools and numpy load slowly on the VM's emulated CPU
        return self

    def state(self):
        return json.loads(self.state_path.read_text())


