#!/usr/bin/env python3
"""`msid bench ticks --can` (run inside the vcan VM): the host tick loop of a described CAN device at 1 kHz on
vcan0 against msid-devsim's DBC node (which cycles at 1 kHz under SCHED_FIFO 20), msid's against the loop a user
would write without it (tools/peers/msid_peers/can_tick_peer.py: python-can and cantools, time.sleep pacing), in
the same run against the same node. Reported per loop: ticks, lateness (wake-up minus deadline) median, p99 and
max, round trip, CPU per tick, and the jitter of the command frames on the bus: the deviation of each interval
between two command frames from the tick period, from the kernel's receive timestamps (candump -L). Beside them,
the same jitter of a frame the kernel's broadcast manager (CAN_BCM) sends on its own 1 ms timer, its payload
updated every tick from user space: what a BCM-timed command frame would give on this machine.

msid runs as `msid measure --map` would (SCHED_FIFO and locked memory where permitted) and once with
--no-realtime. Figures: docs/benchmarks.md."""
import argparse
import json
import math
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import canlib  # noqa: E402
from mapcan import CanMapSim, description, maplib  # noqa: E402

PEERS = canlib.SRC / "tools" / "peers" / "msid_peers"
PEER = PEERS / "can_tick_peer.py"
sys.path.insert(0, str(PEERS))
from loopcost import callgrind_ir, child_cpu, finish  # noqa: E402
from pacing import quantiles  # noqa: E402

CMD_ID = 0x101   # DriveCmd of mapcan's DBC
PERIOD = 20      # ticks per period of the excitation


class FrameClock:
    """candump -L of one identifier's frames (the command frame unless told) while a loop runs: the kernel's
    receive instants."""

    def __init__(self, tmp, tag, can_id=CMD_ID):
        self.path = Path(tmp) / f"dump-{tag}.log"
        self.can_id = can_id

    def __enter__(self):
        self.f = open(self.path, "w")
        self.p = subprocess.Popen(["candump", "-L", "-r", str(4 << 20), f"vcan0,{self.can_id:X}:7FF"], stdout=self.f)
        time.sleep(0.5)
        return self

    def __exit__(self, *exc):
        time.sleep(0.2)
        self.p.terminate()
        self.p.wait(10)
        self.f.close()
        return False

    def jitter(self, T, skip=0):
        """|interval - T| of successive frames after the first `skip` (those a loop sent before its ticks, such as
        a latency probe's back-to-back frames); intervals beyond 20 T (between a run's phases) are counted apart."""
        t = [float(l.split()[0].strip("()")) for l in self.path.read_text().splitlines() if l.startswith("(")]
        t = t[skip:]
        dev, gaps = [], 0
        for a, b in zip(t, t[1:]):
            if b - a > 20 * T:
                gaps += 1
            else:
                dev.append(abs((b - a) - T))
        return {"frames": len(t), "frames_left_out": skip, "interval_deviation_s": quantiles(dev), "pauses": gaps}


def msid_loop(tmp, sim, desc, rate, periods, realtime):
    tag = "rt" if realtime else "nort"
    out = Path(tmp) / f"out-{tag}"
    # short periods: a sample the loaded VM loses rejects one period of 20 ticks, and the FRF that carries the
    # timing figures is still given (a period of 200 lost nearly every period to a loss or two each)
    cmd = [canlib.MSID, "measure", "--device", sim.uri, "--map", desc, "--period", PERIOD, "--lines", "1:2:9",
           "--periods", periods, "--skip-periods", 1, "--rate", rate, "--no-plots", "--quiet", "-o", out]
    if not realtime:
        cmd.insert(-2, "--no-realtime")
    with FrameClock(tmp, tag) as fc:
        r, cpu = child_cpu(cmd)
    if r.returncode != 0:   # a loop that loses a sample in most periods gives no FRF: its message says what was lost
        return {"failed": (r.stderr.strip().splitlines() or ["?"])[-1], "bus": fc.jitter(1.0 / rate)}
    a = json.loads((out / "frf.json").read_text())["acquisition"]
    t = a["timing"]
    n = t["ticks"] + t["ticks_missed"]
    return {"ticks": n, "stale": a["stale_ticks"], "lateness_s": t["lateness_s"],
            "wake_lateness_s": t["wake_lateness_s"], "round_trip_s": t["round_trip_s"],
            "cpu_per_tick_s": t["cpu_per_tick_s"], "user_per_tick_s": t["cpu_user_per_tick_s"],
            "process_cpu_per_tick_s": cpu / n, "scheduling": t["scheduling"], "bus": fc.jitter(1.0 / rate)}


