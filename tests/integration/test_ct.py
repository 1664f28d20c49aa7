"""Continuous-time path: msid excite --omega/--sample-time with lines above
Nyquist, a CT plant sampled exactly at t = n h, msid frf --design; G must be
G(j omega) (not its conjugate) on every line, folded or not."""
import math

import numpy as np
import pytest

import helpers as h
from msid_peers import frf_peer

H = 0.005                  # s; P*h = 1 s, Nyquist 100 Hz
P = 200
# cycles per P*h (= Hz): 113, 151, 229 and 367 lie above Nyquist
CYCLES = [0, 2, 5, 11, 17, 23, 31, 47, 73, 113, 151, 229, 367]
OMEGA = [2 * math.pi * k for k in CYCLES]
K = 8
SIGMA_Y, SIGMA_U = 0.02, 0.001


@pytest.fixture(scope="module")
def ct_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("ct")
    h.run_ok("excite", "--omega", ",".join(repr(w) for w in OMEGA), "--sample-time", repr(H),
             "--period", P, "--inputs", 2, "--experiments", 2, "--periods", K, "--seed", 5,
             "--amplitudes", 0.8, "--csv", d / "gen", "-o", d / "design.json")
    design = h.load_json(d / "design.json")
    plant = h.ct_plant_2x2()
    G0 = h.ct_frf(plant, OMEGA)                                   # L x ny x nu
    n = np.arange(K * P)
    rng = np.random.default_rng(2024)
    paths, max_gen_err = [], 0.0
    for e in range(2):
        # c_{i,l} = A e^{j 2 pi (phi + tau)}: u_i(t) = sum_l Re(c_il e^{j w_l t}) at t = n h
        c = np.zeros((2, len(OMEGA)), complex)
        for l, line in enumerate(design["lines"]):
            for i in range(2):
                turns = line["phase_turns"][i] + h.dft_pattern_turns(i, e, 2)
                c[i, l] = line["amplitude"][i] * np.exp(2j * math.pi * turns)
        # exact phase of w_l n h: 2 pi ((k_l n) mod P) / P
        ph = np.exp(2j * math.pi * (np.outer(n, CYCLES) % P) / P)  # N x L
        u = np.real(ph @ c.T)                                       # N x nu
        y = np.real(np.einsum("nl,lki,il->nk", ph, G0, c))          # N x ny
        gen = h.read_csv(d / "gen" / f"e{e + 1}.csv")
        ug = np.column_stack([gen["u1"], gen["u2"]])
        max_gen_err = max(max_gen_err, np.max(np.abs(ug - u)))
        um = ug + SIGMA_U * rng.standard_normal(ug.shape)
        y = y + SIGMA_Y * rng.standard_normal(y.shape)
        p = d / f"e{e + 1}.csv"
        h.write_csv(p, h.experiment_columns(um, y, time=n * H))
        paths.append(p)
    out = d / "frf.json"
    h.run_ok("frf", "--design", d / "design.json", "--experiment", paths[0], "--experiment", paths[1], "-o", out)
    return {"dir": d, "design": design, "doc": h.load_json(out), "paths": paths, "G0": G0,
            "max_gen_err": max_gen_err}


def test_generator_is_the_sampled_ct_multisine(ct_run):
    # the generated input is u(t) = sum A cos(w t + 2 pi (phi + tau)) sampled at t = n h
    assert ct_run["max_gen_err"] < 1e-9


def test_schemas_and_fields(ct_run):
    design, doc = ct_run["design"], ct_run["doc"]
    h.validate(design, "msid-design-1")
    h.validate(doc, "msid-frf-1")
    assert design["domain"] == doc["domain"] == "ct"
    assert design["sample_time"] == doc["sample_time"] == H
    for l, (line, w) in enumerate(zip(doc["lines"], OMEGA)):
        b, folded = frf_peer.ct_bin(w, P, H)
        assert line["omega"] == w and design["lines"][l]["omega"] == w
        assert (line["bin"], line["folded"]) == (b, folded), l
        assert (design["lines"][l]["bin"], design["lines"][l]["folded"]) == (b, folded), l
        assert line["freq_hz"] == pytest.approx(CYCLES[l], rel=1e-12)
    assert [l["folded"] for l in doc["lines"]].count(True) == 3       # 113, 151, 367 Hz; 229 aliases unfolded
    assert doc["lines"][0]["real"] is True
    assert np.all(np.array(doc["lines"][0]["G"]["im"]) == 0)


def test_G_is_G_of_j_omega(ct_run):
    doc, G0 = ct_run["doc"], ct_run["G0"]
    for l, line in enumerate(doc["lines"]):
        G = h.cplx(line["G"])
        var = np.real(np.diag(h.cplx(line["cov"])))
        t = np.abs((G - G0[l]).T.reshape(-1)) ** 2 / var
        assert np.all(t < 25), f"line {l} ({CYCLES[l]} Hz, bin {line['bin']}): {t}"
        if CYCLES[l]:
            # the conjugate is far away: the check above can tell G(jw) from G(-jw)
            tc = np.abs((G - G0[l].conj()).T.reshape(-1)) ** 2 / var
            assert np.max(tc) > 100, f"line {l}: test not discriminating"


def test_matches_numpy_peer(ct_run):
    peer = frf_peer.estimate_files(ct_run["paths"], design=ct_run["dir"] / "design.json")
    h.compare_with_peer(ct_run["doc"], peer, rel=1e-9)
