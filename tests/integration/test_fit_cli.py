"""`msid fit`, `msid validate`, `msid compare` and `msid frf --direct` end to end:
files validate against their JSON Schemas, known systems come back, G1 closed
form through the CLI, and every bad input gets one clear error and no file."""
import json
import math

import numpy as np
import pytest

import helpers as h


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp("fitbench")
    b = h.make_dt_bench(d, periods=8)
    h.run_ok(*h.frf_args(b, d / "frf.json"))
    A, B, C, D = b["plant"]
    truth = {"format": "msid-model/1", "domain": "dt", "method": "subspace", "order": 4, "n_inputs": 2, "n_outputs": 2,
             "settings": {"weight": "none"}, "A": A.tolist(), "B": B.tolist(), "C": C.tolist(), "D": D.tolist(),
             "n_params": 0, "cost": {"value": 0, "expected": 0, "dof": 0, "p_value": None}, "frf": []}
    (d / "truth.json").write_text(json.dumps(truth))
    return {"dir": d, "frf": d / "frf.json", "truth": d / "truth.json", "plant": b["plant"]}


@pytest.mark.parametrize("method", ["subspace", "ml"])
def test_fit_recovers_plant(bench, method):
    out = bench["dir"] / f"{method}.json"
    r = h.run_ok("fit", "--method", method, "--order", 4, bench["frf"], "-o", out)
    assert f"wrote {out}" in r.stdout
    doc = h.load_json(out)
    h.validate(doc, "msid-model-1")
    assert doc["order"] == 4 and doc["method"] == method and doc["stable"]
    r = h.run_ok("compare", out, bench["truth"])
    h2 = float(r.stdout.split("relative H2 distance ")[1].split(",")[0])
    assert h2 < 0.01, r.stdout
    r = h.run_ok("validate", out, bench["frf"], "-o", bench["dir"] / f"val-{method}.json")
    assert "verdict:" in r.stdout
    v = h.load_json(bench["dir"] / f"val-{method}.json")
    assert v["format"] == "msid-validation/1" and 0 <= v["p_value"] <= 1
    if method == "ml":
        # model FRF within its reported uncertainty of the truth at every line
        G0 = h.dt_frf(bench["plant"], [e["bin"] for e in doc["frf"]], 256)
        for e, g0 in zip(doc["frf"], G0):
            G, cov = h.cplx(e["G"]), h.cplx(e["cov"])
            d = (G - g0).flatten(order="F")
            q = float(np.real(d.conj() @ np.linalg.solve(cov, d)))
            assert q < 40, (e["bin"], q)   # chi2 with 8 real dof: 40 is far in the tail
        assert len(doc["parameters"]["names"]) == doc["n_params"] == 20


@pytest.mark.parametrize("method", ["ml"])
def test_fit_without_order_chooses_it(bench, method):
    """ml without --order: the order scan (--order auto), as msid measure --fit does; the same model as with
    --order auto given (negative controls: a fixed --order writes no order_selection, nor does subspace
    without --order, which keeps its singular-value order)."""
    out, ref = bench["dir"] / f"noorder-{method}.json", bench["dir"] / f"auto-{method}.json"
    r = h.run_ok("fit", "--method", method, bench["frf"], "-o", out)
    assert "chosen order" in r.stdout and "stabilised" in r.stdout and "stable poles" not in r.stdout, r.stdout
    doc = h.load_json(out)
    assert doc["order_selection"]["chosen"] == doc["order"]
    h.run_ok("fit", "--method", method, "--order", "auto", bench["frf"], "-o", ref)
    a, b = h.load_json(ref), doc
    assert a["A"] == b["A"] and a["order_selection"]["chosen"] == b["order_selection"]["chosen"]
    fixed = bench["dir"] / f"fixed-{method}.json"
    h.run_ok("fit", "--method", method, "--order", 4, bench["frf"], "-o", fixed)
    assert "order_selection" not in h.load_json(fixed)
    sv = bench["dir"] / "sv-subspace.json"
    h.run_ok("fit", "--method", "subspace", bench["frf"], "-o", sv)
    assert "order_selection" not in h.load_json(sv)


