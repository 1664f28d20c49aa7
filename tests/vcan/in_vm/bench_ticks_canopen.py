#!/usr/bin/env python3
"""`msid bench ticks --canopen` (run inside the vcan VM): the SYNC loop of a CiA 402 drive in cyclic synchronous
torque on vcan0, msid's (`msid measure --device canopen://vcan0?node=5 --map`: the target in RPDO1, one SYNC, the
TPDO that SYNC asked for; and with sync = "kernel", the RPDO alone, the SYNC from the kernel's timer) against the loop a user would write with the canopen package
(tools/peers/msid_peers/canopen_tick_peer.py: the same PDOs, time.sleep pacing), in the same run against the same
node (msid-devsim --canopen 5 under SCHED_FIFO 20). Reported per loop: ticks, ticks without their TPDO, lateness
(wake-up minus deadline) median, p99 and max, round trip, CPU per tick, and the jitter of the SYNC frames on the
bus: the deviation of each interval between two SYNCs from the period, from the kernel's receive timestamps
(candump -L). Beside them, the same jitter of SYNCs the kernel's broadcast manager (CAN_BCM) sends on its own
timer. Figures: docs/benchmarks.md."""
import argparse
import json
import socket
import struct
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import canlib  # noqa: E402
import comap  # noqa: E402
from bench_ticks_can import BCM_HEAD, CAN_FRAME, FrameClock, print_rows, run_peer  # noqa: E402

PEERS = canlib.SRC / "tools" / "peers" / "msid_peers"
PEER = PEERS / "canopen_tick_peer.py"
sys.path.insert(0, str(PEERS))
from loopcost import child_cpu, finish  # noqa: E402

SYNC_ID = 0x080
PERIOD = 20   # ticks per period: a loaded VM's lost sample rejects one short period, and the FRF (with the
              # timing block) is still given


def msid_loop(tmp, sim, desc, rate, periods, realtime, kernel_sync=False):
    tag = ("rt" if realtime else "nort") + ("-kernel" if kernel_sync else "")
    out = Path(tmp) / f"out-{tag}"
    cmd = [canlib.MSID, "measure", "--device", sim.uri, "--map", desc, "--period", PERIOD, "--lines", "1:2:9",
           "--periods", periods, "--skip-periods", 1, "--rate", rate, "--no-plots", "--quiet", "-o", out]
    if not realtime:
        cmd.insert(-2, "--no-realtime")
    with FrameClock(tmp, "sync-" + tag, SYNC_ID) as fc:
        r, cpu = child_cpu(cmd)
    if r.returncode != 0:
        return {"failed": (r.stderr.strip().splitlines() or ["?"])[-1], "bus": fc.jitter(1.0 / rate)}
    a = json.loads((out / "frf.json").read_text())["acquisition"]
    t = a["timing"]
    n = t["ticks"] + t["ticks_missed"]
    # the SYNCs of the latency probe (one per answer, back to back) come before the tick loop's: left out (the
    # kernel's timer sends none of its own: its SYNCs are all at the period)
    before = 0 if kernel_sync else a["syncs"] - t["ticks"]
    print(f"msid ({tag}): {a['syncs']} SYNCs, {t['ticks']} ticks, {before} before the loop", file=sys.stderr)
    return {"ticks": n, "stale": t.get("measured_ticks_missed", 0) + t.get("exchanges_failed", 0),
            "lateness_s": t["lateness_s"], "wake_lateness_s": t["wake_lateness_s"], "round_trip_s": t["round_trip_s"],
            "cpu_per_tick_s": t["cpu_per_tick_s"], "user_per_tick_s": t["cpu_user_per_tick_s"],
            "process_cpu_per_tick_s": cpu / n, "scheduling": t["scheduling"], "bus": fc.jitter(1.0 / rate, before)}


def peer_loop(tmp, rate, ticks):
    cmd = [sys.executable, PEER, "vcan0", comap.NODE, comap.EDS, rate, ticks]
    return run_peer(cmd, rate, FrameClock(tmp, "sync-peer", SYNC_ID))


def bcm_sync(tmp, rate, ticks):
    """SYNC frames sent by the kernel's broadcast manager on its own timer (period 1 / rate), nothing in user space
    per tick: the SYNC carries no data."""
    T = 1.0 / rate
    s = socket.socket(socket.AF_CAN, socket.SOCK_DGRAM, socket.CAN_BCM)
    s.connect(("vcan0",))
    ival = int(round(T * 1e6))
    head = struct.pack(BCM_HEAD, socket.CAN_BCM_TX_SETUP, socket.CAN_BCM_SETTIMER | socket.CAN_BCM_STARTTIMER, 0, 0,
                       0, ival // 1000000, ival % 1000000, SYNC_ID, 1)
    with FrameClock(tmp, "sync-bcm", SYNC_ID) as fc:
        s.send(head + struct.pack(CAN_FRAME, SYNC_ID, 0, bytes(8)))
        time.sleep(ticks * T)
        s.send(struct.pack(BCM_HEAD, socket.CAN_BCM_TX_DELETE, 0, 0, 0, 0, 0, 0, SYNC_ID, 0))
    s.close()
    return {"ticks": ticks, "bus": fc.jitter(T)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rate", type=float, default=1000)
    ap.add_argument("--periods", type=int, default=100, help=f"measured periods of {PERIOD} ticks (default 100)")
    ap.add_argument("--json", help="also write the figures to this file")
    a = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        desc = comap.preset(tmp)
        with comap.Drive(tmp) as sim:
            rows["msid"] = msid_loop(tmp, sim, desc, a.rate, a.periods, True)
            rows["msid --no-realtime"] = msid_loop(tmp, sim, desc, a.rate, a.periods, False)
            rows["msid, sync = kernel"] = msid_loop(tmp, sim, comap.preset(tmp, top='sync = "kernel"\n',
                                                                           name="kernel.toml"),
                                                    a.rate, a.periods, True, kernel_sync=True)
            n = rows["msid"].get("ticks", (a.periods + 1) * PERIOD)
            rows["canopen script"] = peer_loop(tmp, a.rate, n)
        rows["CAN_BCM SYNC timer"] = bcm_sync(tmp, a.rate, rows["canopen script"]["ticks"])
    print(f"SYNC loop at {a.rate:g} Hz on vcan0 (in the qemu VM) against msid-devsim's CiA 402 node in CST: per tick "
          "the target in RPDO1, one SYNC, the TPDO it asked for")
    print("wake: lateness of the ticks the loop slept for; late: of every tick; rtt: the tick's exchange; CPU/tick: "
          "the loop alone (user: its part in user space); bus: |interval - period| of the SYNC frames (kernel "
          "receive timestamps); lost: ticks without their TPDO")
    print_rows(rows, "canopen script", missing="lost")
    finish(rows, a.json)


if __name__ == "__main__":
    main()
