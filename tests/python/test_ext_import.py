"""msid.import_frf and msid.read_frf of FRFs measured by other tools (the compiled module's readers, those
of `msid import`), msid.fit / msid.validate on them, and a python-control CT FRD (FRF.from_control
without period_samples) fitted as continuous time. ctest runs this file with MSID_PYTHON_DIR = the
staged package (build/python)."""
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from conftest import msid as cli

import msid

skrf = pytest.importorskip("skrf")
control = pytest.importorskip("control")
SKRF_DATA = Path(skrf.data.__file__).resolve().parent


def _plant():
    # two modes, SISO: 30 and 120 rad/s, light damping
    num = [1.0, 0.0, 5000.0]
    den = np.polymul([1, 6, 900], [1, 24, 14400])
    return control.tf(num, den)


def test_import_frf_equals_the_cli_and_scikit_rf(tmp_path):
    src = SKRF_DATA / "ntwk1.s2p"
    f = msid.import_frf(src)
    ref = skrf.Network(str(src))
    assert f.domain == "ct" and f.sample_time is None and f.cov is None
    np.testing.assert_allclose(f.omega, 2 * np.pi * ref.f, rtol=1e-15)
    np.testing.assert_allclose(f.G, ref.s, rtol=1e-13)
    cli("import", src, "-o", tmp_path / "n.json")
    g = msid.read_frf(tmp_path / "n.json")
    np.testing.assert_array_equal(g.G, f.G)
    np.testing.assert_array_equal(msid.read_frf(src).G, f.G)   # read_frf takes the extension
    assert f.signal_names() == (["a1", "a2"], ["b1", "b2"])


def test_fit_of_an_imported_file_is_the_cli_model(tmp_path):
    src = SKRF_DATA / "ring slot measured.s1p"
    cli("fit", "--method", "ml", "--order", "3", src, "-o", tmp_path / "m.json")
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        m = msid.fit(src, method="ml", order=3)
    assert any("no FRF covariance" in str(x.message) for x in w)
    with open(tmp_path / "m.json") as fh:
        doc = json.load(fh)
    np.testing.assert_array_equal(m.A, np.array(doc["A"]))
    assert m.doc["cost"]["p_value"] is None
    v = msid.validate(m, src)
    assert v.p_value is None and v.consistent is None and "no verdict" in repr(v)


def test_control_ct_frd_fitted_as_continuous_time():
    sys = _plant()
    om = np.geomspace(3, 1000, 90)
    frd = control.frd(sys, om)
    f = msid.FRF.from_control(frd)
    assert f.domain == "ct" and f.sample_time is None and f.meta["period_samples"] == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = msid.fit(f, method="ml", order=4)
    assert m.domain == "ct" and m.sample_time is None
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(m.A)), np.sort_complex(sys.poles()), rtol=1e-6)
    # its document (write_frf) keeps it without a covariance: still unweighted
    d = msid.files.frf_to_doc(f)
    assert "cov" not in d["lines"][0] and d["imported"]["format"] == "python-control FRD"


def test_discrete_frd_without_period_is_refused():
    frd = control.frd(control.c2d(_plant(), 0.001), np.linspace(1, 100, 10))
    with pytest.raises(ValueError, match="period_samples"):
        msid.FRF.from_control(frd)


def test_bad_file_is_one_value_error(tmp_path):
    p = tmp_path / "bad.s2p"
    p.write_text("# Hz S RI R 50\n1 0.1 0.2 0.3\n")
    with pytest.raises(ValueError, match=r"'.*bad.s2p' line 2: 4 numbers"):
        msid.import_frf(p)
    with pytest.raises(OSError):
        msid.import_frf(tmp_path / "missing.s1p")


