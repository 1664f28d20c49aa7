#!/usr/bin/env python3
"""msid.frf (the compiled module, in process) against the NumPy peer of `msid bench frf` on the same
job, in the same run: 2x2, P = 4096, 64 periods, 2 experiments, 200 lines (periodic random inputs,
noisy outputs); and the per-call cost of msid.frf on a tiny record (1x1, P = 16, 2 periods, 1 line).
Best of repeated runs (at least `--min-seconds` each). docs/benchmarks.md holds the figures.

    PYTHONPATH=build/python python3 scripts/bench_python_frf.py [--min-seconds S] [--json]
"""
import argparse
import importlib.util
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

import msid

ROOT = Path(__file__).resolve().parents[1]


def load_peer():
    """The NumPy peer of `msid bench frf` (bench_peer.py, wherever the repository keeps it)."""
    for p in sorted(ROOT.glob("**/bench_peer.py")):
        if "build" in p.relative_to(ROOT).parts:
            continue
        spec = importlib.util.spec_from_file_location("msid_bench_peer", p)
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        return mod
    raise SystemExit("bench_peer.py (the NumPy peer of msid bench frf) is not in the repository")


def best_time(fn, min_s):
    """(best wall time, best process CPU time over all threads, runs): the CPU time tells the work on a
    shared machine, where the wall time is an upper bound."""
    fn()   # warm-up (FFTW plans, imports)
    best, cpu, reps, end = float("inf"), float("inf"), 0, time.perf_counter() + min_s
    while reps < 3 or time.perf_counter() < end:
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        best, cpu = min(best, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
        reps += 1
    return best, cpu, reps


def fftw_floor(P, channels, periods):
    """FFTW's own r2c transforms of this job's periods on one core, in seconds, from `msid bench frf`
    in the same run (its P = 4096 case: FFTW_ESTIMATE plans as msid frf, stride C, every period),
    scaled by channels x periods; None when the msid binary is not found. No implementation of this
    job can take less than this on one core, or half of it on two."""
    import re
    import subprocess
    exe = os.environ.get("MSID_BIN") or str(ROOT / "build" / "tools" / "msid")
    if P != 4096 or not os.access(exe, os.X_OK):
        return None
    out = subprocess.run([exe, "bench", "frf", "--only", "2", "--no-peer", "--min-seconds", "1"],
                         capture_output=True, text=True, check=True).stdout
    m = re.search(r"^\s+fft\s+[\d.]+\s+[\d.]+\s+[\d.]+\s+([\d.]+) us", out, re.M)
    if not m:
        return None
    return float(m.group(1)) * 1e-6 / 6 * channels * periods   # that case has 2 + 4 channels


def job_data(P, L, nu, ny, m, K):
    """As bench_peer.main: one random period of the inputs repeated, white outputs, seed 1."""
    rng = np.random.default_rng(1)
    bins = np.sort(rng.choice(np.arange(1, P // 2), size=L, replace=False))
    data = []
    for _ in range(m):
        x = rng.standard_normal((K * P, nu + ny))
        x[:, :nu] = np.tile(x[:P, :nu], (K, 1))
        data.append(x)
    return bins, data


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--min-seconds", type=float, default=2.0)
    ap.add_argument("--json", action="store_true", help="one JSON object instead of the table")
    a = ap.parse_args()
    P, L, nu, ny, m, K = 4096, 200, 2, 2, 2, 64
    bins, data = job_data(P, L, nu, ny, m, K)
    peer = load_peer()
    peer.K_GLOBAL = K
    t_peer, c_peer, n_peer = best_time(lambda: peer.frf_job(data, bins, nu, ny), a.min_seconds)
    t_msid, c_msid, n_msid = best_time(lambda: msid.frf(data, period=P, lines=bins, n_inputs=nu), a.min_seconds)
    # the shares: the compiled call (the job, its FRF as NumPy arrays), then msid.FRF of those arrays
    ext = msid.compute._ext()
    opts = {"period": P, "lines": [int(b) for b in bins], "direct": False}
    names, cols = [f"records[{k}]" for k in range(m)], [[str(c + 1) for c in range(nu + ny)]] * m
    t_ext, c_ext, _ = best_time(lambda: ext.frf(data, names, cols, [nu] * m, opts, None), a.min_seconds)
    res = ext.frf(data, names, cols, [nu] * m, opts, None)
    t_conv, c_conv, _ = best_time(lambda: msid.compute._result(res, "bench"), a.min_seconds)
    # per call: 1x1, P = 16, 2 periods, 1 line
    rng = np.random.default_rng(2)
    u = np.tile(rng.standard_normal(16), 2)
    tiny = np.ascontiguousarray(np.column_stack([u, u + 0.1 * rng.standard_normal(32)]))
    t_tiny, c_tiny, n_tiny = best_time(lambda: msid.frf(tiny, period=16, lines=[1], n_inputs=1), a.min_seconds)
    tiny_args = ([tiny], ["records[0]"], [["1", "2"]], [1], {"period": 16, "lines": [1], "direct": False}, None)
    t_tiny_ext, c_tiny_ext, _ = best_time(lambda: ext.frf(*tiny_args), a.min_seconds)
    floor = fftw_floor(P, nu + ny, m * K)
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    res = {"job": f"{ny}x{nu}, P = {P}, {K} periods, {m} experiments, {L} lines",
           "peer_s": t_peer, "peer_cpu_s": c_peer, "msid_frf_s": t_msid, "msid_frf_cpu_s": c_msid,
           "ext_s": t_ext, "ext_cpu_s": c_ext, "to_frf_s": t_conv, "speedup": t_peer / t_msid,
           "tiny_call_s": t_tiny, "tiny_call_cpu_s": c_tiny, "tiny_ext_s": t_tiny_ext, "tiny_ext_cpu_s": c_tiny_ext,
           "reps": {"peer": n_peer, "msid": n_msid, "tiny": n_tiny},
           "fftw_floor_one_core_s": floor,
           "cpu": cpu, "numpy": np.__version__, "python": platform.python_version()}
    if a.json:
        print(json.dumps(res))
        return
    print(f"msid.frf vs the NumPy peer ({res['job']}), best of >= {a.min_seconds:g} s each, {cpu}")
    print("                                          wall ms    CPU ms (all threads)")
    print(f"  NumPy peer (bench_peer.frf_job)        {1e3 * t_peer:8.2f}  {1e3 * c_peer:8.2f}")
    print(f"  msid.frf -> msid.FRF                   {1e3 * t_msid:8.2f}  {1e3 * c_msid:8.2f}   "
          f"({t_peer / t_msid:.2f}x the peer's wall time)")
    print(f"    the job and its arrays (_msid.frf)   {1e3 * t_ext:8.2f}  {1e3 * c_ext:8.2f}")
    print(f"    the arrays to msid.FRF               {1e3 * t_conv:8.2f}  {1e3 * c_conv:8.2f}")
    if floor is not None:
        print(f"  FFTW's transforms of the record alone   {1e3 * floor:8.2f} one core, {0.5e3 * floor:.2f} on two "
              f"(10x the peer needs {0.1e3 * t_peer:.2f})")
    print(f"  msid.frf on a tiny record, per call    {1e6 * t_tiny:8.1f} us {1e6 * c_tiny:6.1f} us")
    print(f"    of which _msid.frf                   {1e6 * t_tiny_ext:8.1f} us {1e6 * c_tiny_ext:6.1f} us")


if __name__ == "__main__":
    import warnings
    warnings.simplefilter("ignore", msid.NoteWarning)   # the peer's white outputs flag a period now and then
    main()
