"""NumPy peer of the local polynomial method (msid frf --method lpm), written
independently of tools/est/lpm.cpp: the full local least-squares problem with
the transient columns kept explicitly (Pintelon et al. 2010, Part I), solved in
batches of bins with numpy.linalg. Used by the integration tests (agreement with
the CLI) and by `msid bench lpm` (speed).

    Y_e(k+r) = sum_s (G_s r^s) U_e(k+r) + sum_s T_{e,s} r^s + V_e(k+r),  r in window
    q = m(2W+1) - (R+1)(nu+m),  C_v = Vres Vres^H / q,  Cov vec G = M^T kron C_v

Command line (bench): python3 lpm_peer.py FILE N NU NY R W
FILE holds N rows of nu+ny float64 (one experiment); prints JSON with the time and
G at every 1000th bin.
"""
import json
import sys
import time

import numpy as np


def lpm(records, nu, ny, R=2, W=None, k_lo=1, k_hi=None, chunk=20000):
    """records: list of (N, nu+ny) arrays (equal N). Returns dict with bins, G
    (nb, ny, nu), cov (nb, g, g) in the column-stacked vec convention, noise (nb, ny, ny), q."""
    m = len(records)
    N = records[0].shape[0]
    X = [np.fft.rfft(np.asarray(r, dtype=float), axis=0) for r in records]   # (N/2+1, nu+ny)
    if W is None:
        W = 1
        while m * (2 * W + 1) - (R + 1) * (nu + m) < ny + 4:
            W += 1
    q = m * (2 * W + 1) - (R + 1) * (nu + m)
    assert q > 0
    kmax = (N - 1) // 2
    k_hi = kmax if k_hi is None else k_hi
    n = 2 * W + 1
    npar = (R + 1) * (nu + m)
    bins = np.arange(k_lo, k_hi + 1)
    G = np.empty((bins.size, ny, nu), complex)
    cov = np.empty((bins.size, ny * nu, ny * nu), complex)
    noise = np.empty((bins.size, ny, ny), complex)
    for c0 in range(0, bins.size, chunk):
        k = bins[c0:c0 + chunk]
        w0 = np.clip(k - W, 1, kmax - 2 * W)
        idx = w0[:, None] + np.arange(n)[None, :]           # (b, n)
        rho = (idx - k[:, None]) / W                          # (b, n)
        pw = rho[:, None, :] ** np.arange(R + 1)[None, :, None]   # (b, R+1, n)
        b = k.size
        K = np.zeros((b, npar, m * n), complex)
        Yw = np.empty((b, ny, m * n), complex)
        for e in range(m):
            cols = slice(e * n, (e + 1) * n)
            Ue = X[e][idx, :nu]                                # (b, n, nu)
            # G columns: parameter (s, j) -> row s*nu + j; T columns after
            for s in range(R + 1):
                K[:, s * nu:(s + 1) * nu, cols] = (pw[:, s, :, None] * Ue).transpose(0, 2, 1)
                K[:, (R + 1) * nu + e * (R + 1) + s, cols] = pw[:, s, :]
            Yw[:, :, cols] = X[e][idx, nu:].transpose(0, 2, 1)
        KH = np.conj(K.transpose(0, 2, 1))
        A = K @ KH
        Ainv = np.linalg.inv(A)
        Th = Yw @ KH @ Ainv                                    # (b, ny, npar)
        V = Yw - Th @ K
        Cv = V @ np.conj(V.transpose(0, 2, 1)) / q
        M = Ainv[:, :nu, :nu]
        G[c0:c0 + b] = Th[:, :, :nu]
        noise[c0:c0 + b] = Cv
        # kron(M^T, C_v): element (j ny + i, J ny + I) = M[J, j] C_v[i, I]
        cov[c0:c0 + b] = np.einsum("bjJ,biI->bjiJI", M.transpose(0, 2, 1), Cv).reshape(b, nu * ny, nu * ny)
    return {"bins": bins, "G": G, "cov": cov, "noise": noise, "q": q, "W": W}


def main(argv):
    path, N, nu, ny, R, W = argv[1], int(argv[2]), int(argv[3]), int(argv[4]), int(argv[5]), int(argv[6])
    rec = np.fromfile(path, dtype=np.float64).reshape(N, nu + ny)
    best = cpu = float("inf")
    out = None
    for _ in range(2):
        t0, c0 = time.perf_counter(), time.process_time()
        out = lpm([rec], nu, ny, R, W, chunk=20000)
        best = min(best, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    sel = out["G"][::1000]
    print(json.dumps({"sec": best, "cpu": cpu, "numpy": np.__version__, "bins": out["bins"][::1000].tolist(),
                      "G_re": sel.real.ravel().tolist(), "G_im": sel.imag.ravel().tolist()}))


if __name__ == "__main__":
    main(sys.argv)