def test_fit_method_error_lists_every_method_and_help_says_which(bench, tmp_path):
    r = h.run("fit", "--method", "magic", bench["frf"], "-o", tmp_path / "o.json")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    for m in ("subspace", "lmfd", "ml", "multi", "cissim"):
        assert m in r.stderr, m
    r = h.run_ok("fit", "--help")
    first = r.stdout.lstrip().splitlines()[0]
    assert first.startswith("Which method: ml for the model you report"), first
    assert r.stdout.index("Which method") < r.stdout.index("usage: msid fit")
    # lmfd without --order or --nd/--nn still asks for them (it interpolates at every order)
    r = h.run("fit", "--method", "lmfd", bench["frf"], "-o", tmp_path / "l.json")
    assert r.returncode == 2 and "give --order or --nd/--nn" in r.stderr and not (tmp_path / "l.json").exists()


def test_weight_none_on_a_three_period_covariance_writes_the_model(tmp_path):
    """3 periods per experiment: the weighted fit is refused (M >= 4) and says to use --weight none; that fit
    is written with the unit-weight cost, p_value null and a note (the covariance's 2 dof, at most the 2
    outputs, give the weighted cost no finite expectation: it stopped with "not finite at /cost/expected")."""
    b = h.make_dt_bench(tmp_path, periods=3)
    h.run_ok(*h.frf_args(b, tmp_path / "frf.json"))
    r = h.run("fit", "--method", "ml", "--order", 4, tmp_path / "frf.json", "-o", tmp_path / "m.json")
    assert r.returncode == 1 and "--weight none" in r.stderr and not (tmp_path / "m.json").exists()
    # the order scan (no --order) fails at every order for this one reason: said once, no table row per order
    r = h.run("fit", "--method", "ml", tmp_path / "frf.json", "-o", tmp_path / "m.json")
    assert r.returncode == 1 and len(r.stderr.strip().splitlines()) == 1 and "--weight none" in r.stderr, r.stderr
    assert "failed" not in r.stdout and not (tmp_path / "m.json").exists()
    h.run_ok("fit", "--method", "ml", "--order", 4, "--weight", "none", tmp_path / "frf.json", "-o", tmp_path / "n.json")
    doc = h.load_json(tmp_path / "n.json")
    h.validate(doc, "msid-model-1")
    assert doc["cost"]["p_value"] is None and "no finite expectation" in doc["cost"]["note"], doc["cost"]
    assert doc["cost"]["weight"] == "none" and doc["order"] == 4


def test_g1_closed_form_through_the_cli(tmp_path):
    # Gonzalez §V-B(1): one CT line at w1 = 1/sqrt(2); lmfd with nD = 1, nN = 0 gives eq. (56)
    w1 = 1 / math.sqrt(2)
    P, K = 10, 4
    hh = 2 * math.pi / (P * w1)
    h.run_ok("excite", "--period", P, "--omega", repr(w1), "--sample-time", repr(hh), "--periods", K, "--csv",
             tmp_path, "-o", tmp_path / "d.json")
    cols = h.read_csv(tmp_path / "e1.csv")
    t = np.arange(len(cols["u1"])) * hh
    design = h.load_json(tmp_path / "d.json")
    phi = 2 * math.pi * design["lines"][0]["phase_turns"][0]
    G0 = 2 / (1j * w1 + 1)
    rng = np.random.default_rng(3)
    y = abs(G0) * np.cos(w1 * t + phi + np.angle(G0)) + 0.05 * rng.standard_normal(len(t))
    h.write_csv(tmp_path / "x.csv", h.experiment_columns(np.asarray(cols["u1"])[:, None], y[:, None]))
    h.run_ok("frf", "--design", tmp_path / "d.json", "--experiment", tmp_path / "x.csv", "-o", tmp_path / "f.json")
    G = h.cplx(h.load_json(tmp_path / "f.json")["lines"][0]["G"])[0, 0]
    h.run_ok("fit", "--method", "lmfd", "--nd", 1, "--nn", 0, tmp_path / "f.json", "-o", tmp_path / "m.json")
    m = h.load_json(tmp_path / "m.json")
    h.validate(m, "msid-model-1")
    a1, b0 = m["lmfd"]["D"][0][0][0], m["lmfd"]["N"][0][0][0]
    assert abs(a1 - (-G.imag / (w1 * G.real))) < 1e-12 * abs(a1)
    assert abs(b0 - abs(G) ** 2 / G.real) < 1e-12 * abs(b0)
    assert m["unique"] is True and m["parameters"]["names"] == ["D1[1,1]", "N0[1,1]"]
    # under-constrained with a pin: b0 = 0 -> a1 = Re/(w Im), b1 = |G|^2/(w Im)
    h.run_ok("fit", "--method", "lmfd", "--nd", 1, "--nn", 1, "--pin", "N0=0", tmp_path / "f.json", "-o", tmp_path / "p.json")
    p = h.load_json(tmp_path / "p.json")
    assert abs(p["lmfd"]["D"][0][0][0] - G.real / (w1 * G.imag)) < 1e-12 * abs(G.real / (w1 * G.imag))
    assert abs(p["lmfd"]["N"][1][0][0] - abs(G) ** 2 / (w1 * G.imag)) < 1e-12 * abs(abs(G) ** 2 / (w1 * G.imag))
    assert len(p["kernel"][0]) == 1


