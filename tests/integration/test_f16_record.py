"""The real F-16 ground-vibration record (../shared/data/f16-gvt-level3: 1 force, 3 accelerations, 267
lines in 2-15 Hz, 8 periods after the first, nonlinear distortion: every linear model has p = 0) through
`msid frf` and the stable pole-residue ml, against sdypy-EMA's LSCF as the independent modal peer:

- a pole the stable fit holds on the stability bound is marked so (model file, `msid modes`, Python) and
  its damping gets no standard deviation;
- the default fit (`--order auto`) chooses an order whose model holds no pole on the bound and finds
  every mode LSCF finds stably over its orders 30-60, the weak one near 12.3 Hz included;
- ml started from LSCF's poles ends where the default fit ends: LSCF's placement is no lower minimum
  of the weighted cost.

The record is found at $MSID_SHARED_DATA or ../shared/data beside the source tree; without it these
tests are skipped (they need the real measurement, which the repository does not hold)."""
import json
import lzma
import math
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

import helpers as h
from msid_peers.lscf_peer import lscf_stable_modes   # sdypy-EMA's LSCF over its orders 30-60

REC = "f16-gvt-level3/gvt_fullms_level3.csv.xz"
FRF_ARGS = ["--period", 8192, "--lines", "41:307", "--skip-periods", 1, "--fs", 400]
FIT = ["fit", "--method", "ml", "--domain", "ct"]


def shared_data():
    d = os.environ.get("MSID_SHARED_DATA")
    return Path(d) if d else h.ROOT.parent / "shared" / "data"


@pytest.fixture(scope="module")
def frf(tmp_path_factory):
    src = shared_data() / REC
    if not src.exists():
        pytest.skip(f"the F-16 record is not at {src} (set MSID_SHARED_DATA)")
    d = tmp_path_factory.mktemp("f16")
    csv = d / "gvt.csv"
    with lzma.open(src, "rb") as f, open(csv, "wb") as g:
        shutil.copyfileobj(f, g)
    out = d / "frf.json"
    h.run_ok("frf", *FRF_ARGS, "--experiment", csv, "-o", out)
    return out


def fit(frf, out, *args):
    r = h.run(*FIT, *args, frf, "-o", out, timeout=1200)
    assert r.returncode in (0, 3), r.stderr   # 3: not converged, the best iterate written
    doc = h.load_json(out)
    h.validate(doc, "msid-model-1")
    return r, doc


def modes(doc):
    return doc["modes"]["modes"]


def write_start(path, poles_hz_zeta, ny=3):
    """A CT msid-model/1 file holding only poles (fn Hz, zeta): a start for --start."""
    poles = []
    for fn, z in poles_hz_zeta:
        w = 2 * math.pi * fn
        poles.append({"re": -z * w, "im": w * math.sqrt(max(1 - z * z, 0.0))})
    n = 2 * len(poles)
    A = np.zeros((n, n))
    for k, p in enumerate(poles):
        A[2 * k, 2 * k] = A[2 * k + 1, 2 * k + 1] = p["re"]
        A[2 * k, 2 * k + 1], A[2 * k + 1, 2 * k] = p["im"], -p["im"]
    doc = {"format": "msid-model/1", "domain": "ct", "order": n, "n_inputs": 1, "n_outputs": ny, "A": A.tolist(),
           "B": [[1.0]] * n, "C": [[1.0] * n] * ny, "D": [[0.0]] * ny, "pole_residue": {"poles": poles}}
    Path(path).write_text(json.dumps(doc))


def test_pole_on_the_bound_has_no_sd(frf, tmp_path):
    """Order 20: the stable fit holds a pole on the stability bound (the data push it out:
    the distortion of the nonlinear mode at 7.26 Hz). It is marked in the file, in `msid modes` and in
    Python, and its damping has no standard deviation; every other mode keeps its sd. Before, the
    constraint left such poles at zeta ~ 1e-10..1e-5 with a delta-method sd as if they were estimates."""
    out = tmp_path / "m20.json"
    _, doc = fit(frf, out, "--order", 20)
    ms = modes(doc)
    tiny = [m for m in ms if not m["real_pole"] and m["zeta"] < 1e-4]
    assert tiny and all(m["sd_zeta"] is None for m in tiny), tiny   # a damping this small is the constraint's
    held = doc["parameters"]["at_bound"]
    assert held, "order 20 of this record holds a pole on the bound"
    pr = doc["pole_residue"]["poles"]
    assert [f"p{k + 1}" for k, p in enumerate(pr) if p["at_bound"]] == held
    marked = [m for m in ms if m["at_bound"]]
    assert len(marked) == len(held)
    for m in ms:
        if m["real_pole"]:
            continue
        if m["at_bound"]:
            assert m["sd_zeta"] is None and m["zeta"] < 1e-6, m
            assert m["sd_fn"] is not None and m["sd_fn"] >= 0
        else:
            # no pole near the boundary passes for an estimate: a damping this small is the constraint's
            assert m["zeta"] > 1e-4 and m["sd_zeta"] > 0, m
    r = h.run_ok("modes", out)
    rows = [ln for ln in r.stdout.splitlines() if "ON THE STABILITY BOUND" in ln and ln[:1].isdigit()]
    assert len(rows) == len(held)
    assert all(ln.split()[4] == "-" for ln in rows), rows   # the sd(zeta) column
    # Python: the model file and msid modes in process
    from msid.files import Model
    mo = Model(doc, out)
    assert len(mo.poles_at_bound) == len(held)
    assert all(abs(p.real) < 1e-6 * abs(p) for p in mo.poles_at_bound)
    try:
        import msid
        md = msid.modes(out)
    except ImportError:   # the compiled extension is not built here: the file's side is checked above
        return
    assert len(md.at_bound) == len(held) and all(m["sd_zeta"] is None for m in md.at_bound)


