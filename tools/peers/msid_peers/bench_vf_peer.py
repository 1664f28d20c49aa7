"""Vector-fitting peer for `msid bench fit`: writes the simulated
structures of msid.structures (SISO, 1x3, 2x3 accelerances, 12 modes, 267 lines,
and a 10-mode SISO for the order-20 timing) as msid-frf/1 files, fits each with
scikit-rf's VectorFitting at the same order, and reports its weighted cost
(eq. 40 on the files' covariances), its relative error against the true FRF
and its time, with the true FRF at the lines for msid's side of the table.

With --runs N (N >= 1) also the Monte Carlo of `msid bench fit --only 3 --runs N`: N noise
realisations (seeds 0..N-1) of the SISO 10- and 12-mode structures at their nominal order 2K and
at 2K - 2 (one mode of each is below the noise: peak/noise 0.1 and 0.2, so 2K - 2 is the order the
data identify), and of the 2x3 12-mode structure at 24; vector fitting's cost and error per run.

Usage: python3 bench_vf_peer.py DIR OUT.json [--runs N]
"""
import json
import sys
import time

import numpy as np

from msid_peers import structures as S

CASES = [("siso", 12), ("1x3", 12), ("2x3", 12), ("siso", 10)]
SEED = 2
# Monte Carlo cases: (kind, modes, orders below the nominal 2 * modes)
MC_CASES = [("siso", 10, 0), ("siso", 10, 2), ("siso", 12, 0), ("siso", 12, 2), ("2x3", 12, 0)]


def _g0_json(G0):
    return {"re": G0.real.reshape(len(G0), -1, order="F").tolist(), "im": G0.imag.reshape(len(G0), -1, order="F").tolist()}


def monte_carlo(d, runs):
    """One entry per MC case: the runs' files (written once per kind/modes/seed), vector fitting's
    weighted cost, error against the truth and time, and the true FRF at the lines."""
    out, files = [], {}
    for kind, modes, less in MC_CASES:
        st = S.structure(kind, SEED, n_modes=modes)
        n = S.order(st) - less
        case = {"kind": kind, "modes": modes, "order": n, "nominal_order": S.order(st), "runs": []}
        for seed in range(runs):
            key = (kind, modes, seed)
            if key not in files:
                files[key] = S.write(f"{d}/mc-{kind}-{modes}-{seed}.json", S.frf_doc(st, seed))
            om, G, C = S.load_frf(files[key])
            G0 = S.frf(st, 1j * om)
            t0 = time.perf_counter()
            Gvf, _ = S.vector_fit(files[key], n)
            case["runs"].append({"seed": seed, "file": str(files[key]), "vf_seconds": time.perf_counter() - t0,
                                 "vf_cost": S.weighted_cost(G, Gvf, C), "vf_rel_error": S.rel_error(Gvf, G0),
                                 "vf_fit_error": S.rel_error(Gvf, G),   # to the measured FRF (scikit-rf's measure)
                                 "vf_cost_pooled": S.weighted_cost(G, Gvf, S.pooled_cov(files[key])),
                                 "G0": _g0_json(G0)})
        out.append(case)
    return out


def main():
    d, out = sys.argv[1], sys.argv[2]
    runs = int(sys.argv[sys.argv.index("--runs") + 1]) if "--runs" in sys.argv else 0
    import skrf
    res = []
    for kind, modes in CASES:
        st = S.structure(kind, SEED, n_modes=modes)
        path = S.write(f"{d}/{kind}-{modes}.json", S.frf_doc(st, SEED))
        om, G, C = S.load_frf(path)
        G0 = S.frf(st, 1j * om)
        n = S.order(st)
        t0 = time.perf_counter()
        Gvf, _ = S.vector_fit(path, n)
        t = time.perf_counter() - t0
        res.append({"kind": kind, "modes": modes, "file": str(path), "order": n, "vf_seconds": t,
                    "vf_cost": S.weighted_cost(G, Gvf, C), "vf_rel_error": S.rel_error(Gvf, G0),
                    "vf_cost_pooled": S.weighted_cost(G, Gvf, S.pooled_cov(path)),
                    "dynamic_range_db": S.dynamic_range_db(G0),
                    "G0": _g0_json(G0)})
    json.dump({"cases": res, "monte_carlo": monte_carlo(d, runs) if runs > 0 else [], "skrf": skrf.__version__,
               "numpy": np.__version__}, open(out, "w"))


if __name__ == "__main__":
    main()
