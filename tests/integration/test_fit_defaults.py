"""Defaults of `msid fit` that must hold without asking (docs/fitting.md, "Defaults and their rules"):
stable models under model error, pooled weights that never make ml worse than per-line weights,
and ml that never ends above a start it had. Monte Carlo with fixed seeds on simulated plants:
the structures of tools/peers/msid_peers/structures.py with nonlinear distortion added, and DT plants
(2x2 and SISO, orders 2-10) with per-line covariances of a chosen shape and dof."""
import json
import math

import numpy as np
import pytest

import helpers as h
from msid_peers import structures as S


# --- simulated files ---------------------------------------------------------------------------

def dt_plant(order, ny, nu, seed, poles=None):
    """Random stable DT plant of the given order: pole pairs (and one real pole for an odd order)
    with radii in [0.6, 0.95] and angles spread over the band; B, C, D standard normal."""
    rng = np.random.default_rng(seed)
    npair = order // 2
    if poles is None:
        ang = np.sort(rng.uniform(0.05, 0.45, npair)) * 2 * np.pi if npair else np.zeros(0)
        poles = list(rng.uniform(0.6, 0.95, npair) * np.exp(1j * ang))
    A = np.zeros((order, order))
    for k, p in enumerate(poles[:npair]):
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[p.real, p.imag], [-p.imag, p.real]]
    if order % 2:
        A[-1, -1] = rng.uniform(-0.8, 0.8)
    return {"A": A, "B": rng.standard_normal((order, nu)), "C": rng.standard_normal((ny, order)),
            "D": 0.3 * rng.standard_normal((ny, nu))}


def dt_frf(pl, z):
    A, B, C, D = pl["A"], pl["B"], pl["C"], pl["D"]
    return np.array([C @ np.linalg.solve(zz * np.eye(len(A)) - A, B) + D for zz in z])


def dt_doc(pl, seed, n_lines=202, dof=1000, snr_db=10.0, shape="smooth", distortion=0.0):
    """msid-frf/1 of a DT plant at bins 1..n_lines of P = 2 n_lines + 2: per line a covariance
    Gamma_l (shape 'smooth': correlations that change slowly over the band; 'rough': a random
    shape per line), G = G0 + CN(0, Gamma_l) [+ distortion: an error of that many noise sd that the
    covariance does not hold], and the sample covariance of `dof` complex dof."""
    ny, nu = pl["C"].shape[0], pl["B"].shape[1]
    g = ny * nu
    P = 2 * n_lines + 2
    bins = np.arange(1, n_lines + 1)
    G0 = dt_frf(pl, np.exp(2j * np.pi * bins / P))
    s2 = np.mean(np.abs(G0) ** 2) * 10 ** (-snr_db / 10)
    rng = np.random.default_rng(1000 + seed)
    crng = np.random.default_rng(5)          # the covariance shapes: the same for every noise set
    lines = []
    for k in range(n_lines):
        if shape == "rough":
            A = crng.standard_normal((g, g)) + 1j * crng.standard_normal((g, g))
        else:
            t = k / n_lines
            A = np.eye(g, dtype=complex)
            if g > 1:
                A[0, 1], A[1, g - 1], A[g - 1, 0] = 0.8 * math.cos(3 * t), 0.8 * math.sin(2 * t), 0.4
        Gam = A @ A.conj().T
        Gam = Gam / np.real(np.trace(Gam)) * g * s2
        L = np.linalg.cholesky(Gam)
        cn = lambda *sh: (rng.standard_normal(sh) + 1j * rng.standard_normal(sh)) / math.sqrt(2)
        e = L @ cn(g)
        Z = L @ cn(g, dof)
        Gm = G0[k] + e.reshape((ny, nu), order="F") + distortion * math.sqrt(s2) * cn(ny, nu)
        S_ = Z @ Z.conj().T / dof
        lines.append({"bin": int(bins[k]), "freq": float(bins[k] / P), "omega": float(2 * math.pi * bins[k] / P),
                      "G": {"re": Gm.real.tolist(), "im": Gm.imag.tolist()},
                      "cov": {"re": S_.real.tolist(), "im": S_.imag.tolist()}, "dof": dof, "snr": []})
    return {"format": "msid-frf/1", "period_samples": P, "n_inputs": nu, "n_outputs": ny, "n_experiments": 1,
            "domain": "dt", "periods_used": dof + 1, "periods_rejected": 0,
            "noise_cov": {"re": (np.eye(ny) * s2).tolist(), "im": np.zeros((ny, ny)).tolist()},
            "experiments": [], "lines": lines}


