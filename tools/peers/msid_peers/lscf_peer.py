"""Modal peer of `msid fit --method ml --order auto` on a structure's FRF: sdypy-EMA's LSCF (the
least-squares complex frequency-domain estimator, its own z-domain common-denominator model on
0..f_max of the FRF's lines) over its polynomial orders, and the modes it finds stably over them.

Usage: python3 lscf_peer.py FRF.json [--orders 30:60] [--lower HZ] [-o OUT.json]
Prints the stable modes (fn Hz, zeta); -o writes {"modes": [[fn, zeta], ...], "orders": [a, b]}.
Every output of input 1 enters the fit (sdypy-EMA takes one reference).
"""
import json
import sys

import numpy as np


def frf_lines(path):
    """(freq_hz, G[L, ny]) of input 1 of an msid-frf/1 file."""
    with open(path, "r", encoding="utf-8") as f:
        d = json.load(f)
    freq = np.array([ln["freq_hz"] for ln in d["lines"]], float)
    G = np.array([(np.asarray(ln["G"]["re"]) + 1j * np.asarray(ln["G"]["im"]))[:, 0] for ln in d["lines"]])
    return freq, G


def lscf_stable_modes(path, orders=range(30, 61, 2), lower=None, share=0.8, max_zeta=0.1):
    """The modes in the FRF's band with 0 < zeta < max_zeta that recur within 1% in frequency at >= share
    of the polynomial orders (LSCF's stabilisation), as sorted [(fn, median zeta)]."""
    from sdypy import EMA
    freq, G = frf_lines(path)
    lo = float(freq[0]) if lower is None else float(lower)
    band = (lo, float(freq[-1]))
    m = EMA.Model(frf=G.T, freq=freq, lower=lo, upper=float(freq[-1]), pol_order_high=max(orders) // 2,
                  frf_form="accelerance")
    m.get_poles("lscf", show_progress=False)
    per = []
    for j in orders:
        fp, xi = np.asarray(m.pole_freq[j // 2 - 1]), np.asarray(m.pole_xi[j // 2 - 1])
        per.append([(a, b) for a, b in zip(fp, xi) if band[0] <= a <= band[1] and 0 < b < max_zeta])
    found = []
    for a, _ in per[len(per) // 2]:
        hits = [[(x, z) for x, z in p if abs(x - a) <= 0.01 * a] for p in per]
        if sum(1 for hh in hits if hh) >= share * len(per) and not any(abs(a - b) <= 0.01 * a for b, _ in found):
            found.append((float(a), float(np.median([z for hh in hits for _, z in hh]))))
    return sorted(found)


def main(argv):
    if not argv or argv[0].startswith("-"):
        print(__doc__, file=sys.stderr)
        return 2
    path, a, b, lower, out = argv[0], 30, 60, None, None
    i = 1
    while i < len(argv):
        if argv[i] == "--orders":
            a, b = (int(x) for x in argv[i + 1].split(":"))
        elif argv[i] == "--lower":
            lower = float(argv[i + 1])
        elif argv[i] == "-o":
            out = argv[i + 1]
        else:
            print(f"lscf_peer: unknown option {argv[i]}", file=sys.stderr)
            return 2
        i += 2
    modes = lscf_stable_modes(path, range(a, b + 1, 2), lower)
    for fn, z in modes:
        print(f"{fn:10.4f} Hz  zeta {100 * z:6.3f} %")
    if out:
        with open(out, "w", encoding="utf-8") as f:
            json.dump({"modes": modes, "orders": [a, b]}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
