"""msid frf --realisations R with ONE period per realisation (the nonlinear-benchmark layout): the BLA
and its total covariance from the realisations' spread (dof R - 1), the noise part left out of the
file and said on stderr; the file through msid fit, validate and the Python reader. The statistics
(coverage, variance against the spread) are tests/stats/test_stats_bla_one_period.cpp."""
import numpy as np

import helpers as h
from test_modal_cli import frf_realisations, realisation_bench

P = 256
BINS = np.arange(1, 61)
NOTE = "msid frf: note: one period per realisation: noise and nonlinear distortion cannot be separated"


def siso_records(d, R, periods=None, a=0.3, seed=4):
    """R random-phase multisines of one period (periods[r] periods for realisation r) through
    (0.5 + 0.3 z^-1) / (1 - 1.2 z^-1 + 0.6 z^-2), then y = x + a x^3, plus output noise."""
    rng = np.random.default_rng(seed)
    z = np.exp(-2j * np.pi * np.arange(P // 2 + 1) / P)
    G = (0.5 + 0.3 * z) / (1 - 1.2 * z + 0.6 * z ** 2)
    paths, uy = [], []
    for r in range(R):
        U = np.zeros(P // 2 + 1, complex)
        U[BINS] = P / 2 * np.sqrt(2 / len(BINS)) * np.exp(2j * np.pi * rng.uniform(size=len(BINS)))
        u, x = np.fft.irfft(U, P), np.fft.irfft(U * G, P)
        K = 1 if periods is None else periods[r]
        u = np.tile(u, K)
        y = np.tile(x + a * x ** 3, K) + 0.02 * rng.standard_normal(P * K)
        p = d / f"r{r}.csv"
        h.write_csv(p, h.experiment_columns(u[:, None], y[:, None]))
        paths.append(p)
        uy.append((u[:P], y[:P]))
    return paths, uy


def frf(d, paths, R, out, *extra):
    args = ["frf", "--period", P, "--lines", "1:60", "--realisations", R, *extra]
    for p in paths:
        args += ["--experiment", p]
    return h.run(*args, "-o", out)


def test_siso_one_period_file_fit_validate_python(tmp_path):
    R = 6
    paths, uy = siso_records(tmp_path, R)
    out = tmp_path / "bla.json"
    r = frf(tmp_path, paths, R, out)
    assert r.returncode == 0, r.stderr
    assert NOTE in r.stderr and "cov is their total" in r.stderr, r.stderr
    doc = h.load_json(out)
    h.validate(doc, "msid-frf-1")
    nl = doc["nonlinear_distortion"]
    assert nl["realisations"] == R and nl["noise_separated"] is False
    assert nl["note"].startswith("one period per realisation: noise and nonlinear distortion cannot be separated")
    assert "noise_cov" not in doc and "p_value" not in nl
    # the independent peer: each realisation's Y/U from NumPy's DFT, their mean and sample covariance / R
    Gr = np.array([np.fft.fft(y)[BINS] / np.fft.fft(u)[BINS] for u, y in uy])   # R x L
    G = np.array([h.cplx(ln["G"])[0, 0] for ln in doc["lines"]])
    v = np.array([np.real(h.cplx(ln["cov"])[0, 0]) for ln in doc["lines"]])
    assert np.allclose(G, Gr.mean(0), rtol=1e-9, atol=0)
    assert np.allclose(v, np.var(Gr, axis=0, ddof=1) / R, rtol=1e-9, atol=0)
    for ln in doc["lines"]:
        assert ln["dof"] == R - 1
        assert not {"cov_known_input", "noise_cov", "snr", "cov_noise", "var_nl"} & set(ln), sorted(ln)
    # the fits weigh with the total covariance; validate says what it cannot tell
    for method in ("ml", "subspace"):
        h.run_ok("fit", "--method", method, "--order", 2, out, "-o", tmp_path / f"{method}.json")
    val = h.run_ok("validate", tmp_path / "ml.json", out, "-o", tmp_path / "val.json")
    assert "realisations of one period: noise and distortion not separated" in val.stdout, val.stdout
    rep = h.load_json(tmp_path / "val.json")["nonlinear_distortion"]
    assert rep["noise_separated"] is False and "p_value_total" in rep
    # a fit that needs the noise part refuses with one message
    r = h.run("fit", "--method", "ml", "--order", 2, "--weight", "known-input", out, "-o", tmp_path / "ki.json")
    assert r.returncode != 0 and len(r.stderr.strip().splitlines()) == 1 and "cov_known_input" in r.stderr, r.stderr
    assert not (tmp_path / "ki.json").exists()
    # the Python reader: total covariance and dof, no known-input covariance; exact regions from dof R - 1
    import msid
    f = msid.read_frf(out)
    assert f.cov_known_input is None and np.all(f.dof == R - 1) and "noise_cov" not in f.meta
    q = (R - 1) * (0.05 ** (-1 / (R - 1)) - 1)   # F(2, 2(R - 1)) 95% quantile
    assert np.allclose(f.radius(0.95)[:, 0, 0], np.sqrt(v * q), rtol=1e-12)
    # the Bode plot draws the regions of the total covariance and says so in its title
    try:
        import matplotlib
        matplotlib.use("Agg")
        import msid.plot
        fig = msid.plot.bode(f)
        assert "BLA of 6 realisations (one period each: total covariance only)" in fig._suptitle.get_text()
    except ImportError:
        pass
    # written back: no neutral noise keys stand in for the missing ones (a zero noise_cov, cov_known_input = cov)
    msid.write_frf(tmp_path / "rt.json", f)
    rt = h.load_json(tmp_path / "rt.json")
    h.validate(rt, "msid-frf-1")
    assert set(rt) == set(doc) and all(set(a) == set(b) for a, b in zip(rt["lines"], doc["lines"]))


def test_mixed_periods_and_2x2(tmp_path):
    # realisations 1-3 with 3 periods, 4-6 with one: the one-period rule holds for the file, the
    # others keep their transient tests
    R = 6
    paths, _ = siso_records(tmp_path, R, periods=[3, 3, 3, 1, 1, 1])
    out = tmp_path / "mix.json"
    r = frf(tmp_path, paths, R, out)
    assert r.returncode == 0, r.stderr
    assert "msid frf: note: one usable period in realisations 4, 5, 6:" in r.stderr, r.stderr
    doc = h.load_json(out)
    h.validate(doc, "msid-frf-1")
    assert [e["periods_used"] for e in doc["experiments"]] == [3, 3, 3, 1, 1, 1]
    assert [e["transient_tested"] for e in doc["experiments"]] == [True] * 3 + [False] * 3
    # 2x2, two experiments per realisation (DFT pattern), R = 8 >= ny nu + 1 of one period
    d = tmp_path / "mimo"
    d.mkdir()
    mp = realisation_bench(d, 8, 0.4, periods=1)
    r = frf_realisations(d, mp, 8, d / "bla.json")
    assert r.returncode == 0, r.stderr
    assert NOTE in r.stderr
    doc = h.load_json(d / "bla.json")
    h.validate(doc, "msid-frf-1")
    assert all(ln["dof"] == 7 for ln in doc["lines"])
    h.run_ok("fit", "--method", "ml", "--order", 4, d / "bla.json", "-o", d / "m.json")


def test_one_period_refusals(tmp_path):
    paths, _ = siso_records(tmp_path, 2)
    # one realisation of one period: one message, non-zero exit, nothing written
    for extra in ([], ["--realisations", 1]):
        args = ["frf", "--period", P, "--lines", "1:60", *extra, "--experiment", paths[0], "-o", tmp_path / "x.json"]
        r = h.run(*args)
        lines = r.stderr.strip().splitlines()
        assert r.returncode != 0 and len(lines) == 1, r.stderr
        assert not (tmp_path / "x.json").exists()
    assert "--realisations must be at least 2" in lines[0]
    r = h.run("frf", "--period", P, "--lines", "1:60", "--experiment", paths[0], "-o", tmp_path / "x.json")
    assert "at least 2 usable periods" in r.stderr and "--realisations R" in r.stderr, r.stderr
    # R = 3: the file is written (dof 2), but weighting by its total covariance follows the
    # realisations rule of robust-BLA files (F(2, 2(R - 1)) terms need R - 1 > 2): fit and validate refuse
    p3, _ = siso_records(tmp_path, 3)
    out = tmp_path / "b3.json"
    assert frf(tmp_path, p3, 3, out).returncode == 0
    r = h.run("fit", "--method", "ml", "--order", 2, out, "-o", tmp_path / "m3.json")
    assert r.returncode == 1 and "rests on 3 realisations" in r.stderr and "R >= 4" in r.stderr, r.stderr
    # 2x2 of one period: the total covariance of 4 entries needs R >= 5
    d = tmp_path / "mimo"
    d.mkdir()
    mp = realisation_bench(d, 4, 0.4, periods=1)
    r = frf_realisations(d, mp, 4, d / "bla.json")
    lines = r.stderr.strip().splitlines()
    assert r.returncode != 0 and len(lines) == 1 and "at least 5 realisations" in lines[0], r.stderr
    assert not (d / "bla.json").exists()
