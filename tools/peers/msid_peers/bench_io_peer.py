"""Peer for `msid bench io`: read the same experiment files as `msid frf` and
do the same FRF job, the way a competent Python user would: pandas.read_csv
(C engine) for CSV, numpy.load for .npy, scipy.io.loadmat for .mat, then the
vectorised NumPy FRF job of bench_peer.py (per-period rfft, mean, covariance,
batched LS with both covariance forms).

Usage: python3 bench_io_peer.py DIR P BINS_FILE M MIN_SECONDS
DIR holds e1.csv .. eM.csv, e1.npy .., e1.mat ..; prints one JSON object with
the best wall and CPU time of one whole job (read + FRF) per format, timed
inside Python (the interpreter's start-up and imports are not counted).
"""
import json
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_peer  # noqa: E402


def best_of(fn, min_s):
    """(best wall time, best CPU time of the process) of fn() over >= 3 runs lasting >= min_s."""
    fn()
    best, cpu, reps, t_end = float("inf"), float("inf"), 0, time.perf_counter() + min_s
    while reps < 3 or time.perf_counter() < t_end:
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        best = min(best, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
        reps += 1
    return best, cpu


def main():
    d, P, bins_file, m, min_s = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4]), float(sys.argv[5])
    bins = np.array([int(b) for b in open(bins_file).read().split(",")])
    nu = ny = 2

    def job(load):
        data = [load(os.path.join(d, f"e{e + 1}")) for e in range(m)]
        bench_peer.K_GLOBAL = data[0].shape[0] // P
        return bench_peer.frf_job(data, bins, nu, ny)

    out = {"numpy": np.__version__}
    try:
        import pandas as pd
        out["pandas"] = pd.__version__
        out["csv"], out["csv_cpu"] = best_of(
            lambda: job(lambda p: pd.read_csv(p + ".csv", engine="c").to_numpy(np.float64)), min_s)
    except ImportError:
        out["csv_note"] = "pandas missing"
    out["npy"], out["npy_cpu"] = best_of(lambda: job(lambda p: np.load(p + ".npy")), min_s)
    try:
        import scipy
        import scipy.io
        out["scipy"] = scipy.__version__

        def loadmat(p):
            v = scipy.io.loadmat(p + ".mat")
            return np.column_stack([v["u1"].ravel(), v["u2"].ravel(), v["y1"].ravel(), v["y2"].ravel()])
        out["mat"], out["mat_cpu"] = best_of(lambda: job(loadmat), min_s)
    except ImportError:
        out["mat_note"] = "scipy missing"
    print(json.dumps(out))


if __name__ == "__main__":
    main()
