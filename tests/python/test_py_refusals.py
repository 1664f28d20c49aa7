"""The Python API refuses what the command line refuses, before anything is sized
or written. Before the fix fs=inf, fs=1e-320, delta=nan and beta=inf were taken (freq_hz inf, and the
write failed later with "Out of range float values are not JSON compliant"); order=2**31 fitted order 2
(cissim, the command line too) or said "the order must be positive" (ml, subspace); an LPM
window=2**31 said "2W+1 = 1"; Design.crest_factor out of range returned NaN; a sample of 1e307 was
refused by the FRF without its place ("the data's magnitudes are beyond what double precision can
process"), and one of 1e308 dropped its period (a note, the command line too)."""
import os
import re
import subprocess
import warnings

import numpy as np
import pytest

import msid
from child import small_frf

P, LINES = 64, "1:3:20"


@pytest.fixture(scope="module")
def data():
    return small_frf(P, LINES)


@pytest.mark.parametrize("fs", [float("inf"), float("nan"), 1e-320, -1.0])
def test_sample_rates(data, fs):
    d, rec, f = data
    with pytest.raises(ValueError, match="fs"):
        msid.frf(rec, design=d, fs=fs)
    with pytest.raises(ValueError, match="fs"):
        msid.frf(rec, method="lpm", n_inputs=1, fs=fs)


def test_non_finite_options(data):
    d, rec, f = data
    with pytest.raises(ValueError, match="delta must be a finite number, not nan"):
        msid.frf(rec, method="etfe", period=P, n_inputs=1, delta=float("nan"))
    with pytest.raises(ValueError, match="beta must be a finite number, not inf"):
        msid.fit(f, method="ml", order=2, beta=float("inf"))
    with pytest.raises(ValueError, match="alpha must be a finite number"):
        msid.frf(rec, design=d, alpha=float("nan"))
    with pytest.raises(TypeError, match="fs must be a number, not str"):
        msid.frf(rec, design=d, fs="1000")


def test_orders_and_windows_beyond_any_model(data):
    d, rec, f = data
    big = 2 ** 31
    with pytest.raises(ValueError, match=f"order {big} is too large \\(at most 65535"):
        msid.fit([rec], method="cissim", design=d, order=big)
    for method in ("ml", "subspace", "lmfd"):
        with pytest.raises(ValueError, match=f"order {big} is too large \\(at most 65535 states\\)"):
            msid.fit(f, method=method, order=big)
    with pytest.raises(ValueError, match=f"window {big}: a window of 2W\\+1 = {2 * big + 1} bins"):
        msid.frf(rec, method="lpm", n_inputs=1, window=big)
    with pytest.raises(ValueError, match="order must be at most 4294967295"):
        msid.fit(f, method="ml", order=2 ** 40)


def test_design_indices(data):
    d = data[0]
    assert np.isfinite(d.crest_factor(0, 0))
    with pytest.raises(ValueError, match="experiment 1: the design has 1 \\(counted from 0\\)"):
        d.crest_factor(1, 0)
    with pytest.raises(ValueError, match="input 3: the design has 1 \\(counted from 0\\)"):
        d.crest_factor(0, 3)
    with pytest.raises(ValueError, match="experiment 2: the design has 1"):
        d.samples(2, 1)
    with pytest.raises(ValueError, match="more than this machine's memory"):
        d.samples(0, 2 ** 32 - 1)


BEYOND = "is beyond the samples' range (|x| <= 1e+150, whose squares double precision holds): rescale the record"


@pytest.mark.parametrize("value", [1e307, 1e308, -1e200, 2e150])
def test_a_sample_beyond_the_range_is_refused_where_it_is_read(data, tmp_path, value):
    """A sample beyond 1e150 is refused by the reader with its place and cause, in the same words in
    msid.frf (an array, a CSV file, a .npy file) and msid frf (the same files): never a dropped period."""
    d, rec, f = data
    bad = rec.copy()
    bad[3 * P + 5, 1] = value
    shown = f"{value:g}"
    with pytest.raises(ValueError) as e:
        msid.frf(bad, design=d)
    assert str(e.value) == f"'records[0]' row {3 * P + 6}, column 2: {shown} {BEYOND}, e.g. change its units"
    csv, npy, dj = tmp_path / "bad.csv", tmp_path / "bad.npy", tmp_path / "d.json"
    np.savetxt(csv, bad, delimiter=",", header="u1,y1", comments="", fmt="%.17g")
    np.save(npy, bad)
    d.save(dj)
    for path, where, cols in ((csv, f"line {3 * P + 7}, column y1", {}), (npy, f"row {3 * P + 6}, column 2",
                                                                          {"columns": "u1=1,y1=2"})):
        want = f"'{path}' {where}: {shown} {BEYOND}, e.g. change its units"
        with pytest.raises(ValueError) as e:
            msid.frf(str(path), design=d, **cols)
        assert str(e.value) == want
        args = [os.environ["MSID_BIN"], "frf", "--design", dj, "--experiment", path, "-o", tmp_path / "o.json"]
        if cols:
            args += ["--columns", cols["columns"]]
        r = subprocess.run(args, capture_output=True, text=True)
        assert r.returncode == 1 and r.stderr.strip() == f"msid frf: error: {want}", r.stderr
        assert not (tmp_path / "o.json").exists()
    m = msid.Measurement(d)
    with pytest.raises(ValueError, match=re.escape(f"row {3 * P + 6}, column 2: {shown} is beyond the samples' range")):
        m.push(bad, experiment=0)


