"""`msid export`: an FRF file as CSV and as MATLAB .mat in the shape of idfrd (docs/python.md).
Read back with the csv module and scipy.io.loadmat (independent readers) and compared with the
package's reader of the JSON file; bad input gives one message and no file."""
import csv

import numpy as np
import pytest
from conftest import msid

import msid as pkg

sio = pytest.importorskip("scipy.io")


def test_csv(demo, tmp_path):
    f = pkg.read_frf(demo / "frf.json")
    out = tmp_path / "frf.csv"
    msid("export", demo / "frf.json", "--csv", out)
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == f.n_lines
    hz, _ = f.hz_axis()
    sd = f.std()
    for k, row in enumerate(rows):
        assert int(row["bin"]) == f.bins[k] and float(row["freq"]) == f.freq[k]
        assert float(row["freq_hz"]) == pytest.approx(hz[k], rel=1e-15)
        assert float(row["omega"]) == pytest.approx(f.omega_axis()[k], rel=1e-15)
        assert float(row["dof"]) == f.dof[k]
        for i in range(2):
            for j in range(2):
                n = f"G_y{i + 1}_u{j + 1}"
                # %.17g: the values round-trip exactly
                assert complex(float(row[n + "_re"]), float(row[n + "_im"])) == f.G[k, i, j]
                assert float(row[n + "_sd"]) == sd[k, i, j]
    # known-input standard deviations differ from the nonparametric ones (noisy inputs in the demo)
    msid("export", demo / "frf.json", "--csv", tmp_path / "ki.csv", "--known-input")
    ki = list(csv.DictReader((tmp_path / "ki.csv").open()))
    assert float(ki[0]["G_y1_u1_sd"]) == f.std("known-input")[0, 0, 0] != sd[0, 0, 0]


def test_mat_in_idfrd_shape(demo, tmp_path):
    f = pkg.read_frf(demo / "frf.json")
    out = tmp_path / "frf.mat"
    msid("export", demo / "frf.json", "--mat", out)
    m = sio.loadmat(out)
    L = f.n_lines
    R = m["ResponseData"]
    assert R.shape == (2, 2, L) and np.iscomplexobj(R)
    assert np.array_equal(np.transpose(R, (2, 0, 1)), f.G)
    assert m["Frequency"].shape == (L, 1) and np.allclose(m["Frequency"][:, 0], f.omega_axis(), rtol=1e-15)
    assert m["Ts"].shape == (1, 1) and m["Ts"][0, 0] == f.sample_time
    C = m["CovarianceData"]
    assert C.shape == (2, 2, L, 2, 2)
    v = f.variance()
    assert np.allclose(np.transpose(C[:, :, :, 0, 0], (2, 0, 1)), v / 2, rtol=1e-15, atol=0)
    assert np.allclose(np.transpose(C[:, :, :, 1, 1], (2, 0, 1)), v / 2, rtol=1e-15, atol=0)
    assert not C[:, :, :, 0, 1].any() and not C[:, :, :, 1, 0].any()
    assert np.array_equal(np.transpose(m["SD"], (2, 0, 1)), f.std())
    assert np.array_equal(m["dof"][:, 0], f.dof) and np.array_equal(m["Bin"][:, 0], f.bins)
    assert str(m["FrequencyUnit"][0]) == "rad/s"


def test_mat_real_line_and_ct(tmp_path):
    """A DC line (real: all variance in Re) and a continuous-time file (Ts = 0, omega from the file),
    written by the package."""
    G = np.array([[[2.0 + 0j]], [[1.0 - 1.0j]]])
    cov = np.array([[[0.04 + 0j]], [[0.09 + 0j]]])
    f = pkg.FRF(G, [0.0, 0.1], bins=[0, 1], cov=cov, dof=[5, 5], real=[True, False], omega=[0.0, 3.0],
                meta={"period_samples": 10, "domain": "ct", "sample_time": 0.2})
    pkg.write_frf(tmp_path / "ct.json", f)
    msid("export", tmp_path / "ct.json", "--mat", tmp_path / "ct.mat")
    m = sio.loadmat(tmp_path / "ct.mat")
    assert m["Ts"][0, 0] == 0 and np.array_equal(m["Frequency"][:, 0], [0.0, 3.0])
    C = m["CovarianceData"]
    assert C[0, 0, 0, 0, 0] == 0.04 and C[0, 0, 0, 1, 1] == 0 and C[0, 0, 1, 0, 0] == C[0, 0, 1, 1, 1] == 0.045
    assert np.allclose(m["FrequencyHz"][:, 0], [0.0, 3.0 / (2 * np.pi)])