def truth_doc(pl):
    ny, nu = pl["C"].shape[0], pl["B"].shape[1]
    return {"format": "msid-model/1", "domain": "dt", "method": "truth", "order": len(pl["A"]),
            "n_inputs": nu, "n_outputs": ny, "A": pl["A"].tolist(), "B": pl["B"].tolist(),
            "C": pl["C"].tolist(), "D": pl["D"].tolist()}


def write(path, doc):
    path.write_text(json.dumps(doc))
    return path


def fit(tmp, frf, name, *args):
    out = tmp / f"{name}.json"
    r = h.run("fit", *args, frf, "-o", out)
    return r, (h.load_json(out) if out.exists() else None)


def h2_error(tmp, model, truth):
    r = h.run_ok("compare", model, truth, "-o", tmp / "cmp.json")
    assert r.returncode == 0
    return h.load_json(tmp / "cmp.json")["h2_rel"]


def model_G(doc):
    return np.array([h.cplx(e["G"]) for e in doc["frf"]])


def cost_on(frf_path, Gm, C):
    _, G, _ = S.load_frf(frf_path)
    return S.weighted_cost(G, Gm, C)


# The plant: 2x2, order 6, three well-separated pole pairs (one heavily damped at 0.35).
EASY6 = [0.95 * np.exp(2j * np.pi * 0.08), 0.9 * np.exp(2j * np.pi * 0.2), 0.7 * np.exp(2j * np.pi * 0.35)]


# --- 1. stable models by default ---------------------------------------------------------------

