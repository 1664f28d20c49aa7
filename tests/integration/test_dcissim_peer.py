"""The authors' discrete-cISSIM code (github wyqy/dcissim, You, Huang, Zhang 2023) as an independent
peer of `msid fit --method cissim`, run under Octave by tools/peers/dcissim (README there). Skipped
unless MSID_DCISSIM_DIR names a checkout of that code and octave-cli is on PATH.

  * a SISO plant with poles 0.8 and 0.9, nearly noise-free: the reference returns those poles, and
    its FRF at the lines equals that of msid's estimate on the same terms (`--refine none --reduced
    --unweighted --no-d`, the same block rows), to the noise level;
  * a 2x2 plant (poles 0.9 and 0.8 pairs), one experiment exciting both inputs: the same two checks;
  * negative control: without the svd stand-in (Octave takes svd(X, 'vector') for the economy SVD)
    the reference puts a pole at 0, far from the plant's."""
import math
import os
import shutil
import subprocess

import numpy as np
import pytest

from helpers import ROOT, dt_frf, dt_plant_2x2, dt_simulate, load_json, run_ok

REF = os.environ.get("MSID_DCISSIM_DIR", "")
OCTAVE = shutil.which("octave-cli")
pytestmark = pytest.mark.skipif(
    not REF or not os.path.isfile(os.path.join(REF, "identificator", "idenDCISSIMRunner.m")) or not OCTAVE,
    reason="the authors' code (MSID_DCISSIM_DIR) or octave-cli is not here")
DRIVER = ROOT / "tools" / "peers" / "dcissim"


def record(tmp_path, plant, T, K, lines, rel_noise, seed):
    """K periods of random-phase multisines on `lines` (each input its own phases) through `plant`
    in its periodic steady state, white output noise rel_noise of the output's rms; written as the
    raw float64 rows the driver reads and as CSV for msid."""
    A, B, C, D = plant
    rng = np.random.default_rng(seed)
    n = np.arange(T)
    u1 = np.stack([sum(np.cos(2 * math.pi * b * n / T + rng.uniform(0, 2 * math.pi)) for b in lines)
                   for _ in range(B.shape[1])], axis=1)
    u1 /= u1.std(axis=0)
    u = np.tile(u1, (K, 1))
    y = dt_simulate(plant, u, warmup=4, period=T)
    y += rel_noise * y.std() * rng.standard_normal(y.shape)
    rows = np.c_[u, y]
    rows.astype("<f8").tofile(tmp_path / "e.f64")
    names = [f"u{j + 1}" for j in range(u.shape[1])] + [f"y{i + 1}" for i in range(y.shape[1])]
    np.savetxt(tmp_path / "e.csv", rows, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    return rows.shape[0]


def reference(tmp_path, n_rows, nu, ny, T, lines, order, nbar, driver=DRIVER):
    out = tmp_path / "ref.txt"
    call = (f"msid_dcissim_run('{tmp_path / 'e.f64'}', {n_rows}, {nu}, {ny}, {T}, [{' '.join(map(str, lines))}], "
            f"{order}, {nbar}, 0, '{out}')")
    r = subprocess.run([OCTAVE, "--norc", "--quiet", "--no-history", "--no-window-system", "--path", str(driver),
                        "--eval", call], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    mats = {}
    for line in out.read_text().splitlines():
        f = line.split()
        if f[0] != "seconds":
            rr, cc = int(f[1]), int(f[2])
            mats[f[0]] = np.array([float(v) for v in f[3:]]).reshape(cc, rr).T
    return mats


def msid_paper(tmp_path, T, lines, order, nbar):
    """msid's estimate on the reference's terms: the lines alone, the published Alg. 4, D = 0."""
    out = tmp_path / "m.json"
    run_ok("fit", "--method", "cissim", "--period", T, "--lines", ",".join(map(str, lines)), "--experiment",
           tmp_path / "e.csv", "--order", order, "--block-rows", nbar, "--refine", "none", "--reduced",
           "--unweighted", "--no-d", "--no-covariance", "-o", out)
    d = load_json(out)
    return tuple(np.array(d[k], dtype=float) for k in ("A", "B", "C", "D"))


def frf_gap(a, b, plant, lines, T):
    ga, gb, g0 = dt_frf(a, lines, T), dt_frf(b, lines, T), dt_frf(plant, lines, T)
    return max(np.linalg.norm(x - y) / np.linalg.norm(g) for x, y, g in zip(ga, gb, g0))


def poles(A):
    return np.sort_complex(np.linalg.eigvals(A))


def test_siso_poles_and_frf(tmp_path):
    plant = (np.diag([0.8, 0.9]), np.array([[1.0], [1.0]]), np.array([[1.0, -0.5]]), np.zeros((1, 1)))
    T, K, lines = 200, 20, list(range(1, 100, 2))
    rows = record(tmp_path, plant, T, K, lines, 1e-7, 1)
    ref = reference(tmp_path, rows, 1, 1, T, lines, 2, 4)
    p = poles(ref["A"])
    print("reference poles", p)
    assert np.allclose(p, [0.8, 0.9], atol=1e-6)
    m = msid_paper(tmp_path, T, lines, 2, 4)
    gap = frf_gap((ref["A"], ref["B"], ref["C"], ref["D"]), m, plant, lines, T)
    print(f"reference vs msid (same terms): max FRF difference {gap:.2e} of |G|")
    assert gap < 1e-5
    # negative control: Octave's own svd(X, 'vector') (the economy SVD, S a matrix) in idenACN
    broken = tmp_path / "driver"
    shutil.copytree(DRIVER, broken)
    (broken / "compat" / "svd.m").unlink()
    bad = poles(reference(tmp_path, rows, 1, 1, T, lines, 2, 4, driver=broken)["A"])
    print("reference poles without the svd stand-in", bad)
    assert np.min(np.abs(bad)) < 0.1


def test_mimo_poles_and_frf(tmp_path):
    A, B, C, _ = dt_plant_2x2()
    plant = (A, B, C, np.zeros((2, 2)))
    T, K, lines = 240, 16, list(range(1, 60))
    rows = record(tmp_path, plant, T, K, lines, 1e-7, 2)
    ref = reference(tmp_path, rows, 2, 2, T, lines, 4, 8)
    p = poles(ref["A"])
    print("reference poles", p)
    assert np.allclose(p, poles(A), atol=1e-6)
    m = msid_paper(tmp_path, T, lines, 4, 8)
    gap = frf_gap((ref["A"], ref["B"], ref["C"], ref["D"]), m, plant, lines, T)
    print(f"reference vs msid (same terms): max FRF difference {gap:.2e} of |G|")
    assert gap < 1e-5
