"""Vector-fitting peer for `msid bench fit` (issue 9): writes the simulated
structures of msid.structures (SISO, 1x3, 2x3 accelerances, 12 modes, 267 lines,
and a 10-mode SISO for the order-20 timing) as msid-frf/1 files, fits each with
scikit-rf's VectorFitting at the same order, and reports its weighted cost
(eq. 40 on the files' covariances), its relative error against the true FRF
and its time, with the true FRF at the lines for msid's side of the table.

Usage: python3 bench_vf_peer.py DIR OUT.json
"""
import json
import sys
import time

import numpy as np

from msid import structures as S

CASES = [("siso", 12), ("1x3", 12), ("2x3", 12), ("siso", 10)]
SEED = 2


def main():
    d, out = sys.argv[1], sys.argv[2]
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
                    "dynamic_range_db": S.dynamic_range_db(G0),
                    "G0": {"re": G0.real.reshape(len(om), -1, order="F").tolist(),
                           "im": G0.imag.reshape(len(om), -1, order="F").tolist()}})
    json.dump({"cases": res, "skrf": skrf.__version__, "numpy": np.__version__}, open(out, "w"))


if __name__ == "__main__":
    main()
