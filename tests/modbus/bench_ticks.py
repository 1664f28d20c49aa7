#!/usr/bin/env python3
"""`msid bench ticks` (Modbus part): the host tick loop of a described device at 200 Hz over Modbus TCP on
127.0.0.1, msid's against the loop a user would write without it (tools/peers/msid_peers/tick_peer.py:
pymodbus, time.sleep pacing), in the same run against the same msid-devsim --map. Reported per loop: ticks,
lateness (wake-up minus deadline) median, p99 and max, round trip of one tick's exchange, and CPU per tick
of the process. msid runs as `msid measure --map` would (SCHED_FIFO and locked memory where permitted) and once
with --no-realtime; its CPU includes the set-up and the FRF. The CAN part (`msid bench ticks --can`)
runs in the vcan VM: tests/vcan/in_vm/bench_ticks_can.py. Figures: docs/benchmarks.md."""
import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import maplib  # noqa: E402
from mblib import MSID  # noqa: E402

PEERS = HERE.parents[1] / "tools" / "peers" / "msid_peers"
PEER = PEERS / "tick_peer.py"
sys.path.insert(0, str(PEERS))
from loopcost import callgrind_ir, child_cpu, finish  # noqa: E402


def msid_loop(tmp, sim, desc, rate, periods, realtime):
    out = Path(tmp) / ("out-rt" if realtime else "out-nort")
    cmd = [MSID, "measure", "--device", sim.uri, "--map", desc, "--period", 200, "--lines", "1:2:49", "--periods",
           periods, "--skip-periods", 1, "--rate", rate, "--no-plots", "--quiet", "-o", out]
    if not realtime:
        cmd.insert(-2, "--no-realtime")
    r, cpu = child_cpu(cmd)
    if r.returncode != 0:   # on a loaded machine an unprivileged loop can lose a sample in every period
        return {"failed": r.stderr.strip().splitlines()[-1]}
    t = json.loads((out / "frf.json").read_text())["acquisition"]["timing"]
    n = t["ticks"] + t["ticks_missed"]
    return {"ticks": n, "lateness_s": t["lateness_s"], "wake_lateness_s": t["wake_lateness_s"],
            "round_trip_s": t["round_trip_s"], "cpu_per_tick_s": t["cpu_per_tick_s"],
            "user_per_tick_s": t["cpu_user_per_tick_s"], "process_cpu_per_tick_s": cpu / n,
            "scheduling": t["scheduling"]}


def peer_loop(sim, rate, ticks):
    r, cpu = child_cpu([sys.executable, PEER, "127.0.0.1", sim.port, rate, ticks])
    if r.returncode != 0:
        raise RuntimeError(f"tick_peer failed: {r.stderr}")
    j = json.loads(r.stdout)
    if j["failed"]:
        raise RuntimeError(f"tick_peer: {j['failed']} of {j['ticks']} exchanges failed")
    return {"ticks": j["ticks"], "lateness_s": j["lateness_s"], "wake_lateness_s": j["wake_lateness_s"],
            "round_trip_s": j["round_trip_s"], "cpu_per_tick_s": j["cpu_s"] / j["ticks"],
            "user_per_tick_s": j["cpu_user_s"] / j["ticks"],
            "process_cpu_per_tick_s": cpu / j["ticks"], "scheduling": "SCHED_OTHER (a Python script as written)"}


