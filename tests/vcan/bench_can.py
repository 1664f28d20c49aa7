#!/usr/bin/env python3
"""CAN benchmark, run inside the vcan VM by `msid bench can`: the highest sustained sample
rate with zero loss (no sequence gap, no kernel drop) from msid-devsim through SocketCAN to
`msid can measure`, for 4 channels on classic CAN and 16 channels on CAN FD; beside it
the frames/s that can-utils' cangen delivers to candump on the same vcan.

Search: a run as fast as possible first; if it loses nothing, that rate is the answer
(the producer is the limit); otherwise bisect the paced rate between the best loss-free
rate and the unpaced rate (geometric steps, `--steps` runs)."""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent / "in_vm"))
import canlib as c  # noqa: E402

CASES = {
    # name: (plant, inputs, experiments, fd, frames per sample, extra measure args)
    "classic, 4 channels (2x2), int16": (None, 2, 2, False, 2, []),
    "CAN FD, 16 channels (8x8), int16": ("fd16", 8, 8, True, 1, ["--fd"]),
}


def plant_8x8(path):
    d = " ".join(f"{(1.0 if i == j else 0.1):g}" for i in range(8) for j in range(8))
    Path(path).write_text(f"type dt\nstates 0\ninputs 8\noutputs 8\nD {d}\n")


def trial(tmp, design, plant, rate, extra):
    args = ["--seed", 1] + (["--plant", plant] if plant else [])
    with c.Sim(tmp, *args):
        r = c.run("can", "measure", "--iface", "vcan0", "--design", design, "--skip-periods", 1,
                  "--transient", "off", "--rcvbuf", 16 << 20, "--rate", rate, "--timeout", 30, *extra,
                  "-o", Path(tmp) / "frf.json", timeout=600)
    if r.returncode != 0:
        return None
    a = json.loads((Path(tmp) / "frf.json").read_text())["acquisition"]
    ok = a["samples_lost"] == 0 and a["kernel_drops"] == 0
    achieved = a["samples"] / a["stream_seconds"] if a["stream_seconds"] > 0 else 0.0
    return ok, achieved, a


def search(name, tmp, steps, samples):
    plant, nu, m, fd, fps, extra = CASES[name]
    pfile = None
    if plant:
        pfile = Path(tmp) / "p.plant"
        plant_8x8(pfile)
    P = 1024
    periods = max(3, samples // (P * m))
    design = c.excite(tmp, period=P, lines="1:8", amp=0.2, periods=periods, inputs=nu, experiments=m)
    res = trial(tmp, design, pfile, 0, extra)
    if res is None:
        raise RuntimeError(f"{name}: the unpaced run failed")
    ok, top, _ = res
    log = [(0, ok, top)]
    if ok:
        return top, top, log, periods * P * m
    lo, hi = 0.0, top
    for _ in range(steps):
        rate = int((lo * hi) ** 0.5) if lo > 0 else int(hi / 2)
        res = trial(tmp, design, pfile, rate, extra)
        good = res is not None and res[0] and res[1] >= 0.98 * rate
        log.append((rate, good, res[1] if res else 0.0))
        if good:
            lo = rate
        else:
            hi = rate
    return lo, top, log, periods * P * m


def cangen_rate(fd, n):
    """Frames/s from cangen to candump on vcan0, no loss (candump exits after n frames)."""
    with tempfile.TemporaryFile() as out:
        dump = subprocess.Popen(["candump", "-r", str(16 << 20), "-n", str(n), "vcan0,0:0"], stdout=out)
        time.sleep(0.5)
        t0 = time.monotonic()
        gen = ["cangen", "vcan0", "-g", "0", "-n", str(n), "-I", "210", "-D", "i", "-p", "10"]
        gen += ["-f", "-L", "64"] if fd else ["-L", "8"]
        subprocess.run(gen, check=True, capture_output=True)
        try:
            dump.wait(60)
        except subprocess.TimeoutExpired:
            dump.kill()
            return None
        return n / (time.monotonic() - t0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="small runs (a smoke test)")
    ap.add_argument("--steps", type=int, default=5)
    a = ap.parse_args()
    samples = 20000 if a.quick else 100000
    steps = 1 if a.quick else a.steps
    print(f"msid bench can: vcan in a qemu TCG guest ({os.cpu_count()} vCPU), {samples} samples per run")
    rows = []
    for name in CASES:
        with tempfile.TemporaryDirectory() as tmp:
            best, top, log, n = search(name, tmp, steps, samples)
        fd, fps = CASES[name][3], CASES[name][4]
        ref = cangen_rate(fd, 50000 if not a.quick else 10000)
        for rate, ok, ach in log:
            print(f"  {name}: requested {rate or 'max'} Hz -> {ach:.0f} samples/s, {'no loss' if ok else 'LOSS'}")
        rows.append((name, best, best * fps, top, ref))
    print()
    print("| stream | highest loss-free rate (samples/s) | frames/s | unpaced rate (samples/s) | cangen -> candump (frames/s) |")
    print("|---|---|---|---|---|")
    for name, best, fr, top, ref in rows:
        print(f"| {name} | {best:.0f} | {fr:.0f} | {top:.0f} | {ref:.0f} |" if ref else
              f"| {name} | {best:.0f} | {fr:.0f} | {top:.0f} | (lost frames) |")


if __name__ == "__main__":
    main()