def peer_loop(tmp, desc_dir, rate, ticks):
    cmd = [sys.executable, PEER, "vcan0", Path(desc_dir) / "drive.dbc", "DriveCmd", "TorqueCmd", "DriveStatus",
           rate, ticks]
    return run_peer(cmd, rate, FrameClock(tmp, "peer"))


def run_peer(cmd, rate, clock):
    """One peer script's loop while `clock` records the bus: its row of the table (from its JSON report)."""
    with clock as fc:
        r, cpu = child_cpu(cmd)
    if r.returncode != 0:
        raise RuntimeError(f"{Path(str(cmd[1])).name} failed: {r.stderr}")
    j = json.loads(r.stdout)
    return {"ticks": j["ticks"], "stale": j["stale"], "lateness_s": j["lateness_s"],
            "wake_lateness_s": j["wake_lateness_s"], "round_trip_s": j["round_trip_s"],
            "cpu_per_tick_s": j["cpu_s"] / j["ticks"], "user_per_tick_s": j["cpu_user_s"] / j["ticks"],
            "process_cpu_per_tick_s": cpu / j["ticks"], "scheduling": "SCHED_OTHER (a Python script as written)",
            "bus": fc.jitter(1.0 / rate)}


# struct bcm_msg_head (linux/can/bcm.h) with native alignment, then one struct can_frame
BCM_HEAD = "@3I4l2I0q"
CAN_FRAME = "=IB3x8s"