def test_a_sample_at_the_bound_is_taken(data):
    """The control: 1e150 itself, -0.0 and the smallest subnormal are samples (the FRF is made)."""
    d, rec, f = data
    ok = rec.copy()
    ok[3 * P + 5, 1], ok[3 * P + 6, 1], ok[3 * P + 7, 0] = 1e150, -0.0, 5e-324
    with pytest.warns(msid.NoteWarning):
        g = msid.frf(ok, design=d)
    assert g.n_lines == f.n_lines


def test_step_rules_of_lmfd_only(data, tmp_path):
    """delta and beta are the LMFD refinement's step rules: the pole-residue ml fit (the single-input
    default) refuses them, as the command line does; before the fix they were taken and ignored."""
    d, rec, f = data
    want = "delta and beta are the step rules of param lmfd; the pole-residue fit (param poles) takes neither"
    for kw in (dict(delta=2.0), dict(beta=0.5)):
        with pytest.raises(ValueError) as e:
            msid.fit(f, method="ml", order=2, **kw)
        assert str(e.value) == want
    msid.write_frf(tmp_path / "f.json", f)
    r = subprocess.run([os.environ["MSID_BIN"], "fit", "--method", "ml", "--order", "2", "--delta", "0.5",
                        tmp_path / "f.json", "-o", tmp_path / "m.json"], capture_output=True, text=True)
    assert r.returncode == 2 and "--delta and --beta are the step rules of --param lmfd" in r.stderr, r.stderr
    assert msid.fit(f, method="ml", order=2, param="lmfd", delta=0.5).order == 2


def test_an_interpolating_lmfd_is_noted(tmp_path):
    """lmfd at order 200 on 40 lines (80 real equations per output row, 401 unknowns): the model is one of a
    family that passes through every line, and msid says so (a NoteWarning, model.notes, "unique": false)
    where before it returned the 200-state model with dof 0 and no word. The control: an ml fit of order 4
    has no such note."""
    d = msid.design(period=256, lines="1:40", amplitudes=0.3, seed=1, periods=6)
    u = d.samples(0, 6)
    rec = np.column_stack([u[:, 0], 0.5 * u[:, 0] + 0.01 * np.random.default_rng(1).standard_normal(len(u))])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = msid.frf(rec, design=d, skip_periods=1)
    with pytest.warns(msid.NoteWarning) as w:
        m = msid.fit(f, method="lmfd", order=200)
    want = ("the LMFD with nD = 200, nN = 200 has 401 unknowns per output row for 80 real interpolation equations: "
            "one of a 321-dimensional family of models that pass through every line (dof 0, the cost tests nothing)")
    assert any(n.startswith(want) for n in m.notes) and any(str(x.message).startswith(want) for x in w), m.notes
    assert m.order == 200 and m.doc["unique"] is False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        small = msid.fit(f, method="ml", order=4)
    assert not any("family" in n for n in small.notes), small.notes


@pytest.mark.parametrize("amplitude", [1e308, 1e151, 1e-151])
def test_amplitudes_beyond_the_range_are_refused_by_the_design(amplitude):
    """An amplitude whose square double precision cannot hold is refused where the design is made, as msid
    excite refuses it; before the fix the design was made and the FRF later blamed "a singular input matrix"."""
    with pytest.raises(ValueError, match=re.escape("amplitude of line 1 is not finite and in [1e-150, 1e+150] (the "
                                                   "range whose squares double precision holds)")):
        msid.design(period=256, lines="1:40", amplitudes=amplitude)
    assert msid.design(period=256, lines="1:40", amplitudes=1e150).period == 256


def test_a_non_finite_amplitude_is_quoted_as_given():
    """The amplitudes go through NumPy; the message quotes the number the user gave, not NumPy's repr of it
    (before: "not np.float64(inf)")."""
    for given, shown in ((float("inf"), "inf"), ([0.1, float("nan")], "nan")):
        with pytest.raises(ValueError) as e:
            msid.design(period=256, lines="1:2", amplitudes=given)
        assert str(e.value) == f"amplitudes must be a finite number, not {shown}", str(e.value)
