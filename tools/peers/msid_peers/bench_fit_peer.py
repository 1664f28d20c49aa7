"""NumPy peer for `msid bench fit`: a straightforward implementation of the
weighted frequency-domain subspace algorithm (McKelvey et al. 1996; Pintelon
2002 Algorithm 1, discrete time) on msid-frf/1 files, with the same block-row
scan over r in [1.5 n, 6 n] minimising the weighted cost (35).

Usage: python3 bench_fit_peer.py ORDER OUT.json FRF1.json [FRF2.json ...] [--r R]
(--r R: one fixed block-row count instead of the scan)
Writes {"models": [{"A","B","C","D"} per file], "sec_per_fit": [...]}.
"""
import json
import math
import sys
import time

import numpy as np


def load(path):
    d = json.load(open(path))
    ny, nu = d["n_outputs"], d["n_inputs"]
    z, G, C = [], [], []
    for ln in d["lines"]:
        z.append(np.exp(2j * math.pi * ln["freq"]))
        G.append(np.asarray(ln["G"]["re"]) + 1j * np.asarray(ln["G"]["im"]))
        C.append(np.asarray(ln["cov"]["re"]) + 1j * np.asarray(ln["cov"]["im"]))
    return ny, nu, np.array(z), np.array(G), np.array(C)


def fit(ny, nu, z, G, Cov, n, r):
    F = len(z)
    W = z[:, None] ** np.arange(r)[None, :]                       # F x r
    # Z = [U; Y], columns per line and input; real and imaginary parts side by side
    U = np.zeros((r * nu, F * nu), complex)
    Y = np.zeros((r * ny, F * nu), complex)
    for l in range(F):
        for j in range(nu):
            e = np.zeros(nu); e[j] = 1
            U[:, l * nu + j] = np.kron(W[l], e)
            Y[:, l * nu + j] = np.kron(W[l], G[l][:, j])
    Z = np.vstack([np.hstack([U.real, U.imag]), np.hstack([Y.real, Y.imag])])
    R = np.linalg.qr(Z.T, mode="r")
    R22 = R[r * nu:, r * nu:]
    CY = np.zeros((r * ny, r * ny))
    for l in range(F):
        S = sum(Cov[l][j * ny:(j + 1) * ny, j * ny:(j + 1) * ny] for j in range(nu))
        CY += np.real(np.kron(np.outer(W[l], W[l].conj()), S))
    lam, V = np.linalg.eigh((CY + CY.T) / 2)
    keep = lam > 1e-13 * lam.max()
    sq = np.where(keep, np.sqrt(np.abs(lam)), 0)
    isq = np.where(keep, 1 / np.sqrt(np.where(keep, lam, 1)), 0)
    Ch, Cih = (V * sq) @ V.T, (V * isq) @ V.T
    Us, s, _ = np.linalg.svd(Cih @ R22.T)
    O = Ch @ Us[:, :n]
    A = np.linalg.lstsq(O[:(r - 1) * ny], O[ny:], rcond=None)[0]
    Cm = O[:ny]
    # B, D by weighted least squares (eq. 17)
    g = ny * nu
    rows, rhs = [], []
    for l in range(F):
        K = Cm @ np.linalg.inv(z[l] * np.eye(n) - A)
        Phi = np.hstack([np.kron(np.eye(nu), K), np.eye(g)])
        L = np.linalg.cholesky(Cov[l])
        Wp = np.linalg.solve(L, Phi)
        Wy = np.linalg.solve(L, G[l].flatten(order="F"))
        rows += [Wp.real, Wp.imag]
        rhs += [Wy.real, Wy.imag]
    th = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    B = th[:n * nu].reshape((n, nu), order="F")
    D = th[n * nu:].reshape((ny, nu), order="F")
    cost = 0.0
    for l in range(F):
        Gm = Cm @ np.linalg.solve(z[l] * np.eye(n) - A, B) + D
        e = np.linalg.solve(np.linalg.cholesky(Cov[l]), (G[l] - Gm).flatten(order="F"))
        cost += float(np.vdot(e, e).real)
    return cost, (A, B, Cm, D)


def main():
    args = sys.argv[1:]
    fixed_r = None
    if "--r" in args:
        i = args.index("--r")
        fixed_r = int(args[i + 1])
        del args[i:i + 2]
    n = int(args[0])
    out = args[1]
    models, times = [], []
    for path in args[2:]:
        ny, nu, z, G, C = load(path)
        F = len(z)
        rmax = int(math.floor(2 * F * nu / (nu + ny))) - 1
        t0 = time.perf_counter()
        best = None
        rs = [fixed_r] if fixed_r else range(max(n + 1, math.ceil(1.5 * n)), min(6 * n, rmax) + 1)
        for r in rs:
            c, m = fit(ny, nu, z, G, C, n, r)
            if best is None or c < best[0]:
                best = (c, m)
        times.append(time.perf_counter() - t0)
        A, B, Cm, D = best[1]
        models.append({"A": A.tolist(), "B": B.tolist(), "C": Cm.tolist(), "D": D.tolist()})
    json.dump({"models": models, "sec_per_fit": times, "numpy": np.__version__}, open(out, "w"))


if __name__ == "__main__":
    main()
