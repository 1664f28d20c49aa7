"""NumPy peer of the crest factors of a multisine design (`msid bench crest`): each input of each
experiment synthesised with one inverse real FFT (numpy.fft.irfft) from the design's DT coefficients,
crest = max|u| / rms(u). Written independently of lib/src/msid_design.c.

    u(n) = sum_l Re(c_l exp(j 2 pi b_l n / P))   (a DC line: Re(c_l))

Command line: python3 crest_peer.py FILE P L M NU
FILE: L uint32 bins, then M*NU*L complex128 coefficients (index (e*NU + i)*L + l).
Prints JSON: the crest factors [M*NU], the best time of 3 (wall and CPU seconds), NumPy's version.
"""
import json
import sys
import time

import numpy as np


def crest_factors(P, bins, coef):
    """coef: (M*NU, L) complex; returns the crest factor of each row."""
    X = np.zeros((coef.shape[0], P // 2 + 1), complex)
    dc = bins == 0
    X[:, bins[~dc]] = coef[:, ~dc] * (P / 2.0)
    X[:, 0] = np.real(coef[:, dc]).sum(axis=1) * P
    u = np.fft.irfft(X, n=P, axis=1)
    return np.max(np.abs(u), axis=1) / np.sqrt(np.mean(u * u, axis=1))


def main():
    path, P, L, M, NU = sys.argv[1], *map(int, sys.argv[2:6])
    raw = open(path, "rb").read()
    bins = np.frombuffer(raw, np.uint32, L).astype(np.int64)
    coef = np.frombuffer(raw, np.complex128, M * NU * L, offset=4 * L).reshape(M * NU, L)
    best, cpu = 1e300, 1e300
    for _ in range(3):
        t0, c0 = time.perf_counter(), time.process_time()
        cf = crest_factors(P, bins, coef)
        best, cpu = min(best, time.perf_counter() - t0), min(cpu, time.process_time() - c0)
    print(json.dumps({"crest": cf.tolist(), "sec": best, "cpu": cpu, "numpy": np.__version__}))


if __name__ == "__main__":
    main()
