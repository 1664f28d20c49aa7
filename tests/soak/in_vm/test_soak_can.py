"""Soak with faults on CAN, inside the qemu VM of tests/vcan/vm.py (real SocketCAN, vcan0):
msid-devsim -> vcan0 -> `msid can measure` -> the core, rounds of random CAN faults from a fixed seed
(random drops, duplicates, reorders, malformed frames, error frames, bus-off, device restarts) until
MSID_SOAK_CAN_SECONDS (default 30) of rounds have started. Per round: exit 0 (no crash; a hang
detector only), the host's anonymous RSS does not grow from the first half of the run to the second, every
injected fault is in the host's counters, and the FRF is bit-identical to the honest device's when no
sample was lost, else statistically consistent with the truth (95% regions, binomial). The device is paced
(--rate 2000): unpaced, a host process that a loaded TCG VM starves overflows its socket queue, and those
honestly counted kernel drops are not faults the soak injected."""
import json
import os
import random
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "tests" / "vcan" / "in_vm"))
sys.path.insert(0, str(ROOT / "tests" / "soak"))
import canlib as c  # noqa: E402
from test_soak import check_memory, settled_rss, watch  # noqa: E402

BUDGET = float(os.environ.get("MSID_SOAK_CAN_SECONDS", "30"))
K = int(os.environ.get("MSID_SOAK_CAN_PERIODS", "32"))
SEED = int(os.environ.get("MSID_SOAK_SEED", "15"))
P, CHUNKS = 256, 2             # classic int16, 4 channels: 2 frames per sample
KERNEL_REORDERS = 4            # reorders vcan itself may add per round (see the accounting below)


@pytest.fixture(scope="module")
def design(tmp_path_factory):
    if not Path("/sys/class/net/vcan0").exists():
        pytest.fail("no vcan0: this test runs inside the VM (ctest -R soak_vcan boots it with tests/vcan/vm.py)")
    return c.excite(tmp_path_factory.mktemp("design"), period=P, periods=K)


def draw(rng):
    n = K * P
    menu = {   # drop and malformed are exclusive (a frame is counted once), so are dup and reorder
        "drop": lambda: ["--drop-frac", f"{rng.uniform(1e-4, 1e-3):.5f}"],
        "malformed": lambda: ["--malformed-every", rng.randrange(700, 3000)],
        "dup": lambda: ["--dup-every", rng.randrange(50, 400)],
        "reorder": lambda: ["--reorder-every", rng.randrange(50, 400)],
        "error": lambda: ["--error-every", rng.randrange(300, 3000)],
        "busoff": lambda: ["--bus-off-at", f"{rng.randrange(2)}:{rng.randrange(P, n - P)}:{rng.randrange(5, 60)}"],
        "restart": lambda: ["--restart-at", f"{rng.randrange(2)}:{rng.randrange(P, n - P)}"],
    }
    names = [rng.choice(["drop", "malformed"]), rng.choice(["dup", "reorder"])]
    names += rng.sample(["error", "busoff", "restart"], rng.randrange(0, 3))
    return names, [str(x) for k in names for x in menu[k]()]


def run_round(tmp, design, args):
    with c.Sim(tmp, "--seed", 4, *args) as sim:
        out = Path(tmp) / "frf.json"
        log = Path(tmp) / "host.log"   # a file, not a pipe: watch() reads where acquisition ended
        with open(log, "w") as f:
            p = subprocess.Popen([c.MSID, "can", "measure", "--iface", "vcan0", "--design", str(design),
                                  "--skip-periods", "1", "--rcvbuf", str(4 << 20), "--rate", "2000", "--transient",
                                  "off", "-o", str(out)], stdout=f, stderr=subprocess.STDOUT, text=True)
        host, _ = watch(p, sim.p.pid, 900, f"msid can measure (faults {args})", log)
        p.wait()
        err = log.read_text()
        assert p.returncode == 0, f"faults {args}: {err}"
        doc = json.loads(out.read_text())
    return doc, sim.report(), sim.truth(), host


def test_soak_can(design, tmp_path):
    rng = random.Random(SEED)
    (tmp_path / "honest").mkdir()
    ref, _, truth, host = run_round(tmp_path / "honest", design, [])
    check_memory(host, 64, "host (honest)", settled=0.5)   # the TCG VM is slow to start a process
    ref_kb = settled_rss(host, settled=0.5)
    t0, rounds = time.monotonic(), 0
    while rounds < 2 or time.monotonic() - t0 < BUDGET:
        names, args = draw(rng)
        tmp = tmp_path / f"round{rounds}"
        tmp.mkdir()
        doc, rep, truth, host = run_round(tmp, design, args)
        a, inj = doc["acquisition"], rep["injected"]
        why = f"faults {args}: host {a}, device {inj}"
        check_memory(host, 64, f"host, faults {args}", settled=0.5, ref_kb=ref_kb)
        assert a["duplicates"] == inj["duplicated"], why
        # every injected reorder is seen; the kernel may add a few: vcan hands each frame to the sending
        # CPU's backlog, and a sender that migrates between the VM's 2 CPUs can have two frames delivered
        # in the other order (seen once in the 30-minute soak: 566 seen, 564 injected)
        assert 0 <= a["reordered"] - inj["reordered"] <= KERNEL_REORDERS, why
        assert a["malformed"] == inj["malformed"] and a["error_frames"] == inj["error_frames"], why
        assert a["device_restarts"] == inj["restarts"], why
        assert a["frames_missing"] == inj["dropped"] + inj["malformed"] + CHUNKS * inj["busoff_samples"], why
        for n, key in (("drop", "dropped"), ("malformed", "malformed"), ("dup", "duplicated"),
                       ("reorder", "reordered"), ("error", "error_frames"), ("busoff", "bus_off"),
                       ("restart", "restarts")):
            if n in names and n != "drop":
                assert inj[key] >= 1, f"{n} drawn but never injected: {why}"
        if a["samples_lost"] == 0 and a["device_restarts"] == 0:
            assert c.lines_equal(doc, ref), f"faults {args} cost no sample but changed the FRF"
        else:
            c.check_coverage(doc, truth, min_fraction=0.85)
        print(f"round {rounds}: {' '.join(args)}: lost {a['samples_lost']}, missing frames {a['frames_missing']}, "
              f"host HWM {host[-1][1]} kB")
        rounds += 1
    print(f"CAN soak: seed {SEED}, {rounds} rounds of 2 x {K} x {P} samples")
