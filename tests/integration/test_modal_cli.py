"""Through the CLI: `msid fit --order a:b|auto` (order
selection written to the model file), `modes` in every model file and
`msid modes`, `msid frf --realisations R` (robust BLA: noise and nonlinear
distortion variances) with its use in `msid validate`, and the distortion
level from detection lines with one realisation. Fixed seeds."""
import numpy as np
import pytest

import helpers as h


def realisation_bench(d, R, nonlinear, periods=4, seed=3):
    """R random-phase realisations (msid excite seeds 11..) of the 2x2 DT bench, each
    2 experiments (DFT pattern), static cubic output y + a y^3, output noise."""
    plant = h.dt_plant_2x2()
    rng = np.random.default_rng(seed)
    paths = []
    for r in range(R):
        g = d / f"gen{r}"
        h.run_ok("excite", "--period", h.DT_P, "--lines", h.DT_LINES, "--inputs", 2, "--experiments", 2,
                 "--periods", periods, "--seed", 11 + r, "--csv", g, "-o", d / f"design{r}.json")
        for e in (1, 2):
            cols = h.read_csv(g / f"e{e}.csv")
            u = np.column_stack([cols["u1"], cols["u2"]])
            y = h.dt_simulate(plant, u, warmup=6, period=h.DT_P)
            y = y + nonlinear * y ** 3 + h.DT_SIGMA_Y * rng.standard_normal(y.shape)
            p = d / f"r{r}e{e}.csv"
            h.write_csv(p, h.experiment_columns(u, y))
            paths.append(p)
    return paths


def frf_realisations(d, paths, R, out):
    args = ["frf", "--design", d / "design0.json", "--realisations", R]
    for p in paths:
        args += ["--experiment", p]
    return h.run(*args, "-o", out)


@pytest.mark.parametrize("nonlinear,detected", [(0.0, False), (0.4, True)])
def test_frf_realisations_mimo(tmp_path, nonlinear, detected):
    R = 8
    paths = realisation_bench(tmp_path, R, nonlinear)
    out = tmp_path / "bla.json"
    r = frf_realisations(tmp_path, paths, R, out)
    assert r.returncode == 0, r.stderr
    doc = h.load_json(out)
    h.validate(doc, "msid-frf-1")
    nl = doc["nonlinear_distortion"]
    assert nl["realisations"] == R and nl["experiments_per_realisation"] == 2
    assert nl["distortion_detected"] == detected, nl
    assert doc["n_experiments"] == 2 * R and len(doc["experiments"]) == 2 * R
    line = doc["lines"][3]
    assert line["dof"] == R - 1 and line["dof_noise"] > 0 and len(line["var_nl"]) == 4
    total = np.real(np.diag(h.cplx(line["cov"])))
    noise = np.real(np.diag(h.cplx(line["cov_noise"])))
    assert np.allclose(np.array(line["var_nl"]), total - noise, rtol=1e-9, atol=0)
    if detected:
        assert "nonlinear distortion detected" in r.stderr
        # a model of the BLA weighted by the total covariance; validate names the distortion level
        m = tmp_path / "ml.json"
        h.run_ok("fit", "--method", "ml", "--order", 4, out, "-o", m)
        v = h.run_ok("validate", m, out, "-o", tmp_path / "val.json")
        assert "nonlinear distortion (8 realisations" in v.stdout
        rep = h.load_json(tmp_path / "val.json")["nonlinear_distortion"]
        assert rep["p_value_noise_only"] < 0.05 <= rep["p_value_total"], rep
        assert "distortion level" in rep["finding"]


def test_frf_realisations_bad_split(tmp_path):
    paths = realisation_bench(tmp_path, 2, 0.0, periods=2)
    r = frf_realisations(tmp_path, paths[:3], 2, tmp_path / "x.json")
    assert r.returncode != 0 and "do not split into 2 blocks" in r.stderr
    assert not (tmp_path / "x.json").exists()