def instructions_per_tick(tmp, sim, desc, rate):
    """User-space instructions per tick, from two runs of different lengths (their difference: set-up, start and
    the FRF's fixed part cancel), for msid and for the script; independent of the machine's load."""
    def msid_cmd(periods, tag):
        return [MSID, "measure", "--device", sim.uri, "--map", desc, "--period", 100, "--lines", "1:2:25", "--periods",
                periods, "--skip-periods", 0, "--rate", rate, "--no-plots", "--quiet", "--no-realtime", "-o",
                Path(tmp) / f"cg-{tag}"]
    m = (callgrind_ir(msid_cmd(6, "m6"), tmp, "m6") - callgrind_ir(msid_cmd(2, "m2"), tmp, "m2")) / 400
    peer = lambda n: [sys.executable, PEER, "127.0.0.1", sim.port, rate, n]
    p = (callgrind_ir(peer(300), tmp, "p300") - callgrind_ir(peer(100), tmp, "p100")) / 200
    return m, p


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rate", type=float, default=200)
    ap.add_argument("--periods", type=int, default=10, help="measured periods of 200 ticks (default 10)")
    ap.add_argument("--json", help="also write the figures to this file")
    ap.add_argument("--instructions", action="store_true",
                    help="also count the user-space instructions per tick of both loops under callgrind (at 50 Hz)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        desc = maplib.description(Path(tmp) / "dev.toml", counter=False)
        rows = {}
        with maplib.MapSim(tmp, desc, "--cycle-hz", a.rate) as sim:
            rows["msid"] = msid_loop(tmp, sim, desc, a.rate, a.periods, True)
            rows["msid --no-realtime"] = msid_loop(tmp, sim, desc, a.rate, a.periods, False)
            rows["pymodbus script"] = peer_loop(sim, a.rate, rows["msid"].get("ticks", (a.periods + 1) * 200))
        insn = None
        if a.instructions:
            with maplib.MapSim(tmp, desc, "--cycle-hz", 50) as sim50:
                insn = instructions_per_tick(tmp, sim50, desc, 50)
    print(f"host tick loop at {a.rate:g} Hz over Modbus TCP on 127.0.0.1 (msid-devsim --map, FC 16 + FC 04 per tick)")
    print("wake: lateness of the ticks the loop slept for (its clock's precision); late: of every tick (a slow answer")
    print("makes the next tick late); CPU/tick: the loop alone, user: its part in user space (the rest is the kernel's")
    print("TCP stack, the same two transactions for both); process: everything the process ran, set-up included")
    print(f"{'loop':22} {'ticks':>6} {'wake med':>9} {'wake p99':>9} {'wake max':>9} {'late p99':>9} {'rtt p99':>9} "
          f"{'CPU/tick':>9} {'user':>9} {'process':>9}")
    for name, r in rows.items():
        if name == "instructions_per_tick":
            continue
        if "failed" in r:
            print(f"{name:22} no FRF: {r['failed']}")
            continue
        W, L, R = r["wake_lateness_s"], r["lateness_s"], r["round_trip_s"]
        print(f"{name:22} {r['ticks']:6d} {1e6 * W['median']:7.0f}us {1e6 * W['p99']:7.0f}us {1e6 * W['max']:7.0f}us "
              f"{1e6 * L['p99']:7.0f}us {1e6 * R['p99']:7.0f}us {1e6 * r['cpu_per_tick_s']:7.1f}us "
              f"{1e6 * r['user_per_tick_s']:7.1f}us {1e6 * r['process_cpu_per_tick_s']:7.1f}us")
    p, m = rows["pymodbus script"], rows["msid"]
    ratio = lambda a, b: a / max(b, 1e-12)
    if "failed" not in m:
        print(f"ratio script / msid: wake lateness p99 {ratio(p['wake_lateness_s']['p99'], m['wake_lateness_s']['p99']):.1f}x, "
              f"lateness p99 {ratio(p['lateness_s']['p99'], m['lateness_s']['p99']):.1f}x, "
              f"CPU per tick {ratio(p['cpu_per_tick_s'], m['cpu_per_tick_s']):.1f}x "
              f"(user space {ratio(p['user_per_tick_s'], m['user_per_tick_s']):.1f}x)")
    if insn:
        print(f"user-space instructions per tick (callgrind): msid {insn[0]:.0f}, pymodbus script {insn[1]:.0f} "
              f"({insn[1] / insn[0]:.1f}x)")
        rows["instructions_per_tick"] = {"msid": insn[0], "pymodbus script": insn[1]}
    finish(rows, a.json)


if __name__ == "__main__":
    main()