def test_mat_confidence_scale_makes_gaussian_regions_exact(tmp_path):
    """showConfidence draws a Gaussian region: at SD standard deviations of CovarianceData a disc of radius
    SD sqrt(v/2) (DC lines: SD sqrt(v)). With CovarianceData95 = CovarianceData .* ConfidenceScale95 and
    SD = SD95 that radius is the exact 95% radius of msid.regions (F(2, 2 dof); DC F(1, dof)) at every dof,
    and the unscaled region is too small by a factor (1.7x at dof 1.6, 1.07x at 12)."""
    dof = np.array([1.6, 12.0, 4.0, 1e6, 3.0])
    real = np.array([False, False, False, False, True])
    L = len(dof)
    v = np.array([0.04, 0.09, 1.0, 0.25, 0.16])
    f = pkg.FRF(np.full((L, 1, 1), 1 + 1j), np.arange(1, L + 1) / 64, bins=np.arange(1, L + 1), cov=v[:, None, None],
                dof=dof, real=real, meta={"period_samples": 64, "domain": "dt", "sample_time": 1e-3})
    f.G[real] = 2.0
    pkg.write_frf(tmp_path / "f.json", f)
    msid("export", tmp_path / "f.json", "--mat", tmp_path / "f.mat")
    m = sio.loadmat(tmp_path / "f.mat")
    sd95 = m["SD95"][0, 0]
    assert sd95 == pytest.approx(np.sqrt(-2 * np.log(0.05)), rel=1e-15)
    C, C95, scale = m["CovarianceData"], m["CovarianceData95"], m["ConfidenceScale95"][:, 0]
    assert np.allclose(C95, C * scale[None, None, :, None, None], rtol=1e-15, atol=0)
    exact = pkg.regions.radius(v, dof, 0.95, real)
    # the Gaussian region's radius: SD times the sd of Re (a circle for the circular complex lines; the DC
    # lines have all their variance on Re)
    drawn = sd95 * np.sqrt(C95[0, 0, :, 0, 0])
    assert np.allclose(drawn, exact, rtol=1e-9), (drawn, exact)
    plain = sd95 * np.sqrt(C[0, 0, :, 0, 0])
    assert exact[0] / plain[0] == pytest.approx(1.714, abs=2e-3) and exact[1] / plain[1] == pytest.approx(1.066, abs=2e-3)
    assert scale[3] == pytest.approx(1.0, abs=1e-5)   # many dof: the Gaussian limit


def test_model_mat_in_ss_shape(demo, tmp_path):
    """msid export model.json --mat: A, B, C, D, Ts and the signal names in the shape ss/idss take, read with
    scipy; the state-space model evaluated from those matrices equals the model's FRF in the file."""
    mdl = pkg.read_model(demo / "model.json")
    out = tmp_path / "model.mat"
    r = msid("export", demo / "model.json", "--mat", out)
    assert "wrote" in r.stdout
    m = sio.loadmat(out)
    n, ny, nu = mdl.order, mdl.n_outputs, mdl.n_inputs
    assert m["A"].shape == (n, n) and m["B"].shape == (n, nu) and m["C"].shape == (ny, n) and m["D"].shape == (ny, nu)
    for k in "ABCD":
        assert np.array_equal(m[k], getattr(mdl, k)), k
    assert m["Ts"][0, 0] == mdl.sample_time
    assert [str(x[0]) for x in m["InputName"][:, 0]] == ["u1", "u2"]
    assert [str(x[0]) for x in m["OutputName"][:, 0]] == ["y1", "y2"]
    assert str(m["Domain"][0]) == "dt" and str(m["Method"][0]) == "ml" and m["Order"][0, 0] == n
    # the model from the .mat at the FRF lines (z = exp(j omega Ts)) is the file's frf[]
    f = pkg.read_frf(demo / "frf.json")
    A, B, Cm, D, Ts = m["A"], m["B"], m["C"], m["D"], m["Ts"][0, 0]
    G = np.array([Cm @ np.linalg.solve(z * np.eye(n) - A, B) + D for z in np.exp(1j * f.omega_axis() * Ts)])
    assert np.abs(G - mdl.frf_G).max() < 1e-10 * np.abs(mdl.frf_G).max()
    # names from the file, and a CT model (Ts 0)
    doc = mdl.doc
    doc.update(input_names=["force", "torque"], output_names=["acc", "vel"], domain="ct")
    pkg.write_model(tmp_path / "named.json", pkg.Model(doc))
    msid("export", tmp_path / "named.json", "--mat", tmp_path / "named.mat")
    m = sio.loadmat(tmp_path / "named.mat")
    assert [str(x[0]) for x in m["InputName"][:, 0]] == ["force", "torque"] and m["Ts"][0, 0] == 0
    assert [str(x[0]) for x in m["OutputName"][:, 0]] == ["acc", "vel"] and str(m["Domain"][0]) == "ct"


def test_bad_input(demo, tmp_path):
    cases = [(["export", demo / "frf.json"], 2, "exactly one of"),
             (["export", demo / "frf.json", "--csv", tmp_path / "a.csv", "--mat", tmp_path / "a.mat"], 2, "exactly one"),
             (["export", demo / "model.json", "--csv", tmp_path / "a.csv"], 2, "--mat only"),
             (["export", demo / "truth.json", "--mat", tmp_path / "a.mat"], 1, "msid-frf/1"),
             (["export", tmp_path / "none.json", "--csv", tmp_path / "a.csv"], 1, "cannot open"),
             (["export", demo / "frf.json", "--mat", tmp_path / "no" / "dir" / "a.mat"], 1, "cannot")]
    for args, code, msg in cases:
        r = msid(*args, check=False)
        assert r.returncode == code and msg in r.stderr, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not any(tmp_path.iterdir())