def test_detection_lines_one_realisation(tmp_path):
    b = h.make_dt_bench(tmp_path, periods=6, nonlinear=0.4)
    out = tmp_path / "frf.json"
    # odd lines 1..41 excited, cubic: odd harmonics above the band (even lines stay empty)
    r = h.run_ok(*h.frf_args(b, out, "--detect-lines", "43:2:81"))
    doc = h.load_json(out)
    h.validate(doc, "msid-frf-1")
    nl = doc["nonlinear_distortion"]
    assert nl["realisations"] == 1 and nl["distortion_detected"] and nl["nl_to_noise_db"] > 0
    assert "detection lines show nonlinear distortion" in r.stderr
    m = tmp_path / "sub.json"
    h.run_ok("fit", "--method", "subspace", "--order", 4, out, "-o", m)
    v = h.run_ok("validate", m, out)
    assert "from the detection lines" in v.stdout
    # linear plant: nothing detected
    lin = tmp_path / "lin"
    lin.mkdir()
    b = h.make_dt_bench(lin, periods=6)
    h.run_ok(*h.frf_args(b, lin / "frf.json", "--detect-lines", "43:2:81"))
    assert not h.load_json(lin / "frf.json")["nonlinear_distortion"]["distortion_detected"]


@pytest.fixture(scope="module")
def linfrf(tmp_path_factory):
    d = tmp_path_factory.mktemp("orderbench")
    b = h.make_dt_bench(d, periods=8)
    h.run_ok(*h.frf_args(b, d / "frf.json"))
    return d


@pytest.mark.parametrize("method,rng", [("subspace", "2:7"), ("ml", "auto")])
def test_order_selection_cli(linfrf, method, rng):
    out = linfrf / f"{method}-sel.json"
    r = h.run_ok("fit", "--method", method, "--order", rng, linfrf / "frf.json", "-o", out)
    assert "chosen order 4" in r.stdout, r.stdout
    doc = h.load_json(out)
    h.validate(doc, "msid-model-1")
    sel = doc["order_selection"]
    assert sel["chosen"] == 4 and doc["order"] == 4
    rows = {o["order"]: o for o in sel["orders"]}
    if method == "ml":   # ML cost follows its law: the p-value rule decides
        assert sel["rule"] == "p-value" and rows[2]["p_value"] < 0.05 <= rows[4]["p_value"]
    else:                # subspace is not ML: its cost may sit above the law; the elbow picks 4 here
        assert sel["rule"] in ("p-value", "elbow") and rows[4]["cost"] < 1e-3 * rows[2]["cost"]
    assert not list(linfrf.glob("*.tmp"))
    assert len(doc["modes"]["modes"]) == 2


def test_modes_cli(linfrf, tmp_path):
    m = tmp_path / "ml.json"
    r = h.run_ok("fit", "--method", "ml", "--order", 4, linfrf / "frf.json", "-o", m)
    assert "zeta [%]" in r.stdout
    doc = h.load_json(m)
    modes = doc["modes"]["modes"]
    assert len(modes) == 2 and all(x["sd_fn"] > 0 and x["sd_zeta"] > 0 for x in modes)
    # the plant's poles: |z| = 0.9 at 0.03 cycles/sample and 0.8 at 0.12 (no sample time: cycles/sample)
    assert doc["modes"]["frequency_unit"] == "cycles/sample"
    fn = sorted(x["fn"] for x in modes)
    exact = sorted(abs(np.log(r_ * np.exp(2j * np.pi * f))) / (2 * np.pi) for r_, f in ((0.9, 0.03), (0.8, 0.12)))
    for a, b, x in zip(fn, exact, sorted(modes, key=lambda q: q["fn"])):
        assert abs(a - b) < 5 * x["sd_fn"], (a, b, x["sd_fn"])
    o = tmp_path / "modes.json"
    r = h.run_ok("modes", m, "-o", o)
    assert "sd(fn)" in r.stdout and h.load_json(o)["format"] == "msid-modes/1"
    s = tmp_path / "sub.json"
    h.run_ok("fit", "--method", "subspace", "--order", 4, linfrf / "frf.json", "-o", s)
    r = h.run_ok("modes", s)
    assert "subspace gives no parameter covariance" in r.stdout
    assert h.load_json(s)["modes"]["modes"][0]["sd_fn"] is None
    bad = h.run("modes", linfrf / "frf.json")
    assert bad.returncode != 0 and "not an msid-model/1 file" in bad.stderr
    # a real pole (order 5: one pole left over): its damping ratio is +-1 by definition, its sd '-'
    r5 = tmp_path / "ml5.json"
    r = h.run("fit", "--method", "ml", "--param", "poles", "--order", 5, linfrf / "frf.json", "-o", r5)
    assert r.returncode in (0, 3), r.stderr
    real = [x for x in h.load_json(r5)["modes"]["modes"] if x["real_pole"]]
    rows = [ln for ln in h.run_ok("modes", r5).stdout.splitlines() if "(real pole)" in ln]
    assert real and len(rows) == len(real) and all(ln.split()[4] == "-" for ln in rows), rows
