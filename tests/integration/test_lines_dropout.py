"""`msid frf --lines auto` where the force drops out: a shaker test simulated as loggers write it (P =
1024 at 1 kHz, 3 periods, an odd multisine on bins 1..301 from a generator, the measured force 35 dB down
over a structural resonance at 60-73 Hz and near the 50 Hz mains, noise on force and acceleration). The
F test cannot take those bins over 3 periods. Without a reference msid names them (stdout, a note, the
file's lines_auto block) instead of dropping them silently; with the generator's signal logged as
column r1 (or named by --reference) every excited bin is found and the FRF holds the truth. Controls:
no drop-out names nothing; detection lines of the grid without any input are not named. Fixed seeds."""
import json

import numpy as np

import helpers as h

P, FS, K = 1024, 1000.0, 3
ODD = np.arange(1, 302, 2)
RESONANCE = [k for k in ODD if 61 <= k <= 75]    # 59.6-73.2 Hz
MAINS = [49, 51, 53]                              # 47.9-51.8 Hz
DROP = 10 ** (-35 / 20)


def plant(k):
    """Acceleration per force: a lightly damped mode at 68 Hz."""
    s = 2j * np.pi * k * FS / P
    w = 2 * np.pi * 68.0
    return s * s / (s * s + 2 * 0.02 * w * s + w * w)


def shaker(tmp, name, drop=True, detection=(), seed=4, ref_name="r1", with_ref=True):
    """A CSV of u1 (force), y1 (acceleration) and optionally the generator's signal; returns its path."""
    rng = np.random.default_rng(seed)
    lines = np.array([k for k in ODD if k not in detection])
    R = np.zeros(P // 2 + 1, complex)
    R[lines] = np.exp(2j * np.pi * rng.random(lines.size)) * P / 2
    U = R.copy()
    if drop:
        U[RESONANCE + MAINS] *= DROP
    Y = U * plant(np.arange(P // 2 + 1))
    r, u, y = (np.tile(np.fft.irfft(X, P), K) for X in (R, U, Y))
    u = u + 0.0876 * rng.standard_normal(u.size)
    y = y + 0.01 * rng.standard_normal(y.size)
    cols, head = [u, y], ["u1", "y1"]
    if with_ref:
        cols.append(r)
        head.append(ref_name)
    path = tmp / name
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(head), comments="", fmt="%.12g")
    return path


def frf(tmp, path, *extra):
    out = tmp / (path.stem + ".frf.json")
    r = h.run("frf", "--period", str(P), "--lines", "auto", "--fs", str(FS), "--experiment", str(path), *extra,
              "-o", str(out))
    assert r.returncode == 0, r.stderr
    return json.loads(out.read_text()), r


def test_dropout_lines_named_without_reference(tmp_path):
    doc, r = frf(tmp_path, shaker(tmp_path, "e.csv", with_ref=False))
    la = doc["lines_auto"]
    bins = [ln["bin"] for ln in doc["lines"]]
    assert sorted(set(ODD) - set(bins)) == sorted(RESONANCE + MAINS)   # the F test lost them
    assert la["undecided_bins"] == sorted(RESONANCE + MAINS)            # and msid names every one
    assert la["grid"] == {"step": 2, "first": 1, "last": 301} and la["silent_grid_bins"] == 0
    assert la["from"] == "the inputs"
    note = [ln for ln in r.stderr.splitlines() if ln.startswith("msid frf: note: --lines auto: 11 bin(s) of the")]
    assert len(note) == 1, r.stderr
    assert "(bins 1 to 301 in steps of 2)" in note[0] and "47.85-51.76 Hz, 59.57-73.24 Hz" in note[0]
    assert "--reference r1=COLUMN" in note[0] and "excitation's grid" not in r.stdout


def test_reference_column_finds_every_line(tmp_path):
    doc, r = frf(tmp_path, shaker(tmp_path, "e.csv"))   # the file's own r1: used without asking
    bins = [ln["bin"] for ln in doc["lines"]]
    assert bins == list(ODD)
    assert doc["lines_auto"]["from"] == "the reference r1=r1" and doc["lines_auto"]["undecided_bins"] == []
    assert "of the reference" in r.stdout and "note" not in r.stderr
    # the FRF holds the plant within its exact 95% region, also where the force dropped
    G = np.array([ln["G"]["re"][0][0] + 1j * ln["G"]["im"][0][0] for ln in doc["lines"]])
    var = np.array([ln["cov"]["re"][0][0] for ln in doc["lines"]])
    z = np.abs(G - plant(np.array(bins))) ** 2 / var
    # |e|^2 / var is F(2, 2n) with n = dof: P(F > x) = (1 + x/n)^-n, so the 95% quantile is n (0.05^(-1/n) - 1)
    n = doc["lines"][0]["dof"]
    q95 = n * (0.05 ** (-1 / n) - 1)
    inside = z <= q95
    assert inside.mean() >= 0.85, (inside.mean(), np.flatnonzero(~inside))
    assert inside[[bins.index(k) for k in RESONANCE + MAINS]].mean() >= 0.8


def test_named_reference_and_errors(tmp_path):
    path = shaker(tmp_path, "gen.csv", ref_name="Gen")
    doc, _ = frf(tmp_path, path, "--reference", "r1=Gen", "--columns", "u1=u1,y1=y1")   # Gen is not u/y: mapped
    assert [ln["bin"] for ln in doc["lines"]] == list(ODD)
    assert doc["lines_auto"]["from"] == "the reference r1=Gen"
    r = h.run("frf", "--period", str(P), "--lines", "1:301:2", "--experiment", str(path), "--reference", "r1=Gen",
              "--columns", "u1=u1,y1=y1", "-o", str(tmp_path / "x.json"))
    assert r.returncode == 2 and "--reference applies to --lines auto" in r.stderr
    r = h.run("frf", "--period", str(P), "--lines", "auto", "--experiment", str(path), "--reference", "r1=Generator",
              "--columns", "u1=u1,y1=y1", "-o", str(tmp_path / "x.json"))
    assert r.returncode != 0 and "Generator" in r.stderr
    assert not (tmp_path / "x.json").exists()


def test_controls_name_nothing_that_is_not_undecided(tmp_path):
    # no drop-out: every odd bin found, nothing named
    doc, r = frf(tmp_path, shaker(tmp_path, "flat.csv", drop=False, with_ref=False))
    assert [ln["bin"] for ln in doc["lines"]] == list(ODD)
    assert doc["lines_auto"]["undecided_bins"] == [] and "excitation's grid" not in r.stdout
    # detection lines (every 4th odd bin without input): left out of the grid, named only where the
    # noise happens to pass the 5% level (about 1 in 20 of them)
    det = list(ODD[3:-1:4])
    doc, _ = frf(tmp_path, shaker(tmp_path, "det.csv", drop=False, detection=det, with_ref=False))
    la = doc["lines_auto"]
    assert [ln["bin"] for ln in doc["lines"]] == [k for k in ODD if k not in det]
    assert la["silent_grid_bins"] + len(la["undecided_bins"]) == len(det)
    assert len(la["undecided_bins"]) <= 0.15 * len(det)
    assert set(la["undecided_bins"]) <= set(det)