def test_direct_frf_on_partial_periods(tmp_path, bench):
    # the bench's records cut to a non-whole number of periods: --direct still estimates, with pcov
    d = bench["dir"]
    cut = []
    for e in (1, 2):
        cols = h.read_csv(d / f"e{e}.csv")
        n = 256 * 5 + 77
        cut.append(tmp_path / f"c{e}.csv")
        h.write_csv(cut[-1], {k: np.asarray(v)[:n] for k, v in cols.items() if k != "t"})
    out = tmp_path / "direct.json"
    r = h.run_ok("frf", "--direct", "--design", d / "design.json", "--experiment", cut[0], "--experiment", cut[1], "-o", out)
    assert "not whole periods" in r.stderr
    doc = h.load_json(out)
    h.validate(doc, "msid-frf-1")
    assert doc["whole_periods"] is False and doc["lines_correlated"] is True
    G0 = h.dt_frf(bench["plant"], [e["bin"] for e in doc["lines"]], 256)
    worst = 0
    for e, g0 in zip(doc["lines"], G0):
        dv = (h.cplx(e["G"]) - g0).flatten(order="F")
        sd = np.sqrt(np.real(np.diag(h.cplx(e["cov"]))))
        worst = max(worst, float(np.max(np.abs(dv) / sd)))
        assert "pcov" in e
    assert worst < 6, worst


def _no_new_files(tmp_path, before):
    assert sorted(p.name for p in tmp_path.iterdir()) == before


