#!/usr/bin/env python3
"""Modbus benchmark, run by `msid bench modbus`: the highest sustained sample rate with zero loss
(no ring overrun) from msid-devsim to `msid modbus measure`, 4 channels (2x2, int16: 5 registers
per sample with the tag), over Modbus TCP on 127.0.0.1 and over RTU at 115200 baud on a socat pty
pair (the simulator waits each frame's wire time), beside each link's theoretical register rate.

Search: unpaced first (the device writes as fast as the host reads: the link's throughput), then
a paced run at that rate, bisecting down (geometric steps) until a run loses nothing."""
import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mblib as c  # noqa: E402

W = 5          # registers per sample: tag + 4 int16 channels


def trial(tmp, design, rtu, rate, ring):
    args = ["--seed", 1] + (["--ring", ring] if ring else [])
    with c.Sim(tmp, *args, rtu=rtu) as sim:
        r = c.run("modbus", "measure", *sim.link, "--design", design, "--skip-periods", 1, "--transient", "off",
                  "--rate", rate, "--timeout", 30, "-o", Path(tmp) / "frf.json", timeout=900)
    if r.returncode != 0:
        return None
    a = json.loads((Path(tmp) / "frf.json").read_text())["acquisition"]
    return a["samples_lost"] == 0, a["samples"] / a["stream_seconds"], a


def search(name, rtu, samples, steps, ring):
    with tempfile.TemporaryDirectory() as tmp:
        P = 256
        periods = max(3, samples // (P * 2))
        design = c.excite(tmp, period=P, lines="1:8", amp=0.2, periods=periods)
        res = trial(tmp, design, rtu, 0, ring)
        if res is None:
            raise RuntimeError(f"{name}: the unpaced run failed")
        top, a = res[1], res[2]
        log = [(0, True, top)]
        lo, hi, rate = 0, top, int(top)
        for _ in range(steps):
            res = trial(tmp, design, rtu, rate, ring) if rate > 0 else None
            good = res is not None and res[0] and res[1] >= 0.95 * rate
            log.append((rate, good, res[1] if res else 0.0))
            if good:
                lo = rate
                break
            hi = rate
            rate = int(rate * 0.85)
        return lo, top, a["link_reg_rate"], log


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="small runs (a smoke test)")
    o = ap.parse_args()
    tcp_n, rtu_n, steps = (20000, 2000, 3) if o.quick else (200000, 12000, 8)
    print(f"msid bench modbus: {os.cpu_count()} CPU(s), 4 channels int16 ({W} registers per sample), "
          f"{tcp_n} samples over TCP, {rtu_n} over RTU per run")
    rows = []
    for name, rtu, n in (("Modbus TCP, 127.0.0.1", False, tcp_n), ("Modbus RTU, 115200 baud 8N1 (socat pty)", True, rtu_n)):
        best, top, link, log = search(name, rtu, n, steps, 0)
        for rate, ok, ach in log:
            print(f"  {name}: requested {rate or 'max'} Hz -> {ach:.0f} samples/s, {'no loss' if ok else 'LOSS'}")
        rows.append((name, best, top, link, rtu))
    print()
    print("| link | highest loss-free rate (samples/s, 4 ch) | registers/s | unpaced (samples/s) | "
          "link register rate (registers/s) | theoretical max (samples/s) | share |")
    print("|---|---|---|---|---|---|---|")
    for name, best, top, link, rtu in rows:
        src = "theoretical, 125-register reads" if rtu else "measured, 125-register reads"
        print(f"| {name} | {best:.0f} | {best * W:.0f} | {top:.0f} | {link:.0f} ({src}) | {link / W:.0f} | "
              f"{best * W / link:.0%} |")


if __name__ == "__main__":
    main()