def test_import_frf_of_a_mat73_file_equals_v5(demo, tmp_path):
    """`msid export --mat` (v5) of the demo's FRF, its variables written again as MATLAB v7.3 (h5py, as
    `save -v7.3` writes them; empty units as MATLAB's empty arrays): msid.import_frf reads the same FRF
    from both, bit for bit, in a process that has h5py's own HDF5 loaded beside libmatio's; msid.fit of
    the v7.3 file is the v5 file's model."""
    scipy_io = pytest.importorskip("scipy.io")
    pytest.importorskip("h5py")
    import helpers
    v5, v73 = tmp_path / "v5.mat", tmp_path / "v73.mat"
    cli("export", demo / "frf.json", "--mat", v5)
    variables = {}
    for k, v in scipy_io.loadmat(v5).items():
        if k.startswith("__"):
            continue
        if v.dtype == object:   # a cell of char rows: N x 1
            variables[k] = [str(c.flat[0]) if c.size else "" for c in v.flat]
        elif v.dtype.kind == "U":
            variables[k] = str(v.flat[0])
        else:
            variables[k] = v
    assert variables["InputUnit"] == ["", ""]
    helpers.write_mat73(v73, variables)
    a, b = msid.import_frf(v5), msid.import_frf(v73)
    for k in ("G", "omega", "freq", "cov", "dof"):
        np.testing.assert_array_equal(getattr(b, k), getattr(a, k), err_msg=k)
    assert b.signal_names() == a.signal_names() == (["u1", "u2"], ["y1", "y2"])
    assert b.signal_units() == a.signal_units()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        np.testing.assert_array_equal(msid.fit(v73, method="ml", order=2).A, msid.fit(v5, method="ml", order=2).A)


def _same_mat_value(a, b):
    """Equal values of scipy.io.loadmat (cell arrays are object arrays of arrays)."""
    if isinstance(a, np.ndarray) and a.dtype == object:
        return isinstance(b, np.ndarray) and a.shape == b.shape and \
            all(_same_mat_value(p, q) for p, q in zip(a.flat, b.flat))
    return np.array_equal(a, b)


def test_export_equals_the_cli(demo, tmp_path, monkeypatch):
    """msid.export (tools/frfexport in process) writes what `msid export` writes: the same CSV bytes, the
    same .mat variables (scipy.io.loadmat), from a file and from the FRF or model object; its refusals are
    the command line's, with nothing written."""
    from no_process import refuse_processes
    scipy_io = pytest.importorskip("scipy.io")
    frf, model = demo / "frf.json", demo / "model.json"
    cli("export", frf, "--csv", tmp_path / "cli.csv")
    cli("export", frf, "--mat", tmp_path / "cli.mat", "--known-input")
    cli("export", model, "--mat", tmp_path / "cli_model.mat")
    with monkeypatch.context() as mp:
        refuse_processes(mp)
        msid.export(frf, tmp_path / "py.csv")
        msid.export(msid.read_frf(frf), tmp_path / "obj.csv")
        msid.export(frf, tmp_path / "py.mat", known_input=True)
        msid.export(msid.read_model(model), tmp_path / "py_model.mat")
    assert (tmp_path / "py.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()
    assert (tmp_path / "obj.csv").read_bytes() == (tmp_path / "cli.csv").read_bytes()
    for a, b in (("py.mat", "cli.mat"), ("py_model.mat", "cli_model.mat")):
        x, y = scipy_io.loadmat(tmp_path / a), scipy_io.loadmat(tmp_path / b)
        keys = sorted(k for k in x if not k.startswith("__"))
        assert keys == sorted(k for k in y if not k.startswith("__")) and ("A" in keys or "ResponseData" in keys)
        for k in keys:
            assert _same_mat_value(x[k], y[k]), k
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(ValueError, match="exports to mat only"):
        msid.export(model, tmp_path / "m.csv")
    with pytest.raises(ValueError, match="give a .csv or .mat"):
        msid.export(frf, tmp_path / "f.txt")
    with pytest.raises(OSError, match="cannot"):
        msid.export(frf, tmp_path / "no" / "dir" / "f.mat")
    assert sorted(p.name for p in tmp_path.iterdir()) == before