def test_default_fit_finds_the_weak_mode(frf, tmp_path):
    """The default fit (`--order auto`) chooses an order whose stable model holds no pole on the bound
    and no pole pair at a damping the data cannot give, and finds every mode LSCF finds stably over its
    orders 30-60 on the same FRF, the weak in-band one near 12.3 Hz included (LSCF's unweighted
    estimate sits 0.05-0.1 Hz below the weighted one: test_lscf_poles_are_no_better_minimum). Before,
    the elbow rule chose order 12: no mode near 5.1 or 12.3 Hz, a pair at 19.8 Hz on the bound."""
    out = tmp_path / "auto.json"
    r, doc = fit(frf, out)
    sel = doc["order_selection"]
    ms = [m for m in modes(doc) if not m["real_pole"]]
    peer = lscf_stable_modes(frf)
    print("LSCF stable modes:", [(round(a, 3), round(100 * z, 2)) for a, z in peer])
    print("msid default:", sel["chosen"], [(round(m["fn"], 3), round(100 * m["zeta"], 2)) for m in ms])
    assert all(m["zeta"] > 1e-4 for m in ms), ms
    assert len(peer) >= 6
    assert any(12.0 < a < 12.5 for a, _ in peer), peer
    for a, z in peer:
        near = [m for m in ms if abs(m["fn"] - a) <= 0.01 * a]
        assert near, f"LSCF's mode at {a:.3f} Hz (zeta {100 * z:.2f}%) is not in the default fit"
        assert 0.2 * z < near[0]["zeta"] < 5 * z
    weak = [m for m in ms if 12.0 < m["fn"] < 12.5]
    assert len(weak) == 1 and 0.003 < weak[0]["zeta"] < 0.03 and weak[0]["identified"], weak
    assert sel["rule"] == "elbow" and doc["parameters"]["at_bound"] == [], (sel["chosen"], doc["parameters"]["at_bound"])
    assert all(m["sd_zeta"] is not None for m in ms)


def test_lscf_poles_are_no_better_minimum(frf, tmp_path):
    """The weighted costs of the two estimators' poles on the same FRF: LSCF's in-band modes (its
    stabilised poles) with the residues by weighted least squares cost more than msid's fit of the same
    order, and ml started from them ends at the default start's cost: LSCF's placement, its 12.3 Hz
    mode's frequency included, is not a lower minimum of the cost ml minimises that the default misses."""
    peer = lscf_stable_modes(frf)
    extra = [(0.5, 0.2), (19.8, 0.02)]   # a pair below and one above the band, as msid's own fit has
    start = tmp_path / "lscf.json"
    write_start(start, peer + extra)
    n = 2 * len(peer + extra)
    _, own = fit(frf, tmp_path / "own.json", "--order", n)
    _, ls0 = fit(frf, tmp_path / "ls0.json", "--order", n, "--start", start, "--max-iter", 0)
    _, ls = fit(frf, tmp_path / "ls.json", "--order", n, "--start", start)
    c = lambda d: d["cost"].get("fit_cost_smoothed_weights", d["cost"]["value"])   # the cost ml minimises
    print(f"order {n}: msid {c(own):.6g}, LSCF poles + LS residues {c(ls0):.6g}, ml from LSCF's poles {c(ls):.6g}")
    assert c(ls0) > 1.2 * c(own)
    assert c(ls) >= c(own) * (1 - 1e-6)
    near = lambda d: [m["fn"] for m in modes(d) if 12.0 < m["fn"] < 12.5]
    assert len(near(ls)) == 1 and abs(near(ls)[0] - near(own)[0]) < 0.01


def test_bench_modal_runs(frf):
    """`msid bench fit --only modal FRF` times the default order scan as a process and prints its choice
    (the figures of docs/benchmarks.md); without the FRF it says what it needs (exit 2)."""
    r = h.run("bench", "fit", "--only", "modal", frf, "--no-peer", timeout=1200)
    assert r.returncode == 0, r.stderr
    row = [ln for ln in r.stdout.splitlines() if "msid fit --order auto" in ln]
    assert len(row) == 1 and "s CPU" in row[0] and "order 18 (elbow)" in row[0], r.stdout
    assert "12.3" in row[0]
    r = h.run("bench", "fit", "--only", "modal")
    assert r.returncode == 2 and "give one FRF file" in r.stderr, (r.returncode, r.stderr)
