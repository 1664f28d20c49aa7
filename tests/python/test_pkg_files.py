"""The msid Python package's files, python-control conversion and exact regions (docs/python.md).

Peers: the msid CLI (msid fit / validate read what the package writes and must give the same numbers),
python-control (evaluates the state-space and transfer-function models independently), scipy.stats
(F quantiles), and a NumPy Monte Carlo of the F(2, 2n) law with a chi-square negative control."""
import json
import math

import numpy as np
import pytest
from conftest import msid

import msid as pkg
from helpers import validate
from msid import regions

control = pytest.importorskip("control")


def load(p):
    with open(p, encoding="utf-8") as f:
        return json.load(f)


def test_read_frf_shapes_and_vec_convention(demo):
    f = pkg.read_frf(demo / "frf.json")
    doc = load(demo / "frf.json")
    L, ny, nu = len(doc["lines"]), doc["n_outputs"], doc["n_inputs"]
    assert f.G.shape == (L, ny, nu) and f.cov.shape == (L, ny * nu, ny * nu) and f.dof.shape == (L,)
    assert f.meta["format"] == "msid-frf/1" and f.meta["n_experiments"] == 2 and f.domain == "dt"
    for k in (0, L // 2, L - 1):
        ln = doc["lines"][k]
        for i in range(ny):
            for j in range(nu):
                assert f.G[k, i, j] == complex(ln["G"]["re"][i][j], ln["G"]["im"][i][j])
                # vec(G) stacks columns: G[i][j] is element i + ny*j of the covariance
                assert f.std()[k, i, j] == math.sqrt(ln["cov"]["re"][i + ny * j][i + ny * j])
        assert f.dof[k] == ln["dof"]
    hz, unit = f.hz_axis()
    assert unit == "Hz" and np.allclose(hz, [ln["freq_hz"] for ln in doc["lines"]])
    assert np.allclose(f.omega_axis(), 2 * np.pi * hz)


def test_frf_write_round_trip_is_valid_and_fits_identically(demo, tmp_path):
    f = pkg.read_frf(demo / "frf.json")
    out = tmp_path / "copy.json"
    pkg.write_frf(out, f)
    validate(load(out), "msid-frf-1")
    g = pkg.read_frf(out)
    assert np.array_equal(g.G, f.G) and np.array_equal(g.cov, f.cov) and np.array_equal(g.dof, f.dof)
    assert np.array_equal(g.cov_known_input, f.cov_known_input) and g.line_extra == f.line_extra
    # msid fit on the written file gives the same model as on the original
    msid("fit", "--method", "ml", "--order", "4", out, "-o", tmp_path / "m.json")
    a, b = load(demo / "model.json"), load(tmp_path / "m.json")
    assert a["A"] == b["A"] and a["cost"]["value"] == b["cost"]["value"]


def test_frf_to_control_and_back(demo, tmp_path):
    f = pkg.read_frf(demo / "frf.json")
    frd = f.to_control()
    assert isinstance(frd, control.FrequencyResponseData)
    resp = np.asarray(frd.frdata if hasattr(frd, "frdata") else frd.fresp)
    assert resp.shape == (2, 2, f.n_lines)
    assert np.array_equal(np.transpose(resp, (2, 0, 1)), f.G) and np.allclose(frd.omega, f.omega_axis())
    # python-control's own evaluation at a line gives G
    assert np.allclose(frd.eval(frd.omega[3]), f.G[3])
    g = pkg.FRF.from_control(frd, f.meta["period_samples"], f.sample_time, cov=f.cov, dof=f.dof)
    assert np.array_equal(g.bins, f.bins) and np.allclose(g.freq, f.freq, rtol=0, atol=1e-15)
    out = tmp_path / "frd.json"
    pkg.write_frf(out, g)
    validate(load(out), "msid-frf-1")
    # the model validates on the round-tripped FRF with the cost it has on the original
    r1 = msid("validate", demo / "model.json", demo / "frf.json", "-o", tmp_path / "v1.json")
    r2 = msid("validate", demo / "model.json", out, "-o", tmp_path / "v2.json")
    c1, c2 = (float(r.stdout.split("weighted cost ")[1].split(",")[0]) for r in (r1, r2))
    assert c1 == pytest.approx(c2, rel=1e-9)


def test_control_plots_of_frf_and_model(demo):
    """python-control's own plots take what to_control() gives: a named FRD with the file's dt and signal
    names (bode_plot needs a name, nyquist_plot a DT FRD that evaluates on the unit circle), the model's
    StateSpace with the same names (step_response against a state recursion of the file's A, B, C, D)."""
    mpl = pytest.importorskip("matplotlib")
    mpl.use("Agg")
    import matplotlib.pyplot as plt
    f = pkg.read_frf(demo / "frf.json")
    m = pkg.read_model(demo / "model.json")
    frd = f.to_control()
    assert frd.dt == f.sample_time and frd.isdtime(strict=True) and frd.name
    assert frd.input_labels == ["u1", "u2"] and frd.output_labels == ["y1", "y2"]
    try:
        cp = control.bode_plot(frd)
        assert cp.axes.shape == (4, 2)   # magnitude and phase per output, one column per input
        mag = cp.lines[0, 1][0].get_ydata()   # y1 / u2 magnitude: the data, not a re-evaluation
        assert np.allclose(mag, np.abs(f.G[:, 0, 1]), rtol=1e-12)
        assert frd.name in cp.figure._suptitle.get_text()
        # Nyquist of one SISO path at the measured lines (an FRD has no other points)
        g = frd[1, 0]
        cp = control.nyquist_plot(g, g.omega)
        drawn = [ln for group in cp.lines[0] for ln in group if ln is not None and len(ln.get_xdata()) == f.n_lines]
        xy = drawn[0].get_xydata()   # the primary curve: the lines in order
        assert np.allclose(xy[:, 0] + 1j * xy[:, 1], f.G[:, 1, 0], rtol=1e-9, atol=0)
        # the model: Bode, Nyquist and step response with its names and dt
        ss = m.to_control()
        assert ss.name and ss.dt == m.sample_time and ss.input_labels == ["u1", "u2"]
        control.bode_plot(ss)
        control.nyquist_plot(ss[0, 0])
        n = 200
        r = control.step_response(ss, T=np.arange(n) * ss.dt)
        y = np.asarray(r.outputs)             # (ny, nu, n): output i for a unit step on input j
        x = np.zeros((m.order, m.n_inputs))
        want = np.empty((m.n_outputs, m.n_inputs, n))
        for k in range(n):                    # x[k+1] = A x[k] + B, y[k] = C x[k] + D (zero initial state)
            want[:, :, k] = m.C @ x + m.D
            x = m.A @ x + m.B
        assert np.allclose(y, want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
        assert r.output_labels == ["y1", "y2"]
    finally:
        plt.close("all")
    # the names come from the file when it carries them
    f.meta.update(input_names=["force", "torque"], output_names=["acc", "vel"])
    frd = f.to_control(name="bench")
    assert frd.name == "bench" and frd.input_labels == ["force", "torque"] and frd.output_labels == ["acc", "vel"]


def test_control_round_trips_keep_dt_and_names(demo):
    f = pkg.read_frf(demo / "frf.json")
    m = pkg.read_model(demo / "model.json")
    # FRF -> FRD -> FRF: the lines and G bit for bit, the sample time from the FRD's dt
    frd = f.to_control()
    g = pkg.FRF.from_control(frd, f.meta["period_samples"], frd.dt)
    assert np.array_equal(g.G, f.G) and np.array_equal(g.bins, f.bins) and g.sample_time == f.sample_time
    # Model -> StateSpace -> Model: the same matrices, dt and response at the lines
    ss = m.to_control()
    back = pkg.Model.from_control(ss, f)
    for k in "ABCD":
        assert np.array_equal(getattr(back, k), getattr(m, k)), k
    assert back.sample_time == m.sample_time
    assert np.allclose(back.frf_G, m.frf_G, rtol=0, atol=1e-10 * np.abs(m.frf_G).max())
    tf = m.to_control("tf")
    assert tf.dt == m.sample_time and tf.name == ss.name and tf.output_labels == ss.output_labels
    # a DT file without a sample time: dt True, frequencies in rad/sample
    f.meta.pop("sample_time")
    f.freq_hz = None
    frd = f.to_control()
    assert frd.dt is True and np.allclose(frd.omega, 2 * np.pi * f.freq)
    v = frd(np.exp(1j * frd.omega[:3]))   # z on the unit circle: the lines' G (the Nyquist contour of DT)
    assert np.array_equal(np.transpose(v, (2, 0, 1)), f.G[:3])


def test_frd_off_bin_refused():
    frd = control.frd(np.ones((1, 1, 2)), [0.1, 0.2])
    with pytest.raises(ValueError, match="DFT bins"):
        pkg.FRF.from_control(frd, 64)


def test_model_to_control_matches_file_and_validate(demo, tmp_path):
    f = pkg.read_frf(demo / "frf.json")
    m = pkg.read_model(demo / "model.json")
    assert m.order == 4 and m.domain == "dt" and m.sample_time == f.sample_time
    ss = m.to_control()
    assert isinstance(ss, control.StateSpace) and ss.dt == f.sample_time
    # python-control evaluates the model at the data lines as msid fit wrote it (frf[] of the file)
    resp = ss.frequency_response(f.omega_axis())
    Gss = np.transpose(np.asarray(resp.frdata if hasattr(resp, "frdata") else resp.fresp), (2, 0, 1))
    scale = np.abs(m.frf_G).max()
    assert np.abs(Gss - m.frf_G).max() < 1e-10 * scale
    assert np.abs(m.response(f) - m.frf_G).max() < 1e-10 * scale
    tf = m.to_control("tf")
    assert isinstance(tf, control.TransferFunction)
    Gtf = np.transpose(np.asarray(tf(np.exp(1j * f.omega_axis() * f.sample_time))), (2, 0, 1))
    assert np.abs(Gtf - m.frf_G).max() < 1e-6 * scale
    # write_model keeps the file valid and identical in content
    pkg.write_model(tmp_path / "m.json", m)
    validate(load(tmp_path / "m.json"), "msid-model-1")
    assert load(tmp_path / "m.json") == load(demo / "model.json")


def test_model_from_control_validates_with_msid(demo, tmp_path):
    f = pkg.read_frf(demo / "frf.json")
    ss = pkg.read_model(demo / "model.json").to_control()
    for name, sys_ in (("good", ss), ("bad", control.ss(ss.A * 0.97, ss.B, ss.C, ss.D, ss.dt))):
        m = pkg.Model.from_control(sys_, f, source="frf.json", n_params=20)
        p = tmp_path / f"{name}.json"
        pkg.write_model(p, m)
        validate(load(p), "msid-model-1")
        r = msid("validate", p, demo / "frf.json")
        cost = float(r.stdout.split("weighted cost ")[1].split(",")[0])
        expected = float(r.stdout.split("expected ")[1].split(" ")[0])
        pv = float(r.stdout.split("p-value ")[1].split()[0])
        # the package's cost block is the one msid validate computes (docs/fitting.md eq. 40 and its law)
        assert m.doc["cost"]["value"] == pytest.approx(cost, rel=1e-5)
        assert m.doc["cost"]["expected"] == pytest.approx(expected, rel=1e-5)
        assert m.doc["cost"]["p_value"] == pytest.approx(pv, rel=1e-3, abs=1e-12)
        verdict = "NOT consistent" not in r.stdout
        assert verdict == (name == "good"), r.stdout   # negative control: moved poles are rejected


def test_model_from_control_refuses_wrong_domain(demo):
    f = pkg.read_frf(demo / "frf.json")
    with pytest.raises(ValueError, match="ct"):
        pkg.Model.from_control(control.ss([[-1.0]], [[1.0, 0.0]], [[1.0], [0.0]], np.zeros((2, 2))), f)


def test_bad_files_one_message_nothing_written(tmp_path):
    p = tmp_path / "x.json"
    p.write_text('{"format": "msid-model/1"}')
    with pytest.raises(pkg.FormatError, match="expected \"msid-frf/1\""):
        pkg.read_frf(p)
    p.write_text("{not json")
    with pytest.raises(pkg.FormatError, match="not valid JSON"):
        pkg.read_frf(p)
    with pytest.raises(FileNotFoundError, match="cannot read"):   # a file that cannot be read: OSError
        pkg.read_model(tmp_path / "missing.json")
    f = pkg.FRF(np.full((1, 1, 1), np.nan + 0j), [0.1], meta={"period_samples": 10})
    with pytest.raises(ValueError):
        pkg.write_frf(tmp_path / "nan.json", f)   # NaN is never written
    assert sorted(x.name for x in tmp_path.iterdir()) == ["x.json"]


def test_f_quantiles_against_scipy():
    from scipy import stats
    for n in (1, 2, 3, 7, 12, 50, 1000):
        assert regions.f2_quantile(0.95, n) == pytest.approx(stats.f.ppf(0.95, 2, 2 * n), rel=1e-10)
        assert regions.f1_quantile(0.95, n) == pytest.approx(stats.t.ppf(0.975, n) ** 2, rel=1e-10)
    assert regions.f2_quantile(0.95, None) == pytest.approx(stats.chi2.ppf(0.95, 2) / 2, rel=1e-12)
    assert regions.f2_quantile(0.95, np.inf) == pytest.approx(stats.chi2.ppf(0.95, 2) / 2, rel=1e-12)
    # the 95% radius of docs/statistics.md: sqrt(v n (0.05^(-1/n) - 1))
    assert regions.radius(2.0, 5) == pytest.approx(math.sqrt(2.0 * 5 * (0.05 ** (-1 / 5) - 1)), rel=1e-12)


def test_region_coverage_monte_carlo_four_periods():
    """K = 4 periods of circular complex Gaussian noise: the mean with its sample variance / K and
    n = K - 1 dof. The F(2, 2n) disc covers 95%; the chi-square disc (dof ignored) must under-cover
    (about 87.5%, docs/statistics.md): the negative control."""
    rng = np.random.default_rng(13)
    R, K = 40000, 4
    z = (rng.standard_normal((R, K)) + 1j * rng.standard_normal((R, K))) * 0.3 + (1 - 2j)
    mean = z.mean(1)
    v = (np.abs(z - mean[:, None]) ** 2).sum(1) / (K - 1) / K
    err = np.abs(mean - (1 - 2j))
    cov_f = np.mean(err <= regions.radius(v, K - 1))
    cov_chi = np.mean(err <= regions.radius(v, None))
    se = math.sqrt(0.95 * 0.05 / R)
    assert abs(cov_f - 0.95) < 4 * se, cov_f
    assert cov_chi < 0.90, cov_chi
    # real (DC) lines: t law with n dof
    x = rng.standard_normal((R, K)) * 0.3 + 2.0
    mx = x.mean(1)
    vx = x.var(1, ddof=1) / K
    cov_t = np.mean(np.abs(mx - 2.0) <= regions.radius(vx, K - 1, real=True))
    assert abs(cov_t - 0.95) < 4 * se, cov_t


def test_demo_regions_agree_with_msid_demo(demo):
    """The package's regions on the demo FRF hold the true FRF as often as msid demo reports (the same
    exact law, computed independently)."""
    f = pkg.read_frf(demo / "frf.json")
    truth = load(demo / "truth.json")["lines"]
    assert [t["bin"] for t in truth] == list(f.bins)
    G0 = np.array([np.asarray(t["G"]["re"]) + 1j * np.asarray(t["G"]["im"]) for t in truth])
    inside = int(np.sum(np.abs(f.G - G0) <= f.radius()))
    r = msid("demo", "--out", demo / "again", "--quiet", "--seed", "7")
    reported = int(r.stdout.split(" of ")[0].split()[-1])
    assert inside == reported


def test_subsystem_keeps_the_right_covariance(demo, tmp_path):
    f = pkg.read_frf(demo / "frf.json")
    s = f.subsystem([1], [0, 1])   # output y2, both inputs
    assert s.G.shape == (f.n_lines, 1, 2) and np.array_equal(s.G[:, 0, :], f.G[:, 1, :])
    # vec of the 1x2 sub-matrix: (y2,u1), (y2,u2) = elements 1 and 1 + 2*1 = 3 of the 2x2 vec
    assert np.array_equal(s.cov, f.cov[:, [1, 3]][:, :, [1, 3]])
    assert np.array_equal(s.std()[:, 0, :], f.std()[:, 1, :])
    pkg.write_frf(tmp_path / "s.json", s)
    validate(load(tmp_path / "s.json"), "msid-frf-1")
    msid("validate", demo / "model.json", demo / "frf.json")   # the 2x2 model does not fit a 1x2 file:
    r = msid("validate", demo / "model.json", tmp_path / "s.json", check=False)
    assert r.returncode != 0 and "outputs" in r.stderr


def test_pip_install(demo, tmp_path):
    """`pip install ./tools/python` gives `import msid` outside the source tree (a copy of the package is
    built, offline: --no-build-isolation, so the source tree gets no build/ or egg-info). Files only
    (-C wheel.cmake=false): the compiled module's build is the repository's (docs/python.md)."""
    import shutil
    import subprocess
    import sys
    from conftest import ROOT
    src = tmp_path / "src"
    shutil.copytree(ROOT / "tools" / "python", src, ignore=shutil.ignore_patterns("__pycache__"))
    r = subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-build-isolation", "--no-deps",
                        "--no-index", "-C", "wheel.cmake=false", "--target", str(tmp_path / "site"), str(src)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    # every module and the PEP 561 marker, so that type checkers read the installed package's hints
    installed = {p.name for p in (tmp_path / "site" / "msid").iterdir()}
    assert {p.name for p in (ROOT / "tools" / "python" / "msid").glob("*.py")} | {"py.typed"} <= installed
    code = ("import msid, sys; f = msid.read_frf(sys.argv[1]); "
            "print(msid.__file__, f.G.shape, msid.plot.__name__, msid.report.__name__)")
    env = {k: v for k, v in __import__("os").environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(tmp_path / "site")
    r = subprocess.run([sys.executable, "-c", code, str(demo / "frf.json")], capture_output=True, text=True,
                       env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(str(tmp_path / "site")) and "(14, 2, 2) msid.plot msid.report" in r.stdout
