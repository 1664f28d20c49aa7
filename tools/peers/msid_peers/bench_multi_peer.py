"""Peer of `msid bench fit --only multi`: the same multiple-experiment output-error ML
solved the way a general tool does it (the prediction-error approach of the System
Identification Toolbox for multi-experiment data): SciPy least_squares (Levenberg-Marquardt,
finite-difference Jacobian) over the poles AND every record's initial conditions, so the
number of unknowns grows with the number of records N.

usage: python3 bench_multi_peer.py in.json out.json
in.json: {"order": n, "sets": [{"records": [[y...], ...], "start": [alpha...]}, ...]}
out.json: {"scipy": version, "results": [{"alpha": [...], "seconds": t, "nfev": k}, ...]}
Model: a(q^-1) y = 0 with pre-initial values y(-1..-n) (scipy.signal.lfiltic), a = [1, alpha].
"""
import json
import sys
import time

import numpy as np
import scipy
from scipy.optimize import least_squares
from scipy.signal import lfilter, lfiltic


def fit(records, alpha0):
    n = len(alpha0)
    ys = [np.asarray(r, dtype=float) for r in records]
    zeros = [np.zeros(y.size) for y in ys]

    def resid(p):
        a = np.concatenate([[1.0], p[:n]])
        out = []
        for i, y in enumerate(ys):
            zi = lfiltic([1.0], a, p[n + i * n: n + (i + 1) * n])
            out.append(y - lfilter([1.0], a, zeros[i], zi=zi)[0])
        return np.concatenate(out)

    # initial conditions from the start poles by linear least squares per record (a fair start)
    a0 = np.concatenate([[1.0], alpha0])
    p0 = [np.asarray(alpha0, dtype=float)]
    for i, y in enumerate(ys):
        X = np.column_stack([lfilter([1.0], a0, zeros[i], zi=lfiltic([1.0], a0, np.eye(n)[k]))[0] for k in range(n)])
        p0.append(np.linalg.lstsq(X, y, rcond=None)[0])
    t0 = time.perf_counter()
    r = least_squares(resid, np.concatenate(p0), method="lm", xtol=1e-12, ftol=1e-12)
    return r.x[:n], time.perf_counter() - t0, int(r.nfev)


def main():
    cfg = json.load(open(sys.argv[1]))
    res = []
    for s in cfg["sets"]:
        a, t, k = fit(s["records"], s["start"])
        res.append({"alpha": a.tolist(), "seconds": t, "nfev": k})
    json.dump({"scipy": scipy.__version__, "numpy": np.__version__, "results": res}, open(sys.argv[2], "w"))


if __name__ == "__main__":
    main()