def bcm_msg(opcode, flags, ival2_us, data):
    head = struct.pack(BCM_HEAD, opcode, flags, 0, 0, 0, ival2_us // 1000000, ival2_us % 1000000, CMD_ID, 1)
    return head + struct.pack(CAN_FRAME, CMD_ID, 8, data)


def bcm_loop(tmp, rate, ticks):
    """The kernel's broadcast manager sends the command frame on its own timer (period 1 / rate); a Python loop
    updates its payload every tick (TX_SETUP without SETTIMER: the next timer event sends the new payload)."""
    T = 1.0 / rate
    s = socket.socket(socket.AF_CAN, socket.SOCK_DGRAM, socket.CAN_BCM)
    s.connect(("vcan0",))
    with FrameClock(tmp, "bcm") as fc:
        s.send(bcm_msg(socket.CAN_BCM_TX_SETUP, socket.CAN_BCM_SETTIMER | socket.CAN_BCM_STARTTIMER,
                       int(round(T * 1e6)), bytes(8)))
        t0 = time.monotonic() + T
        for n in range(ticks):
            d = t0 + n * T - time.monotonic()
            if d > 0:
                time.sleep(d)
            v = int(round(5000 * math.sin(2 * math.pi * n / 64)))
            s.send(bcm_msg(socket.CAN_BCM_TX_SETUP, 0, 0, struct.pack("<h6x", v)))
        s.send(bcm_msg(socket.CAN_BCM_TX_DELETE, 0, 0, bytes(8)))
    s.close()
    return {"ticks": ticks, "bus": fc.jitter(T)}


def instructions_per_tick(tmp, sim, desc, desc_dir, rate):
    """User-space instructions per tick, from two runs of different lengths (their difference: set-up, start and
    the FRF's fixed part cancel), for msid and for the script; independent of the machine's load."""
    def msid_cmd(periods, tag):
        return [canlib.MSID, "measure", "--device", sim.uri, "--map", desc, "--period", PERIOD, "--lines", "1:2:9",
                "--periods", periods, "--skip-periods", 0, "--rate", rate, "--no-plots", "--quiet", "--no-realtime",
                "-o", Path(tmp) / f"cg-{tag}"]
    m = (callgrind_ir(msid_cmd(12, "m12"), tmp, "m12") - callgrind_ir(msid_cmd(4, "m4"), tmp, "m4")) / (8 * PERIOD)
    peer = lambda n: [sys.executable, PEER, "vcan0", Path(desc_dir) / "drive.dbc", "DriveCmd", "TorqueCmd",
                      "DriveStatus", rate, n]
    p = (callgrind_ir(peer(300), tmp, "p300") - callgrind_ir(peer(100), tmp, "p100")) / 200
    return m, p


def us(x):
    return f"{1e6 * x:7.0f}us"


def print_rows(rows, script, missing="stale"):
    """The table of the loops (msid's, the script's, a kernel timer's bus jitter alone) and the script / msid ratios;
    `missing`: the header of the ticks that found nothing to read."""
    print(f"{'loop':20} {'ticks':>6} {missing:>6} {'wake med':>9} {'wake p99':>9} {'late p99':>9} {'rtt p99':>9} "
          f"{'CPU/tick':>9} {'user':>9} {'bus med':>9} {'bus p99':>9} {'bus max':>9}")
    for name, r in rows.items():
        b = r["bus"]["interval_deviation_s"]
        if "failed" in r:
            print(f"{name:20} no FRF (bus jitter median {us(b['median'])}, p99 {us(b['p99'])}): {r['failed']}")
            continue
        if "lateness_s" not in r:
            print(f"{name:20} {r['ticks']:6d} {'':6} {'':9} {'':9} {'':9} {'':9} {'':9} {'':9} "
                  f"{us(b['median'])} {us(b['p99'])} {us(b['max'])}")
            continue
        W, L, R = r["wake_lateness_s"], r["lateness_s"], r["round_trip_s"]
        print(f"{name:20} {r['ticks']:6d} {r['stale']:6d} {us(W['median'])} {us(W['p99'])} {us(L['p99'])} "
              f"{us(R['p99'])} {1e6 * r['cpu_per_tick_s']:7.1f}us {1e6 * r['user_per_tick_s']:7.1f}us "
              f"{us(b['median'])} {us(b['p99'])} {us(b['max'])}")
    p, m = rows[script], rows["msid"]
    if "failed" not in m:
        ratio = lambda x, y: x / max(y, 1e-12)
        print(f"ratio script / msid: wake lateness p99 "
              f"{ratio(p['wake_lateness_s']['p99'], m['wake_lateness_s']['p99']):.1f}x, lateness p99 "
              f"{ratio(p['lateness_s']['p99'], m['lateness_s']['p99']):.1f}x, CPU per tick "
              f"{ratio(p['cpu_per_tick_s'], m['cpu_per_tick_s']):.1f}x (user space "
              f"{ratio(p['user_per_tick_s'], m['user_per_tick_s']):.1f}x), bus jitter p99 "
              f"{ratio(p['bus']['interval_deviation_s']['p99'], m['bus']['interval_deviation_s']['p99']):.1f}x")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rate", type=float, default=1000)
    ap.add_argument("--periods", type=int, default=100, help="measured periods of 20 ticks (default 100)")
    ap.add_argument("--json", help="also write the figures to this file")
    ap.add_argument("--instructions", action="store_true",
                    help="also count the user-space instructions per tick of both loops under callgrind (at 50 Hz)")
    a = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        desc = description(tmp, counter=False)   # samples placed by tick: a late tick is not a lost cycle
        A, B, C, D = maplib.siso_plant()
        plant = maplib.write_plant(Path(tmp) / "plant.txt", A, B, C, D)
        with CanMapSim(tmp, desc, "--plant", plant, "--cycle-hz", a.rate) as sim:
            rows["msid"] = msid_loop(tmp, sim, desc, a.rate, a.periods, True)
            rows["msid --no-realtime"] = msid_loop(tmp, sim, desc, a.rate, a.periods, False)
            n = rows["msid"].get("ticks", a.periods * PERIOD)
            rows["python-can script"] = peer_loop(tmp, tmp, a.rate, n)
        rows["CAN_BCM timer"] = bcm_loop(tmp, a.rate, rows["python-can script"]["ticks"])
        insn = None
        if a.instructions:
            with CanMapSim(tmp, desc, "--plant", plant, "--cycle-hz", 50) as sim50:
                insn = instructions_per_tick(tmp, sim50, desc, tmp, 50)
    print(f"host tick loop at {a.rate:g} Hz on vcan0 (in the qemu VM) against msid-devsim's DBC node: per tick the "
          "status frames taken, one command frame sent")
    print("wake: lateness of the ticks the loop slept for; late: of every tick; rtt: the tick's exchange; CPU/tick: "
          "the loop alone (user: its part in user space); bus: |interval - period| of the command frames (kernel "
          "receive timestamps)")
    print_rows(rows, "python-can script")
    if insn:
        print(f"user-space instructions per tick (callgrind, 50 Hz): msid {insn[0]:.0f}, python-can script "
              f"{insn[1]:.0f} ({insn[1] / insn[0]:.1f}x)")
        rows["instructions_per_tick"] = {"msid": insn[0], "python-can script": insn[1]}
    finish(rows, a.json)


if __name__ == "__main__":
    main()
