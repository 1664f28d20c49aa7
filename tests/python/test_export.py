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


def test_bad_input(demo, tmp_path):
    cases = [(["export", demo / "frf.json"], 2, "exactly one of"),
             (["export", demo / "frf.json", "--csv", tmp_path / "a.csv", "--mat", tmp_path / "a.mat"], 2, "exactly one"),
             (["export", demo / "model.json", "--mat", tmp_path / "a.mat"], 1, "msid-frf/1"),
             (["export", tmp_path / "none.json", "--csv", tmp_path / "a.csv"], 1, "cannot open"),
             (["export", demo / "frf.json", "--mat", tmp_path / "no" / "dir" / "a.mat"], 1, "cannot")]
    for args, code, msg in cases:
        r = msid(*args, check=False)
        assert r.returncode == code and msg in r.stderr, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert not any(tmp_path.iterdir())