def test_stable_by_default_under_nonlinear_distortion(tmp_path):
    """Structures whose FRF holds an error the covariance does not (one realisation with nonlinear
    distortion: p = 0 for any linear model). At an order with room for spurious poles the
    unconstrained fits (--allow-unstable, the negative control) come out unstable in some seeds;
    every default fit, ml and subspace, CT and DT, is stable and says which rule applied."""
    unstable_free = 0
    runs = 0
    for seed in range(4):
        st = S.structure("siso", seed, n_modes=6)
        doc = S.frf_doc(st, seed, n_lines=160, periods=8)
        rng = np.random.default_rng(300 + seed)
        for ln in doc["lines"]:   # distortion: 20x the noise sd of the mean, not in the covariance
            sd = math.sqrt(ln["cov"]["re"][0][0])
            ln["G"]["re"][0][0] += 20 * sd * rng.standard_normal() / math.sqrt(2)
            ln["G"]["im"][0][0] += 20 * sd * rng.standard_normal() / math.sqrt(2)
        p = write(tmp_path / f"nl{seed}.json", doc)
        for method in ("ml", "subspace"):
            r, m = fit(tmp_path, p, f"{method}{seed}", "--method", method, "--domain", "ct", "--order", 16)
            assert r.returncode in (0, 3), r.stderr
            assert m["cost"]["p_value"] < 1e-6                     # the model is rejected: model error
            assert m["stable"] is True and m["stability"]["enforced"] is True, (method, seed, m["stability"])
            assert m["stability"]["max_real_pole"] < 0
            assert m["settings"]["stability"] == "stable (default)"
            r, u = fit(tmp_path, p, f"{method}{seed}u", "--method", method, "--domain", "ct", "--order", 16,
                       "--allow-unstable")
            assert r.returncode in (0, 3), r.stderr
            assert u["settings"]["stability"] == "allow-unstable" and u["stability"]["enforced"] is False
            unstable_free += not u["stable"]
            runs += 1
    print(f"unconstrained fits unstable: {unstable_free}/{runs}")
    assert unstable_free >= 2          # the constraint is what keeps the default fits stable
    # DT, 2x2 (ml's LMFD parametrisation) with distortion, at an order above the plant's
    uf = 0
    for seed in range(3):
        pl = dt_plant(6, 2, 2, 50 + seed, EASY6)
        p = write(tmp_path / f"dt{seed}.json", dt_doc(pl, seed, n_lines=120, dof=40, snr_db=30, distortion=15))
        for method in ("ml", "subspace"):
            r, m = fit(tmp_path, p, f"dt{method}{seed}", "--method", method, "--order", 10)
            assert r.returncode in (0, 3), r.stderr
            assert m["stable"] is True and m["stability"]["enforced"] is True, (method, seed, m["stability"])
            assert m["stability"]["max_abs_pole"] < 1
            r, u = fit(tmp_path, p, f"dt{method}{seed}u", "--method", method, "--order", 10, "--allow-unstable")
            uf += not u["stable"]
    print(f"DT unconstrained fits unstable: {uf}/6")
    # --stable stays accepted (the default's rule, named), --stable with --allow-unstable is refused
    r, m = fit(tmp_path, tmp_path / "nl0.json", "st", "--method", "ml", "--domain", "ct", "--order", 16, "--stable")
    assert m["settings"]["stability"] == "stable" and m["stable"] is True
    r, _ = fit(tmp_path, tmp_path / "nl0.json", "bad", "--method", "ml", "--domain", "ct", "--order", 16, "--stable",
               "--allow-unstable")
    assert r.returncode == 2 and "contradicts" in r.stderr


# --- 2. pooled weights never worse than per-line weights -----------------------------------------

CASES = [("rough", 8), ("rough", 1000), ("smooth", 8), ("smooth", 1000)]


@pytest.mark.parametrize("shape,dof", CASES)
def test_pooled_never_worse_than_per_line(tmp_path, shape, dof):
    """2x2 DT order 6, 202 lines, 10 dB: ml's error against the truth with the default weights over
    that with each line's own (--weight-smooth 0). Covariances whose shape changes from line to line
    (rough) must not make pooling worse (measured 1.000 with 8 dof; the trace-only test, negative
    control in docs/fitting.md, made it 1.011 at 8 dof and pooled the 1000-dof lines);
    smooth ones must make it better where the dof are small (measured 0.755) and, with 1000 dof, the
    line's own weights are precise: nothing is pooled, the fits are the same."""
    pl = dt_plant(6, 2, 2, 50, EASY6)
    truth = write(tmp_path / "truth.json", truth_doc(pl))
    ratios = []
    seeds = range(6) if dof < 100 else range(2)
    for seed in seeds:
        p = write(tmp_path / f"f{seed}.json", dt_doc(pl, seed, dof=dof, shape=shape))
        r, mp = fit(tmp_path, p, "pooled", "--method", "ml", "--order", 6)
        assert r.returncode == 0, r.stderr
        e_pool = h2_error(tmp_path, tmp_path / "pooled.json", truth)
        r, m0 = fit(tmp_path, p, "line", "--method", "ml", "--order", 6, "--weight-smooth", 0)
        assert r.returncode == 0, r.stderr
        e_line = h2_error(tmp_path, tmp_path / "line.json", truth)
        pool = mp["settings"]["weight_pooling"]
        if dof >= 1000:   # 1000/997: precise own weights, nothing pooled, the same fit
            assert pool["pooled"] == 0 and pool["precise_own_weights"] == 202
            assert mp["cost"]["value"] == m0["cost"]["value"] and e_pool == e_line
        ratios.append(e_pool / e_line)
        print(f"{shape} dof {dof} seed {seed}: pooled {e_pool:.4g} per-line {e_line:.4g} {pool}")
    mean = float(np.mean(ratios))
    print(f"{shape} dof {dof}: mean error ratio pooled / per-line {mean:.4f}")
    if shape == "rough":
        assert mean <= 1.005, ratios
    else:
        assert mean <= (0.85 if dof < 100 else 1.0), ratios


