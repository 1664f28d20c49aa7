"""Names and units carried through: a CSV whose columns are called "Force [N]" and "Acc [m/s^2]"
(or mapped so with --columns) gives frf.json input_names/output_names and input_units/output_units;
the package, the Bode plot (titles, |G| in m/s^2/N), the .mat export (InputName, InputUnit, ... as
idfrd takes them, read back by scipy) and python-control keep them. Files whose columns are u1/y1
(or a .npy's bare numbers) get no such keys: the files msid wrote before are unchanged."""
import json

import numpy as np
import pytest
from conftest import msid

import msid as pkg

sio = pytest.importorskip("scipy.io")

P, K, BINS = 64, 4, [1, 2, 3, 5, 8]


def _record(seed=3):
    """A first-order plant in steady state, 4 periods, a little output noise: columns u, y."""
    rng = np.random.default_rng(seed)
    n = np.arange(P * K)
    u = np.zeros(n.size)
    y = np.zeros(n.size)
    for b in BINS:
        w, ph = 2 * np.pi * b / P, rng.uniform(0, 2 * np.pi)
        G = 0.5 / (1 - 0.6 * np.exp(-1j * w))
        u += np.cos(w * n + ph)
        y += abs(G) * np.cos(w * n + ph + np.angle(G))
    return np.column_stack([u, y + 1e-3 * rng.standard_normal(n.size)])


def _csv(path, header):
    rows = _record()
    with open(path, "w") as fh:
        fh.write(",".join(header) + "\n")
        for r in rows:
            fh.write(f"{r[0]:.17g},{r[1]:.17g}\n")
    return path


def _frf(tmp_path, rec, *extra):
    out = tmp_path / "frf.json"
    msid("frf", "--period", P, "--lines", ",".join(map(str, BINS)), "--fs", 1000, "--experiment", rec, "-o", out,
         *extra)
    return out


def test_header_names_and_units_reach_every_output(tmp_path):
    out = _frf(tmp_path, _csv(tmp_path / "r.csv", ['"Force [N]"', '"Acc [m/s^2]"']),
               "--columns", "u1=Force [N],y1=Acc [m/s^2]")
    doc = json.loads(out.read_text())
    assert doc["input_names"] == ["Force"] and doc["output_names"] == ["Acc"]
    assert doc["input_units"] == ["N"] and doc["output_units"] == ["m/s^2"]
    f = pkg.read_frf(out)
    assert f.signal_names() == (["Force"], ["Acc"])
    assert f.signal_units() == (["N"], ["m/s^2"])
    assert f.gain_unit(0, 0) == "m/s^2/N"
    # the Bode plot: the pair's title and |G| in its unit
    fig = pkg.plot.bode(f)
    labels = [a.get_ylabel() for a in fig.axes]
    titles = [a.get_title() for a in fig.axes]
    assert "|G| (dB re 1 m/s^2/N)" in labels and "Acc / Force" in titles
    # MATLAB: idfrd's InputName/OutputName/InputUnit/OutputUnit, read by scipy
    msid("export", out, "--mat", tmp_path / "frf.mat")
    m = sio.loadmat(tmp_path / "frf.mat")
    assert str(m["InputName"][0, 0][0]) == "Force" and str(m["OutputName"][0, 0][0]) == "Acc"
    assert str(m["InputUnit"][0, 0][0]) == "N" and str(m["OutputUnit"][0, 0][0]) == "m/s^2"
    # the model carries them on (the names of the FRF it was fitted to), and its .mat export
    msid("fit", "--method", "subspace", "--order", 1, out, "-o", tmp_path / "model.json")
    mod = pkg.read_model(tmp_path / "model.json")
    assert mod.signal_names() == (["Force"], ["Acc"]) and mod.signal_units() == (["N"], ["m/s^2"])
    msid("export", tmp_path / "model.json", "--mat", tmp_path / "model.mat")
    mm = sio.loadmat(tmp_path / "model.mat")
    assert str(mm["InputName"][0, 0][0]) == "Force" and str(mm["OutputUnit"][0, 0][0]) == "m/s^2"
    # python-control
    ct = pytest.importorskip("control")
    frd = f.to_control()
    assert list(frd.input_labels) == ["Force"] and list(frd.output_labels) == ["Acc"]
    del ct


def test_mapped_names_without_units(tmp_path):
    """--columns maps plain names: names, and no unit keys (none is known)."""
    out = _frf(tmp_path, _csv(tmp_path / "r.csv", ["F", "a"]), "--columns", "u1=F,y1=a")
    doc = json.loads(out.read_text())
    assert doc["input_names"] == ["F"] and doc["output_names"] == ["a"]
    assert "input_units" not in doc and "output_units" not in doc
    f = pkg.read_frf(out)
    assert f.signal_units() == ([""], [""]) and f.gain_unit(0, 0) == ""
    msid("export", out, "--mat", tmp_path / "frf.mat")
    m = sio.loadmat(tmp_path / "frf.mat")
    assert m["InputUnit"][0, 0].size == 0   # an empty unit, as idfrd has by default


@pytest.mark.parametrize("kind", ["csv", "CSV", "npy"])
def test_default_columns_add_no_keys(tmp_path, kind):
    """u1/y1 columns (in either case, as the readers match them; and a .npy's columns 1, 2) are the
    defaults: no names or units are written."""
    rec = (_csv(tmp_path / "r.csv", ["u1", "y1"] if kind == "csv" else ["U1", "Y1"]) if kind != "npy"
           else tmp_path / "r.npy")
    if kind == "npy":
        np.save(rec, _record())
    extra = ("--columns", "u1=1,y1=2") if kind == "npy" else ()
    doc = json.loads(_frf(tmp_path, rec, *extra).read_text())
    for k in ("input_names", "output_names", "input_units", "output_units"):
        assert k not in doc
    assert pkg.read_frf(tmp_path / "frf.json").signal_names() == (["u1"], ["y1"])