BAD = {
    "wrong format": (lambda d, b: ["fit", "--method", "subspace", "--order", 2, d / "design.json", "-o", d / "o.json"],
                     "expected \"msid-frf/1\""),
    "order too high": (lambda d, b: ["fit", "--method", "subspace", "--order", 40, b["frf"], "-o", d / "o.json"],
                       "the largest order these lines support is"),
    "lmfd over-constrained": (lambda d, b: ["fit", "--method", "lmfd", "--nd", 1, "--nn", 1, b["frf"], "-o", d / "o.json"],
                              "over-constrained"),
    "bad method": (lambda d, b: ["fit", "--method", "magic", b["frf"], "-o", d / "o.json"], "--method must be"),
    "bad pin": (lambda d, b: ["fit", "--method", "lmfd", "--nd", 1, "--pin", "X1=2", b["frf"], "-o", d / "o.json"],
                "expected e.g. N0=0"),
    "validate wrong model": (lambda d, b: ["validate", b["frf"], b["frf"]], "expected \"msid-model/1\""),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_input(tmp_path, bench, name):
    h.run_ok("excite", "--period", 16, "--lines", "1,3", "-o", tmp_path / "design.json")
    before = sorted(p.name for p in tmp_path.iterdir())
    args, phrase = BAD[name]
    r = h.run(*args(tmp_path, bench))
    assert r.returncode != 0, r.stdout
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and phrase in lines[0], r.stderr
    _no_new_files(tmp_path, before)


def _edited_frf(tmp_path, bench, edit):
    doc = h.load_json(bench["frf"])
    edit(doc)
    p = tmp_path / "edited.json"
    p.write_text(json.dumps(doc))
    return p


def test_missing_covariance(tmp_path, bench):
    p = _edited_frf(tmp_path, bench, lambda d: d["lines"][2].pop("cov"))
    r = h.run("fit", "--method", "ml", "--order", 4, p, "-o", tmp_path / "o.json")
    assert r.returncode == 1 and "needs the FRF covariance" in r.stderr and f"bin {h.load_json(p)['lines'][2]['bin']}" in r.stderr
    assert not (tmp_path / "o.json").exists()
    # unweighted fits do not need it
    h.run_ok("fit", "--method", "subspace", "--order", 4, "--weight", "none", p, "-o", tmp_path / "u.json")


def test_singular_weights_name_the_line(tmp_path, bench):
    def zero(d):
        n = len(d["lines"][5]["cov"]["re"])
        d["lines"][5]["cov"] = {"re": [[0.0] * n for _ in range(n)], "im": [[0.0] * n for _ in range(n)]}
    p = _edited_frf(tmp_path, bench, zero)
    r = h.run("fit", "--method", "subspace", "--order", 4, p, "-o", tmp_path / "o.json")
    b = h.load_json(p)["lines"][5]["bin"]
    assert r.returncode == 1 and f"singular weights at line bin {b}" in r.stderr, r.stderr
    assert not (tmp_path / "o.json").exists()


def test_existing_model_untouched_on_failure(tmp_path, bench):
    out = tmp_path / "m.json"
    out.write_text("keep")
    r = h.run("fit", "--method", "subspace", "--order", 40, bench["frf"], "-o", out)
    assert r.returncode == 1
    assert out.read_text() == "keep"


@pytest.mark.parametrize("param", ["lmfd", "poles"])
def test_non_convergence_keeps_the_best_iterate(tmp_path, bench, param):
    # iterations running out is not an error that loses the work: the best iterate is
    # written, marked "converged": false with its cost and gradient norm, one warning, exit status 3
    out = tmp_path / "m.json"
    start = ("--start", "sk") if param == "lmfd" else ()   # --param poles runs all its starts (sk is refused there)
    r = h.run("fit", "--method", "ml", "--param", param, "--order", 4, *start, "--max-iter", 1, bench["frf"], "-o", out)
    assert r.returncode == 3, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "did not converge in 1 iterations" in lines[0], r.stderr
    doc = h.load_json(out)
    h.validate(doc, "msid-model-1")
    assert doc["converged"] is False and doc["iterations"] == 1 and doc["gradient_norm"] > 0
    assert doc["cost"]["value"] > 0
    # the same fit with enough iterations converges and exits 0
    r = h.run_ok("fit", "--method", "ml", "--param", param, "--order", 4, bench["frf"], "-o", tmp_path / "c.json")
    assert h.load_json(tmp_path / "c.json")["converged"] is True


def test_subspace_refine_spelling(tmp_path, bench):
    # --refine ml|none, as for cissim: ml is the 30-step budget, none the bare estimate (0 steps)
    out = {}
    for r in ("ml", "30", "none", "0"):
        out[r] = tmp_path / f"m-{r}.json"
        h.run_ok("fit", bench["frf"], "--method", "subspace", "--order", 4, "--refine", r, "-o", out[r])
    assert out["ml"].read_bytes() == out["30"].read_bytes()
    assert out["none"].read_bytes() == out["0"].read_bytes()
    assert out["ml"].read_bytes() != out["none"].read_bytes()   # the refinement did something
    r = h.run("fit", bench["frf"], "--method", "subspace", "--order", 4, "--refine", "bogus", "-o", tmp_path / "x.json")
    assert r.returncode == 2 and "--refine must be ml, none or a number of steps" in r.stderr
    assert not (tmp_path / "x.json").exists()