# --- 3. ml never ends above a start it had ------------------------------------------------------

def test_easy_sixth_order_converges(tmp_path):
    """The issue's case: 2x2 DT, 3 well-separated pole pairs, 202 lines, 1000-dof covariances whose
    correlations change from line to line. ml converges (exit 0) and ends no higher than the subspace
    model it starts from, for the default and per-line weights."""
    pl = dt_plant(6, 2, 2, 50, EASY6)
    for seed in range(3):
        p = write(tmp_path / f"f{seed}.json", dt_doc(pl, seed, dof=1000, shape="rough", snr_db=5))
        for extra in ((), ("--weight-smooth", 0)):
            r, m = fit(tmp_path, p, "ml", "--method", "ml", "--order", 6, *extra)
            assert r.returncode == 0 and m["converged"] is True, (seed, extra, r.stderr)
            r, s = fit(tmp_path, p, "sub", "--method", "subspace", "--order", 6, *extra)
            assert m["cost"]["value"] <= s["cost"]["value"] * (1 + 1e-9), (seed, m["cost"], s["cost"])
            assert m["cost"]["value"] <= m["cost_start"] * (1 + 1e-12) + 1e-9


def test_ml_never_above_its_starts(tmp_path):
    """Random DT plants, SISO (pole-residue form) and 2x2 (LMFD form), orders 2-10, 120 lines, smooth
    covariances with 15 dof (pooled weights) or 400 dof (each line's own): ml's cost,
    on the weights it minimises, is no higher than that of every start it lists and than the model
    `msid fit --method subspace` writes on the same file. ml converges on all but at most 2 (random
    plants can hold flat valleys where LM creeps; the easy case above must converge)."""
    worst = 0.0
    n_runs = 0
    slow = []   # ran out of iterations (exit 3): the guarantee below holds for the best iterate too
    for i in range(30):
        siso = i < 15
        order = 2 + i % 9 if siso else 2 * (1 + (i - 15) % 5)   # the LMFD's order: a multiple of ny
        ny = nu = 1 if siso else 2
        pl = dt_plant(order, ny, nu, 700 + i)
        dof = 15 if i % 2 else 400
        p = write(tmp_path / f"r{i}.json", dt_doc(pl, i, n_lines=120, dof=dof, snr_db=20))
        # --feedthrough yes: the same model class for every start and the end (auto may drop D after
        # the search, by its likelihood-ratio test, at a cost above the starts')
        r, m = fit(tmp_path, p, "ml", "--method", "ml", "--order", order, "--feedthrough", "yes")
        assert r.returncode in (0, 3) and m["converged"] is (r.returncode == 0), (i, order, r.stderr)
        if r.returncode == 3:
            slow.append((i, order, "siso" if siso else "2x2"))
        r, s = fit(tmp_path, p, "sub", "--method", "subspace", "--order", order, "--feedthrough", "yes")
        assert r.returncode == 0, r.stderr
        # the cost ml minimises, and the subspace model's on the same weights (pooled when msid pools)
        Cw = S.pooled_cov(str(p))
        V_ml = cost_on(p, model_G(m), Cw)
        V_sub = cost_on(p, model_G(s), Cw)
        mine = m["cost"].get("fit_cost_smoothed_weights", m["cost"]["value"])
        assert abs(mine - V_ml) <= 1e-8 * V_ml, (i, mine, V_ml)   # the same weights as msid's
        assert V_ml <= V_sub * (1 + 1e-9), (i, order, V_ml, V_sub)
        if "starts" in m:
            assert all(V_ml <= st["cost"] * (1 + 1e-9) for st in m["starts"]), (i, m["starts"], V_ml)
            assert any(st["start"] == "subspace-refined" for st in m["starts"])
        else:
            assert V_ml <= m["cost_start"] * (1 + 1e-9)
        worst = max(worst, V_ml / V_sub)
        n_runs += 1
    print(f"{n_runs} plants: largest ml / subspace cost {worst:.6f}; out of iterations: {slow}")
    # convergence: every plant but the slow valleys of random plants (measured: one 2x2 of order 8,
    # 200 iterations from 453.66 to 439.62, 439.37 after 2000; the pole-residue form creeps there too)
    assert len(slow) <= 2, slow


