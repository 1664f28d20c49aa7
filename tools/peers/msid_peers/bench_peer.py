"""NumPy peer for `msid bench frf`: the same job as the msid core, written the
way a competent NumPy user would (vectorised): per-period rfft, pick the lines,
mean and sample covariance across periods per experiment, least-squares FRF per
line, and both covariance forms.

Usage: python3 bench_peer.py P L NU NY M K [min_seconds]
Prints one JSON object: {"sec_per_job": best time of one whole job}.
"""
import json
import sys
import time

import numpy as np


def frf_job(data, bins, nu, ny):
    """data: list over experiments of arrays (K*P, nu+ny). Returns G, cov_a, cov_b."""
    m = len(data)
    P = data[0].shape[0] // K_GLOBAL
    means, scat, Ks = [], [], []
    for x in data:
        K = x.shape[0] // P
        X = np.fft.rfft(x[: K * P].reshape(K, P, -1), axis=1)[:, bins, :]   # K x L x C
        mu = X.mean(axis=0)                                                  # L x C
        D = X - mu
        S = np.einsum("klc,kld->lcd", D, D.conj())                          # L x C x C scatter
        means.append(mu)
        scat.append(S)
        Ks.append(K)
    U = np.stack([mu[:, :nu] for mu in means], axis=2)                      # L x nu x m
    Y = np.stack([mu[:, nu:] for mu in means], axis=2)                      # L x ny x m
    UH = U.conj().transpose(0, 2, 1)                                        # L x m x nu
    M = U @ UH                                                              # L x nu x nu
    W = np.linalg.solve(M, U).conj().transpose(0, 2, 1)                     # L x m x nu (M Hermitian)
    G = Y @ W                                                               # L x ny x nu
    B = np.concatenate([-G, np.broadcast_to(np.eye(ny), G.shape[:1] + (ny, ny))], axis=2)
    L = len(bins)
    g = nu * ny
    cov_a = np.zeros((L, g, g), complex)
    cov_b = np.zeros((L, g, g), complex)
    dofk = sum(K - 1 for K in Ks)
    Sp = sum(S[:, nu:, nu:] for S in scat) / dofk
    for e in range(m):
        Se = B @ scat[e] @ B.conj().transpose(0, 2, 1) / ((Ks[e] - 1) * Ks[e])
        ww = np.einsum("lj,lk->ljk", W[:, e, :], W[:, e, :].conj())        # L x nu x nu
        cov_a += np.einsum("ljk,lab->ljakb", ww, Se).reshape(L, g, g)
        cov_b += np.einsum("ljk,lab->ljakb", ww, Sp / Ks[e]).reshape(L, g, g)
    return G, cov_a, cov_b


K_GLOBAL = 1


def main():
    global K_GLOBAL
    P, L, nu, ny, m, K = (int(a) for a in sys.argv[1:7])
    min_s = float(sys.argv[7]) if len(sys.argv) > 7 else 0.5
    K_GLOBAL = K
    rng = np.random.default_rng(1)
    bins = np.sort(rng.choice(np.arange(1, P // 2), size=L, replace=False))
    data = []
    for _ in range(m):          # periodic inputs (one random period repeated), noisy outputs
        x = rng.standard_normal((K * P, nu + ny))
        x[:, :nu] = np.tile(x[:P, :nu], (K, 1))
        data.append(x)
    frf_job(data, bins, nu, ny)                                             # warm-up
    best = float("inf")
    t_end = time.perf_counter() + min_s
    reps = 0
    while reps < 3 or time.perf_counter() < t_end:
        t0 = time.perf_counter()
        frf_job(data, bins, nu, ny)
        best = min(best, time.perf_counter() - t0)
        reps += 1
    print(json.dumps({"sec_per_job": best, "reps": reps, "numpy": np.__version__}))


if __name__ == "__main__":
    main()
