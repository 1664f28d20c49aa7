"""Detection lines: a cubic output nonlinearity shows at the non-excited odd
harmonics (p-value tiny); without it the p-values are unremarkable."""

import numpy as np
import pytest

import helpers as h
from msid_peers import frf_peer

P = 256
# odd multisine with every third odd line left out: 5, 11, 17, ... stay free
EXCITED = [k for k in range(1, 60, 2) if k % 6 != 5]
ODD_FREE = [k for k in range(5, 60, 6)]              # 5, 11, ..., 59
EVEN_FREE = [2, 4, 6, 8, 10, 20, 30, 40]           # a cubic puts nothing on even bins
K = 8
SIGMA = 0.02


def _plant():
    # SISO first-order low-pass, y(n) = 0.6 y(n-1) + 0.4 u(n-1) + 0.2 u(n)
    A, B, C, D = (np.array([[0.6]]), np.array([[1.0]]), np.array([[0.4]]), np.array([[0.2]]))
    return A, B, C, D


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("detect")
    h.run_ok("excite", "--period", P, "--lines", ",".join(map(str, EXCITED)), "--periods", K,
             "--amplitudes", 0.4, "--seed", 9, "--csv", d / "gen", "-o", d / "design.json")
    u = h.read_csv(d / "gen" / "e1.csv")["u1"][:, None]
    ylin = h.dt_simulate(_plant(), u, warmup=4, period=P)
    rng = np.random.default_rng(99)
    noise = SIGMA * rng.standard_normal(ylin.shape)
    out = {}
    for name, a in (("linear", 0.0), ("cubic", 0.3)):
        y = ylin + a * ylin ** 3 + noise
        p = d / f"{name}.csv"
        h.write_csv(p, h.experiment_columns(u, y))
        o = d / f"{name}.json"
        h.run_ok("frf", "--design", d / "design.json", "--experiment", p,
                 "--detect-lines", ",".join(map(str, ODD_FREE + EVEN_FREE)), "-o", o)
        doc = h.load_json(o)
        h.validate(doc, "msid-frf-1")
        out[name] = {"doc": doc, "path": p, "pv": {l["bin"]: l["p_value"][0] for l in doc["detection_lines"]}}
    out["dir"] = d
    return out


def test_cubic_shows_at_odd_free_lines(runs):
    pv = runs["cubic"]["pv"]
    for b in ODD_FREE:
        assert pv[b] < 1e-6, (b, pv[b])
    for b in EVEN_FREE:
        assert pv[b] > 1e-4, (b, pv[b])


def test_linear_p_values_not_tiny(runs):
    pv = runs["linear"]["pv"]
    assert min(pv.values()) > 1e-4, pv
    # and not all near 1 either: roughly uniform
    assert 0.1 < np.mean(list(pv.values())) < 0.9


def test_detection_lines_match_peer(runs):
    for name in ("linear", "cubic"):
        doc = runs[name]["doc"]
        peer = frf_peer.estimate_files([runs[name]["path"]], design=runs["dir"] / "design.json",
                                       detect=ODD_FREE + EVEN_FREE)
        h.compare_with_peer(doc, peer, rel=1e-9)
        for a, b in zip(doc["detection_lines"], peer["detection_lines"]):
            assert a["bin"] == b["bin"] and a["freq"] == b["freq"]
            h.assert_rel(h.cplx(a["Y_mean"]), h.cplx(b["Y_mean"]), 1e-9, f"bin {a['bin']} Y_mean")
            assert a["noise_var"][0] == pytest.approx(b["noise_var"][0], rel=1e-9)
            pa, pb = a["p_value"][0], b["p_value"][0]
            if pb > 1e-250:
                assert pa == pytest.approx(pb, rel=1e-8), a["bin"]
            else:
                assert pa < 1e-200