# --- an FRF without covariance (another tool's): standard deviations from the residual variance --------

def test_no_covariance_sds_from_the_residual_variance(tmp_path):
    """A CT FRF as an analogue instrument gives it (frequency, re, im; no covariance, no sample time):
    the SISO column of helpers.ct_plant_2x2 (a mode at 24.7 Hz, zeta 0.26, and a real pole) on 80 lines,
    white complex noise of variance sigma^2 = (2% of the median |G|)^2 on every line, 100 seeds, ml at
    the right order. The unit-weight fit scales its covariances by s^2 = 2 V / (2 L - n_params):
    - s^2 is unbiased for sigma^2 (mean within 3%);
    - the mode frequency's reported standard deviation matches its spread over the seeds (ratio within
      0.8-1.25) and its 95% interval covers the truth about 95% of the time;
    - control: the standard deviations of unit noise, what msid reported before (sd / s), miss the
      spread by the factor 1/sigma (about 80 here)."""
    from test_import import _ct_csv
    plant = h.ct_plant_2x2()
    om = np.geomspace(10, 5000, 80)
    G0 = h.ct_frf(plant, om)[:, :1, :1]
    sigma = 0.02 * np.median(np.abs(G0))
    rng = np.random.default_rng(41)
    true_fn = abs(np.linalg.eigvals(plant[0])[0]) / (2 * np.pi)
    fn, sd, s2 = [], [], []
    for k in range(100):
        G = G0 + sigma * (rng.standard_normal(G0.shape) + 1j * rng.standard_normal(G0.shape)) / np.sqrt(2)
        csv = tmp_path / "a.csv"
        _ct_csv(csv, om, G, names=("y1",), ins=("u1",))
        r = h.run("fit", "--method", "ml", "--order", 3, csv, "-o", tmp_path / "m.json")
        assert r.returncode == 0, r.stderr
        m = h.load_json(tmp_path / "m.json")
        mode = [x for x in m["modes"]["modes"] if not x["real_pole"]]
        assert len(mode) == 1, m["modes"]
        fn.append(mode[0]["fn"])
        sd.append(mode[0]["sd_fn"])
        s2.append(m["residual_variance"])
        if k == 0:
            assert "rest on the fit's residual variance" in r.stdout + r.stderr
    fn, sd, s2 = np.array(fn), np.array(sd), np.array(s2)
    assert abs(s2.mean() / sigma**2 - 1) < 0.03, (s2.mean(), sigma**2)
    ratio = fn.std(ddof=1) / sd.mean()
    cover = np.mean(np.abs(fn - true_fn) <= 1.96 * sd)
    print(f"s^2/sigma^2 {s2.mean() / sigma**2:.4f}, spread/sd {ratio:.3f}, 95% coverage {cover:.2f}")
    assert 0.8 < ratio < 1.25, ratio
    assert 0.90 <= cover <= 0.99, cover
    unit = sd / np.sqrt(s2)   # the control: unit noise
    assert not 0.8 < fn.std(ddof=1) / unit.mean() < 1.25
