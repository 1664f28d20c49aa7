"""`msid fit` on simulated structures as a bench engineer meets them:
12 modes (2 rigid-body), 0.5-2% damping, accelerations (direct feedthrough),
60-80 dB dynamic range, 267 lines, SISO, 1x3 and 2x3 — against vector fitting
(scikit-rf's VectorFitting, the independent peer) at the same order; feedthrough
choice, stability, non-convergence, unit invariance of fit and validate, and the
M >= 4 refusal for any number of outputs. Generator: tools/peers/msid_peers/structures.py."""
import functools
import json
import os

import numpy as np
import pytest

import helpers as h
from msid_peers import structures as S

SEED = 2          # dynamic range 65 dB (SISO), 77 dB (1x3), 78 dB (2x3)
# The peer comparison in ctest: SISO and 2x3 (scikit-rf needs ~30 s on the 1x3 case, where the
# padded 3x3 network converges slowly); MSID_FULL_STRUCTURES=1 adds 1x3. `msid bench fit --only 3`
# compares all three cases (and a 10-mode SISO) side by side.
KINDS = ["siso", "1x3", "2x3"] if os.environ.get("MSID_FULL_STRUCTURES") else ["siso", "2x3"]


@functools.lru_cache(maxsize=None)
def _vector_fit(path, n):
    """scikit-rf once per (file, order) for the whole module."""
    return S.vector_fit(path, n)[0]


def _fit(tmp, frf, name, *args, ok=True):
    out = tmp / f"{name}.json"
    r = h.run("fit", *args, "--domain", "ct", frf, "-o", out)
    if ok:
        assert r.returncode == 0, r.stderr
    return r, (h.load_json(out) if out.exists() else None)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    d = tmp_path_factory.mktemp("structures")
    out = {}
    for kind in ("siso", "1x3", "2x3"):
        st = S.structure(kind, SEED)
        p = S.write(d / f"{kind}.json", S.frf_doc(st, SEED))
        om, G, C = S.load_frf(p)
        out[kind] = {"st": st, "path": p, "om": om, "G": G, "C": C, "G0": S.frf(st, 1j * om), "dir": d}
    return out


@pytest.mark.parametrize("kind", KINDS)
def test_ml_and_subspace_against_vector_fitting(data, kind):
    D = data[kind]
    n = S.order(D["st"])                                      # 24: 12 modes
    assert 60 <= S.dynamic_range_db(D["G0"]) <= 80
    Gvf = _vector_fit(D["path"], n)
    V_vf, e_vf = S.weighted_cost(D["G"], Gvf, D["C"]), S.rel_error(Gvf, D["G0"])
    _, ml = _fit(D["dir"], D["path"], f"ml-{kind}", "--method", "ml", "--order", n)
    h.validate(ml, "msid-model-1")
    Gml = np.array([h.cplx(e["G"]) for e in ml["frf"]])
    V_ml, e_ml = S.weighted_cost(D["G"], Gml, D["C"]), S.rel_error(Gml, D["G0"])
    print(f"{kind}: ml V = {V_ml:.6g} rel {e_ml:.3g}; vector fitting V = {V_vf:.6g} rel {e_vf:.3g}")
    assert ml["converged"] is True and ml["stable"] is True
    assert ml["feedthrough"]["included"] is True            # accelerations: direct term found by auto
    assert abs(ml["cost"]["value"] - V_ml) < 1e-6 * V_ml      # the file's cost is eq. (40) on the same weights
    # ml's weighted cost, eq. (40) on the weights it minimises (each line's covariance pooled with
    # its neighbours', --weight-smooth 4; computed here independently of msid), no worse than vector
    # fitting's on the same weights. On each line's own 16-period covariance (the file's cost above)
    # ml can land on either side of vector fitting when a pole pair is free (SISO 12 modes, seed 2:
    # 1.0004 with the relaxed vector-fitting start, 0.994 without; 48 seeds in docs/benchmarks.md)
    Cp = S.pooled_cov(D["path"])
    Vp_ml, Vp_vf = S.weighted_cost(D["G"], Gml, Cp), S.weighted_cost(D["G"], Gvf, Cp)
    print(f"{kind}: pooled weights: ml V = {Vp_ml:.6g}, vector fitting V = {Vp_vf:.6g}")
    assert abs(ml["cost"]["fit_cost_smoothed_weights"] - Vp_ml) < 1e-9 * Vp_ml
    assert Vp_ml <= Vp_vf * (1 + 1e-9), (Vp_ml, Vp_vf)
    # relative error against the measured FRF: as good as vector fitting's (within 2%)
    d_ml, d_vf = S.rel_error(Gml, D["G"]), S.rel_error(Gvf, D["G"])
    assert d_ml <= d_vf * 1.02, (d_ml, d_vf)
    # against the truth, at the order the data identify: the SISO structure's weakest mode (9.96 Hz)
    # is below the noise, so at the nominal 24 one pole pair is free and any cost minimiser spends
    # it on the noise; how far depends on the basin it reaches (ml / vector fitting 1.015 before the
    # relaxed vector-fitting start, 1.029 with it; over 48 seeds 1.045 and 1.060, docs/benchmarks.md).
    # At 22 (and on 2x3 at 24, where every mode is seen) the comparison is of estimators, not basins.
    # Per-line weights from M = 16 periods cost the sample-ML factor (--weight-smooth 0: measured
    # 1.09 SISO, 1.12 2x3); the default pools each line's covariance over 9 neighbouring lines
    # (135 dof): measured 0.993 (SISO) and 0.99 (2x3), bound 1.04
    n_nom = n
    if kind == "siso":
        n = n - 2
        Gvf = _vector_fit(D["path"], n)
        e_vf = S.rel_error(Gvf, D["G0"])
        _, ml = _fit(D["dir"], D["path"], f"ml22-{kind}", "--method", "ml", "--order", n)
        e_ml = S.rel_error(np.array([h.cplx(e["G"]) for e in ml["frf"]]), D["G0"])
    assert e_ml <= e_vf * 1.04, (e_ml, e_vf)
    # negative control: with per-line weights the same bound fails on both cases
    _, ml0 = _fit(D["dir"], D["path"], f"ml0-{kind}", "--method", "ml", "--order", n, "--weight-smooth", 0)
    e_ml0 = S.rel_error(np.array([h.cplx(e["G"]) for e in ml0["frf"]]), D["G0"])
    print(f"{kind}: ml per-line weights rel {e_ml0:.4g}, pooled {e_ml:.4g}")
    assert e_ml0 > e_vf * 1.04 and ml0["settings"].get("weight_smooth") is None and ml["settings"]["weight_smooth"] == 4
    # ... and the measured argument for that gap (docs/fitting.md): with the true
    # weights (white homoscedastic noise here, so --weight none) ml's error against the truth is
    # vector fitting's (measured -0.5% SISO at 22, -0.5% 2x3)
    _, mlt = _fit(D["dir"], D["path"], f"mlt-{kind}", "--method", "ml", "--order", n, "--weight", "none")
    e_mlt = S.rel_error(np.array([h.cplx(e["G"]) for e in mlt["frf"]]), D["G0"])
    print(f"{kind}: ml with the true weights rel {e_mlt:.4g} (vector fitting {e_vf:.4g})")
    assert e_mlt <= e_vf * 1.02, (e_mlt, e_vf)
    assert e_ml <= e_mlt * 1.03, (e_ml, e_mlt)        # pooled weights: within 3% of the true weights
    # the covariance is usable by the modal step: full rank (identifiable pole-residue form)
    assert ml["parameters"]["cov_rank"] == len(ml["parameters"]["names"]) == ml["n_params"]
    # the default subspace model (no --stable: stable unless the data need unstable poles, refined)
    _, sub = _fit(D["dir"], D["path"], f"sub-{kind}", "--method", "subspace", "--order", n_nom)
    Gs = np.array([h.cplx(e["G"]) for e in sub["frf"]])
    V_sub = S.weighted_cost(D["G"], Gs, D["C"])
    print(f"{kind}: subspace V = {V_sub:.6g} ({V_sub / V_vf:.3g}x vector fitting), stable {sub['stable']}")
    assert sub["stable"] is True and sub["stability"]["stable"] is True
    assert V_sub <= 2 * V_vf, (V_sub, V_vf)


def test_negative_control_under_modelled(data):
    # the same comparison cannot pass vacuously: at order 12 (half the modes) ml's cost is far
    # above the order-24 vector fit, and validate says NOT consistent
    D = data["siso"]
    Gvf = _vector_fit(D["path"], 24)
    _, ml = _fit(D["dir"], D["path"], "ml-under", "--method", "ml", "--order", 12)
    assert ml["cost"]["value"] > 10 * S.weighted_cost(D["G"], Gvf, D["C"])
    r = h.run_ok("validate", D["dir"] / "ml-under.json", D["path"])
    assert "NOT consistent" in r.stdout


def test_subspace_cost_does_not_rise_with_order(data):
    # on the same data a subspace model of order n costs no more than the one of
    # order n - 2 (docs/fitting.md, "Subspace refinement"); the default model is stable (item 2)
    D = data["siso"]
    costs, raw = [], []
    for n in (16, 20, 24, 28, 32):
        _, m = _fit(D["dir"], D["path"], f"sub{n}", "--method", "subspace", "--order", n)
        costs.append(m["cost"]["value"])
        raw.append(m["subspace"]["refine"]["cost_before"])
        assert m["stable"] is True and m["stability"]["stable"] is True, (n, m["stability"])
        assert m["cost"]["value"] <= m["subspace"]["refine"]["cost_before"] * (1 + 1e-12)
    print("subspace cost per order 16..32:", costs, "before refinement:", raw)
    assert all(b <= a * (1 + 1e-9) for a, b in zip(costs, costs[1:])), costs
    # at the true order (24) the refined model is at the noise level: within 30% of the expected cost
    assert costs[2] < 1.3 * 260, costs


def test_subspace_unconstrained_control(data):
    # negative control: --allow-unstable --refine 0 is the bare r-scan estimate, which on this
    # structure is unstable and not monotone in the order (the property above is not vacuous)
    D = data["siso"]
    c = {}
    for n in (24, 28):
        _, m = _fit(D["dir"], D["path"], f"raw{n}", "--method", "subspace", "--order", n, "--allow-unstable", "--refine", 0)
        c[n] = m["cost"]["value"]
        assert m["stability"]["enforced"] is False
    assert c[28] > c[24], c


def test_order_40_ml(data):
    # high order: over-modelled by 16 poles, still a model (never refused), stable, at most the order-24 cost
    D = data["siso"]
    _, m24 = _fit(D["dir"], D["path"], "ml24", "--method", "ml", "--order", 24)
    r, m40 = _fit(D["dir"], D["path"], "ml40", "--method", "ml", "--order", 40, ok=False)
    assert r.returncode in (0, 3), r.stderr
    assert m40["order"] == 40 and m40["cost"]["value"] <= m24["cost"]["value"] * (1 + 1e-9)
    assert 0 < m40["parameters"]["cov_rank"] <= len(m40["parameters"]["names"])


def test_not_converged_writes_the_best_iterate(data, tmp_path):
    D = data["1x3"]
    out = tmp_path / "nc.json"
    r = h.run("fit", "--method", "ml", "--order", 24, "--domain", "ct", "--max-iter", 1, D["path"], "-o", out)
    assert r.returncode == 3, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "did not converge" in lines[0] and '"converged": false' in lines[0]
    m = h.load_json(out)
    h.validate(m, "msid-model-1")
    assert m["converged"] is False and m["gradient_norm"] > 0 and m["cost"]["value"] > 0


@pytest.mark.parametrize("kind,quantity,expect", [("siso", "acc", True), ("2x2", "acc", True), ("siso", "vel", False)])
def test_feedthrough_auto(tmp_path, kind, quantity, expect):
    st = S.structure(kind, SEED, quantity=quantity)
    p = S.write(tmp_path / "f.json", S.frf_doc(st, SEED))
    om, G, C = S.load_frf(p)
    G0 = S.frf(st, 1j * om)
    # the order the data identify: the SISO structure's weakest mode is below the noise, and at the
    # nominal order ml spends that free pole pair on a pseudo-constant when D = 0 is forced (the
    # relaxed vector-fitting start finds it: error 1.43e-4 against 1.55e-4 with D, cost 268.7
    # against 264.4), so the bias of the wrong model class shows where no pair is free
    n = S.order(st) - (2 if kind == "siso" else 0)
    errs = {}
    for method in ("ml", "subspace"):
        for ft in ("auto", "yes", "no"):
            # forcing D = 0 on accelerance data is the wrong model class: ml may run out of iterations (exit 3)
            r, m = _fit(tmp_path, p, f"{method}-{ft}", "--method", method, "--order", n, "--feedthrough", ft, ok=False)
            assert r.returncode == 0 or (r.returncode == 3 and ft == "no" and expect), r.stderr
            Gm = np.array([h.cplx(e["G"]) for e in m["frf"]])
            errs[method, ft] = S.rel_error(Gm, G0)
            assert m["feedthrough"]["mode"] == ft
            if ft == "auto":
                assert m["feedthrough"]["included"] is expect, (method, m["feedthrough"])
                assert m["feedthrough"]["lr_p_value"] is not None
    if expect:
        assert errs["ml", "auto"] < errs["ml", "no"] / 3, errs      # forcing D = 0 biases accelerance fits
    assert errs["ml", "auto"] < 5e-3, errs


@pytest.mark.parametrize("method", ["ml", "subspace"])
def test_stable_option(data, method):
    D = data["1x3"]
    _, m = _fit(D["dir"], D["path"], f"st-{method}", "--method", method, "--order", 24, "--stable")
    assert m["stable"] is True and m["stability"]["enforced"] is True and m["stability"]["max_real_pole"] < 0
    assert m["cost"]["value"] > 0


def _scaled(D, tmp, a, b):
    return S.write(tmp / f"scaled-{a}-{b}.json", S.frf_doc(D["st"], SEED, out_scale=a, in_scale=b))


@pytest.mark.parametrize("args", [("--method", "ml", "--order", 24), ("--method", "subspace", "--order", 24),
                                  ("--method", "subspace",), ("--method", "ml", "--order", 24, "--weight", "none")])
def test_unit_invariance(data, tmp_path, args):
    # outputs in mm/s^2 instead of m/s^2 and the force in kN: no verdict, p-value, order or relative error changes
    D = data["1x3"]
    ref = _scaled(D, tmp_path, 1.0, 1.0)
    sc = _scaled(D, tmp_path, 1e3, 1e-3)
    res = []
    for p in (ref, sc):
        _, m = _fit(tmp_path, p, "m-" + p.stem, *args)
        v = tmp_path / f"v-{p.stem}.json"
        h.run_ok("validate", tmp_path / f"m-{p.stem}.json", p, "-o", v)
        om, G, _ = S.load_frf(p)
        Gm = np.array([h.cplx(e["G"]) for e in m["frf"]])
        res.append((m["order"], m["cost"]["p_value"], m["feedthrough"]["included"], S.rel_error(Gm, G),
                    h.load_json(v)["p_value"], h.load_json(v)["consistent_at_5pct"]))
    (o1, p1, f1, e1, vp1, c1), (o2, p2, f2, e2, vp2, c2) = res
    assert o1 == o2 and f1 == f2 and c1 == c2
    assert abs(e1 - e2) <= 1e-6 * e1
    assert abs(p1 - p2) <= 1e-6 + 1e-6 * p1 and abs(vp1 - vp2) <= 1e-6 + 1e-6 * vp1, (p1, p2, vp1, vp2)


@pytest.mark.parametrize("kind,periods", [("1x3", 2), ("siso", 3)])
def test_refusal_three_outputs_two_periods(tmp_path, kind, periods):
    # siso at M = 3: ml pools its weights over 9 lines (dof 18) and checked the periods on the pooled
    # weights, so it wrote a model whose own p-value was 0 while subspace refused (fixed 2026-11-24)
    st = S.structure(kind, SEED)
    p = S.write(tmp_path / "f.json", S.frf_doc(st, SEED, periods=periods))
    for method in ("ml", "subspace"):
        r = h.run("fit", "--method", method, "--order", 24, "--domain", "ct", p, "-o", tmp_path / "o.json")
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 1 and len(lines) == 1, r.stderr
        assert "M >= 4" in lines[0] and f"{periods} periods" in lines[0] and "singular weights" not in lines[0], lines[0]
        assert not (tmp_path / "o.json").exists()


def test_pole_residue_modal_sd_monte_carlo(tmp_path):
    # ml's default (pole-residue) models carry delta-method sd of f_n and zeta;
    # 100 runs of a 4-mode accelerance at 2% noise: reported sd match the spread (bound 25%: the
    # sample sd of 100 runs scatters by ~7%; the 150-run study in docs/fitting.md measures 0.88-1.01)
    st = S.structure("siso", 3, n_modes=4)
    fn, zs, sfn, sz = [], [], [], []
    R = 100
    for r in range(R):
        p = S.write(tmp_path / "mc.json", S.frf_doc(st, 1000 + r, periods=16, noise=0.02))
        _, m = _fit(tmp_path, p, "mc", "--method", "ml", "--order", 8, "--feedthrough", "yes")
        modes = sorted((x for x in m["modes"]["modes"] if not x["real_pole"]), key=lambda x: x["fn"])
        assert len(modes) == 4 and "pole-residue" in m["modes"]["sd_source"]
        fn.append([x["fn"] for x in modes]); zs.append([x["zeta"] for x in modes])
        sfn.append([x["sd_fn"] for x in modes]); sz.append([x["sd_zeta"] for x in modes])
    fn, zs, sfn, sz = map(np.array, (fn, zs, sfn, sz))
    rf = fn.std(0, ddof=1) / np.sqrt((sfn ** 2).mean(0))
    rz = zs.std(0, ddof=1) / np.sqrt((sz ** 2).mean(0))
    print("empirical / reported sd: f_n", np.round(rf, 3), "zeta", np.round(rz, 3))
    assert np.all(np.abs(rf - 1) < 0.25) and np.all(np.abs(rz - 1) < 0.25), (rf, rz)
    # unbiased: the mean within 4 standard errors of the truth
    assert np.all(np.abs(fn.mean(0) - st["f"]) < 4 * fn.std(0, ddof=1) / np.sqrt(R))


def _true_lmfd(st):
    """SISO accelerance as N(s)/D(s), D(0) = 1: coefficients in the file's order (D1.., N0..)."""
    P = np.polynomial.polynomial
    dens = [np.array([1.0, 2 * z / (2 * np.pi * f), 1 / (2 * np.pi * f) ** 2]) for f, z in zip(st["f"], st["zeta"])]
    D = functools.reduce(P.polymul, dens)
    N = st["grb"][0, 0] * D
    for k in range(len(dens)):
        rest = functools.reduce(P.polymul, [d for j, d in enumerate(dens) if j != k], np.array([1.0]))
        N = P.polyadd(N, P.polymul(np.array([0, 0, st["phi"][0, k] * st["psi"][0, k] / (2 * np.pi * st["f"][k]) ** 2]), rest))
    return dict({f"D{i}[1,1]": D[i] for i in range(1, len(D))}, **{f"N{j}[1,1]": N[j] for j in range(len(N))})


def _finite_paths(x, path=""):
    if isinstance(x, dict):
        return [p for k, v in x.items() for p in _finite_paths(v, f"{path}/{k}")]
    if isinstance(x, list):
        return [p for i, v in enumerate(x) for p in _finite_paths(v, f"{path}[{i}]")]
    return [path] if x is None or (isinstance(x, float) and not np.isfinite(x)) else []


def _covered(misses, n, p=0.05):
    """A 95% statement holds unless n trials with that many misses are improbable (1e-3)."""
    from math import comb
    return sum(comb(n, k) * p ** k * (1 - p) ** (n - k) for k in range(misses, n + 1)) >= 1e-3


def test_lmfd_ml_bounds_finite_and_covering(tmp_path):
    # `ml --param lmfd` wrote a null theta bound on 16-20 of 25 noisy 4-mode sets
    # (sigma_min(J) from J^T J, condition 2e12 squared). The 25 sets of the modal Monte Carlo:
    # every number finite, Theorem 5's bounds (45)-(46) and the covariance's 95% intervals cover.
    st = S.structure("siso", 3, n_modes=4)
    th0 = _true_lmfd(st)
    R, e_frf, e_th, b_frf, b_th, z = 25, [], [], [], [], []
    for r in range(R):
        p = S.write(tmp_path / "mc.json", S.frf_doc(st, 1000 + r, periods=16, noise=0.02))
        _, m = _fit(tmp_path, p, "lm", "--method", "ml", "--param", "lmfd", "--order", 8)
        assert _finite_paths(m) == [], (r, _finite_paths(m)[:5])
        pr, b = m["parameters"], m["bounds"]
        assert pr["cov_rank"] == len(pr["values"]) == 17 and b["jacobian_rank"] == 17 and b["sigma_min_jacobian"] > 0
        th = np.array(pr["values"]) - np.array([th0[n] for n in pr["names"]])
        z += list(th / np.sqrt(np.diag(pr["cov"])))
        om = np.array([e["omega"] for e in m["frf"]])
        dG = np.array([h.cplx(e["G"]) for e in m["frf"]]) - S.frf(st, 1j * om)
        e_frf.append(np.sqrt(2) * np.linalg.norm(dG)); e_th.append(np.linalg.norm(th))   # calG stacks +-omega
        b_frf.append(b["frf"]); b_th.append(b["theta"])
    e_frf, e_th, b_frf, b_th, z = map(np.array, (e_frf, e_th, b_frf, b_th, z))
    miss_ci = int(np.sum(np.abs(z) > 1.96))
    print(f"misses of {R}: frf bound {np.sum(e_frf > b_frf)}, theta bound {np.sum(e_th > b_th)}; "
          f"median error/bound frf {np.median(e_frf / b_frf):.3g} theta {np.median(e_th / b_th):.3g}; "
          f"95% intervals miss {miss_ci} of {z.size}, sd(z) {z.std():.3f}")
    assert _covered(int(np.sum(e_frf > b_frf)), R) and _covered(int(np.sum(e_th > b_th)), R)
    # the 17 intervals of a run are strongly correlated: a band, not a binomial test (measured 2.6%, sd 0.88)
    ci_ok = lambda zz: np.mean(np.abs(zz) > 1.96) <= 0.10 and abs(zz.std() - 1) < 0.2
    assert ci_ok(z), (miss_ci, z.std())
    # negative controls: the same test fails for bounds shrunk to the median error, or a covariance
    # at a quarter of its size (sd halved)
    assert not _covered(int(np.sum(e_th > np.median(e_th))), R)
    assert not _covered(int(np.sum(e_frf > np.median(e_frf))), R)
    assert not ci_ok(2 * z)


def test_pooled_weights_monte_carlo(tmp_path):
    # ml's default pooled weights (--weight-smooth 4) against per-line weights, 60 runs of a
    # 4-mode accelerance at 2% noise, 16 periods: error against the truth lower, the model FRF's 95%
    # regions cover, validate (each line's own covariance) rejects about 5% at 5%
    st = S.structure("siso", 3, n_modes=4)
    R, err, err0, pv, z2 = 60, [], [], [], []
    for r in range(R):
        p = S.write(tmp_path / "mc.json", S.frf_doc(st, 2000 + r, periods=16, noise=0.02))
        om, G, C = S.load_frf(p)
        G0 = S.frf(st, 1j * om)
        _, m = _fit(tmp_path, p, "m", "--method", "ml", "--order", 8)
        _, m0 = _fit(tmp_path, p, "m0", "--method", "ml", "--order", 8, "--weight-smooth", 0)
        Gm = np.array([h.cplx(e["G"]) for e in m["frf"]])
        err.append(S.rel_error(Gm, G0)); err0.append(S.rel_error(np.array([h.cplx(e["G"]) for e in m0["frf"]]), G0))
        z2 += [abs(Gm[l, 0, 0] - G0[l, 0, 0]) ** 2 / h.cplx(e["cov"])[0, 0].real for l, e in enumerate(m["frf"])]
        h.run_ok("validate", tmp_path / "m.json", p, "-o", tmp_path / "v.json")
        pv.append(h.load_json(tmp_path / "v.json")["p_value"])
    err, err0, pv, z2 = map(np.array, (err, err0, pv, z2))
    rej = int(np.sum(pv < 0.05))
    cover = lambda q: np.mean(q <= np.log(20))          # |dG|^2 / var ~ Exp(1) for a complex scalar
    print(f"rel. error vs truth: pooled {err.mean():.4g}, per-line {err0.mean():.4g} ({err.mean() / err0.mean():.3f}x); "
          f"validate rejects {rej}/{R} at 5%; model FRF 95% regions cover {cover(z2):.3f}")
    assert err.mean() < err0.mean() and np.mean(err < err0) > 0.5
    assert _covered(rej, R) and _covered(R - rej, R, 0.95), rej   # binomial at 1e-3, both tails
    assert 0.93 <= cover(z2) <= 0.985, cover(z2)
    assert not (0.93 <= cover(4 * z2) <= 0.985)          # negative control: regions of half the radius
    # negative control of the rejection test: one mode left out, validate rejects almost always
    _, mu = _fit(tmp_path, p, "mu", "--method", "ml", "--order", 6)
    h.run_ok("validate", tmp_path / "mu.json", p, "-o", tmp_path / "vu.json")
    assert h.load_json(tmp_path / "vu.json")["p_value"] < 0.05


def test_ml_against_vector_fitting_monte_carlo(tmp_path):
    # ml's error against the truth no worse than vector fitting's at the same order, on
    # average over noise seeds (one realisation cannot tell: per seed the ratio scatters by ~1.3%).
    # The 10-mode SISO structure of `msid bench fit --only 3` holds a mode whose peak is 0.1 x the
    # noise sd (6.28 Hz, residue 1e-4): the data identify 9 modes, order 18. At the nominal 20 the
    # free pole pair is spent on the noise by any cost minimiser (ml: cost 1.2% below vector
    # fitting's, error 6% above, 20 seeds; docs/benchmarks.md); at 18 ml and vector fitting agree
    # (20 seeds: mean ratio 1.003, se 0.003). 5 seeds here (vector fitting takes seconds per fit),
    # `msid bench fit --only 3 --runs 20` prints the rest.
    st = S.structure("siso", SEED, n_modes=10)
    n = S.order(st) - 2
    ratio, ratio0, ratio_nom, cost = [], [], [], []
    for seed in range(5):
        p = S.write(tmp_path / f"mc{seed}.json", S.frf_doc(st, seed))
        om, G, C = S.load_frf(p)
        G0 = S.frf(st, 1j * om)
        Gvf = S.vector_fit(p, n)[0]
        e_vf, V_vf = S.rel_error(Gvf, G0), S.weighted_cost(G, Gvf, C)
        err = {}
        for name, order, extra in (("ml", n, ()), ("ml0", n, ("--weight-smooth", 0)), ("nominal", n + 2, ())):
            _, m = _fit(tmp_path, p, name, "--method", "ml", "--order", order, *extra)
            Gm = np.array([h.cplx(e["G"]) for e in m["frf"]])
            err[name] = S.rel_error(Gm, G0)
            if name == "ml":
                cost.append(S.weighted_cost(G, Gm, C) / V_vf)
        ratio.append(err["ml"] / e_vf); ratio0.append(err["ml0"] / e_vf); ratio_nom.append(err["nominal"] / e_vf)
    ratio, ratio0, ratio_nom, cost = map(np.array, (ratio, ratio0, ratio_nom, cost))
    print(f"ml / vector fitting at order {n}: error ratio mean {ratio.mean():.4f} median {np.median(ratio):.4f} "
          f"(per seed {np.round(ratio, 4)}), cost ratio mean {cost.mean():.5f}; per-line weights {ratio0.mean():.4f}; "
          f"ml at the nominal order {n + 2} over vector fitting at {n}: {ratio_nom.mean():.4f}")
    assert ratio.mean() <= 1.015, ratio          # measured 1.0059 (seeds 0-4), 1.0028 (0-19)
    assert cost.mean() <= 1.001, cost            # the cost: ml minimises it with pooled weights (measured 0.9997)
    # negative controls: worse ml fails the same bound. (a) each line's own 16-period sample
    # covariance as weight (--weight-smooth 0, the weighting bias of Gonzalez et al. 2025): measured
    # 1.024; (b) one pole pair too many (the nominal order): measured 1.16
    assert ratio0.mean() > 1.015, ratio0
    assert ratio_nom.mean() > 1.05, ratio_nom


def test_subspace_refinement_on_pooled_weights(tmp_path):
    # msid fit --method subspace refines the r-scan model on the covariances pooled over 2H+1 lines
    # (as ml weighs), not on each line's own M-period sample covariance, whose scatter costs accuracy
    # (the weighting bias and variance of sample ML, Gonzalez et al. 2025). 2x2 accelerance, 4 modes,
    # M = 6 periods, 20 noise seeds: the error against the truth over that of the per-line refinement
    # (--weight-smooth 0, the negative control) measured 0.83 mean, lower in 19 of 20; the p-value of
    # the reported (per-line) cost stays calibrated (60 seeds: 3/60 below 5%, docs/fitting.md).
    st = S.structure("2x2", 3, n_modes=4)
    n = S.order(st)
    ratio, ps = [], []
    for seed in range(20):
        p = S.write(tmp_path / f"p{seed}.json", S.frf_doc(st, 100 + seed, periods=6, noise=0.02))
        om, G, C = S.load_frf(p)
        G0 = S.frf(st, 1j * om)
        err = {}
        for name, extra in (("pool", ()), ("line", ("--weight-smooth", 0))):
            _, m = _fit(tmp_path, p, name, "--method", "subspace", "--order", n, *extra)
            err[name] = S.rel_error(np.array([h.cplx(e["G"]) for e in m["frf"]]), G0)
            if name == "pool":
                ps.append(m["cost"]["p_value"])
                assert m["settings"]["weight_smooth"] == 4 and m["stable"]
        ratio.append(err["pool"] / err["line"])
    ratio = np.array(ratio)
    print(f"pooled / per-line refinement: error ratio mean {ratio.mean():.4f}, lower in {(ratio < 1).sum()}/20; "
          f"p-values {np.round(ps, 3)}")
    assert ratio.mean() < 0.92 and (ratio < 1).sum() >= 15, ratio
    assert sum(p < 0.05 for p in ps) <= 4, ps


def _unidentified(m):
    """1-based indices of the modes msid marks NOT identified (the contribution test, docs/fitting.md)."""
    return [k + 1 for k, e in enumerate(m["modes"]["modes"]) if e.get("identified") is False]


def _check_contribution_tests(m):
    """The contribution test of every complex mode recomputed independently from the model file: in the
    pole-residue form (SISO) v = (Re p, Im p, Re R, Im R) are parameters, so S_v is a block of the
    parameter covariance (no delta method through an eigen-decomposition); dc/dv by central differences."""
    pr = m["parameters"]
    names, th, cov = pr["names"], np.array(pr["values"]), np.array(pr["cov"])
    x = 1j * np.array([e["omega"] for e in m["frf"]])

    def contrib(v):
        p, R = v[0] + 1j * v[1], v[2] + 1j * v[3]
        c = R / (x - p) + np.conj(R) / (x - np.conj(p))
        return np.concatenate([c.real, c.imag])

    W = {}
    for k in range(1, len(names)):
        if f"p{k}.im" not in names:
            break
        idx = [names.index(n) for n in (f"p{k}.re", f"p{k}.im", f"R{k}[1,1].re", f"R{k}[1,1].im")]
        v, S = th[idx], cov[np.ix_(idx, idx)]
        B = np.column_stack([(contrib(v + dv) - contrib(v - dv)) / (2 * dv.sum())
                             for dv in np.diag(1e-6 * np.maximum(np.abs(v), 1e-3))])
        ev, V = np.linalg.eigh(S)
        c = contrib(v)
        W[(v[0], abs(v[1]))] = float(np.sum(np.linalg.lstsq(B @ V @ np.diag(np.sqrt(np.maximum(ev, 0))),
                                                                             c, rcond=1e-9)[0] ** 2))
    checked = 0
    for e in m["modes"]["modes"]:
        if e["real_pole"]:
            continue
        key = min(W, key=lambda q: abs(complex(*q) - complex(*e["pole"])))
        assert abs(complex(*key) - complex(*e["pole"])) < 1e-6 * abs(complex(*key))
        assert e["contribution_test"]["chi2"] == pytest.approx(W[key], rel=2e-3), (key, e["contribution_test"], W[key])
        checked += 1
    assert checked == len(W) > 0


def test_modes_the_data_do_not_identify(tmp_path):
    # At an over-sized order ml spends the free pole pairs on the noise (what no
    # cost minimiser avoids: docs/benchmarks.md). msid says so: a mode whose contribution to the FRF at
    # the fitted lines is within the noise (Wald test of the contribution, p >= 1e-3) is marked NOT
    # identified, in the model file and the table. 12 noise seeds per case (24 in docs/fitting.md).
    # Structure 2, 10 modes: one mode 0.1 x the noise (the data identify order 18); structure 4,
    # 12 modes: two modes below the noise (modal products 1e-5 and 2e-8: order 20 of 24); structure 1,
    # 10 modes: every mode visible (negative control, at the nominal order).
    cases = (("s2-20", 2, 10, 20), ("s2-18", 2, 10, 18), ("s1-20", 1, 10, 20), ("s4-24", 4, 12, 24))
    counts = {}
    for name, sseed, modes, order in cases:
        st = S.structure("siso", sseed, n_modes=modes)
        counts[name] = []
        for seed in range(12):
            p = S.write(tmp_path / f"{name}-{seed}.json", S.frf_doc(st, seed))
            r, m = _fit(tmp_path, p, f"ml-{name}", "--method", "ml", "--order", order, ok=False)
            assert r.returncode in (0, 3), r.stderr
            bad = _unidentified(m)
            counts[name].append(len(bad))
            assert ("NOT identified" in r.stdout) == bool(bad), r.stdout
            for e in m["modes"]["modes"]:
                t = e["contribution_test"]
                assert 0 <= t["p_value"] <= 1 and t["dof"] >= 1 and e["identified"] == (t["p_value"] < 1e-3)
            if seed == 0:
                _check_contribution_tests(m)
    print({k: np.bincount(v).tolist() for k, v in counts.items()})
    # measured (12 seeds): s2-20 [0, 12], s2-18 [12], s1-20 [12], s4-24 [0, 2, 10]
    assert sum(c == 1 for c in counts["s2-20"]) >= 11, counts
    assert sum(c == 2 for c in counts["s4-24"]) >= 9, counts
    # at the orders the data identify, and where every mode is visible, no mode is marked
    assert not any(counts["s2-18"]) and not any(counts["s1-20"]), counts
    # the order scan counts them per order: none up to the order the data identify (18)
    st = S.structure("siso", 2, n_modes=10)
    r, m = _fit(tmp_path, tmp_path / "s2-20-0.json", "scan", "--method", "ml", "--order", "16:2:22")
    rows = {e["order"]: e["modes_not_identified"] for e in m["order_selection"]["orders"]}
    assert rows[16] == rows[18] == 0 and rows[20] == 1 and rows[22] >= 1, rows
    assert m["order_selection"]["chosen"] == 18 and "not identified" in r.stdout
    assert "order-scan.tmp" not in r.stderr, r.stderr   # no warning names the scan's temporary file
    # unit invariance: outputs in other units give the same tests
    ps = [S.write(tmp_path / f"u{k}.json", S.frf_doc(st, 0, out_scale=sc)) for k, sc in enumerate((1.0, 1e3))]
    t = [[e["contribution_test"]["p_value"] for e in _fit(tmp_path, p, f"u{k}", "--method", "ml", "--order", 20,
                                                           ok=False)[1]["modes"]["modes"]] for k, p in enumerate(ps)]
    np.testing.assert_allclose(t[0], t[1], rtol=1e-4, atol=1e-300)


def test_ml_cost_reaches_vector_fitting_at_the_nominal_order(tmp_path):
    # ml's weighted cost no worse than vector fitting's at the same order. At the nominal
    # (over-sized) order of the SISO structures one pole pair is free and the cost has several
    # basins; the relaxed vector-fitting start (Gustavsen 2006: linear pole spacing, the scaling
    # function's constant free, relocated to convergence, as scikit-rf does) reaches scikit-rf's.
    # Before it (vector fitting with log-spaced poles, 15 relocations, and the subspace starts)
    # ml ended above vector fitting on these three seeds: per-line cost / VF's 1.0132, 1.0123
    # (10 modes, seeds 13, 16), 1.0084 (12 modes, seed 0); with it 0.9975, 0.9971, 0.9985.
    # Over 24 seeds of each structure (docs/benchmarks.md) ml's cost is above vector fitting's in
    # 3 of 48 (before: 9), the largest 1.0117.
    for modes, seed in ((10, 13), (10, 16), (12, 0)):
        st = S.structure("siso", 2, n_modes=modes)
        n = S.order(st)
        p = S.write(tmp_path / f"s{modes}_{seed}.json", S.frf_doc(st, seed))
        om, G, C = S.load_frf(p)
        V_vf = S.weighted_cost(G, S.vector_fit(p, n)[0], C)
        _, m = _fit(tmp_path, p, f"ml{modes}_{seed}", "--method", "ml", "--order", n)
        Gm = np.array([h.cplx(e["G"]) for e in m["frf"]])
        ratio = S.weighted_cost(G, Gm, C) / V_vf
        # the cost ml minimises: on the pooled weights (as test_ml_and_subspace_against_vector_fitting)
        Cp = S.pooled_cov(p)
        ratio_p = S.weighted_cost(G, Gm, Cp) / S.weighted_cost(G, S.vector_fit(p, n)[0], Cp)
        print(f"{modes} modes, seed {seed}, order {n}: ml cost / vector fitting's {ratio:.4f}, on the pooled "
              f"weights {ratio_p:.4f} (best start {m['best_start']})")
        assert ratio_p <= 1.0, (modes, seed, ratio_p)
        # On each line's own covariance (which ml does not minimise): 0.9975, 0.9979, 1.0008 since the
        # subspace starts scan on each line's own covariance, as msid fit --method subspace, and ml is
        # stable by default (2026-11-27): on (12, 0) they reach a basin 1% lower on the pooled cost and
        # 0.08% higher on the per-line one (before: 0.9975, 0.9971, 0.9985)
        assert ratio <= 1.002, (modes, seed, ratio)


@pytest.mark.parametrize("kind,modes,lines,order,extra", [("1x3", 5, 10, 10, ("--no-d",)), ("2x3", 12, 15, 24, ())])
def test_ml_with_fewer_lines_per_response_than_vector_fitting_needs(tmp_path, kind, modes, lines, order, extra):
    # several outputs fit an order that one response's lines cannot: vector fitting's per-response
    # system (2F rows for 2N + nd (+1 relaxed) unknowns) is then underdetermined, and its starts keep
    # their initial poles instead of reading past the QR (found by review: an Eigen assertion under
    # the sanitizer build, an out-of-bounds read without it). ml still writes its model.
    st = S.structure(kind, SEED, n_modes=modes)
    p = S.write(tmp_path / "few.json", S.frf_doc(st, SEED, n_lines=lines))
    r, m = _fit(tmp_path, p, "few", "--method", "ml", "--order", order, *extra, ok=False)
    assert r.returncode in (0, 3), r.stderr
    h.validate(m, "msid-model-1")
    assert m["order"] >= order and m["cost"]["value"] > 0


def _model_with_poles(path, poles, h_s=None):
    """An msid-model/1 file whose A holds the given CT poles (pairs by their Im > 0 member) as real 2x2
    blocks; B, C, D are placeholders (a start reads only the poles) and there is no pole_residue block,
    so msid takes the eigenvalues of A, as for any other tool's state-space model."""
    blocks = []
    for p in poles:
        blocks.append(np.array([[p.real, p.imag], [-p.imag, p.real]]) if p.imag > 0 else np.array([[p.real]]))
    n = sum(b.shape[0] for b in blocks)
    A, i = np.zeros((n, n)), 0
    for b in blocks:
        A[i:i + len(b), i:i + len(b)] = b
        i += len(b)
    doc = {"format": "msid-model/1", "domain": "ct", "order": n, "n_inputs": 1, "n_outputs": 1, "A": A.tolist(),
           "B": np.ones((n, 1)).tolist(), "C": np.ones((1, n)).tolist(), "D": [[0.0]]}
    return S.write(path, doc)


def _true_poles(st):
    w = 2 * np.pi * st["f"]
    return [complex(-z * x, x * np.sqrt(1 - z * z)) for z, x in zip(st["zeta"], w)]


def test_start_from_a_model(data, tmp_path):
    # --start MODEL (ml, pole-residue): refine a given model; its poles are the only start.
    D = data["siso"]
    n = S.order(D["st"])
    Cp = S.pooled_cov(D["path"])                     # the weights ml minimises on, computed in Python
    # (a) another tool's model: scikit-rf's vector fitting at the same order. The refinement starts
    # at its poles and never ends above its cost; here it ends below it.
    _, vf = S.vector_fit(D["path"], n)
    Gvf = _vector_fit(D["path"], n)
    vfm = _model_with_poles(tmp_path / "vf.json", [p for p in vf.poles if p.imag >= 0])
    _, m = _fit(tmp_path, D["path"], "from-vf", "--method", "ml", "--start", vfm)
    h.validate(m, "msid-model-1")
    assert m["order"] == n and m["settings"]["start"] == str(vfm)
    assert [s["start"] for s in m["starts"]] == ["model"] and m["best_start"] == "model"
    Gm = np.array([h.cplx(e["G"]) for e in m["frf"]])
    V_m, V_vf = S.weighted_cost(D["G"], Gm, Cp), S.weighted_cost(D["G"], Gvf, Cp)
    print(f"refined vector fitting: pooled cost {V_m:.3f}, vector fitting's {V_vf:.3f}")
    assert m["converged"] and V_m < V_vf
    # (b) a previous msid fit (its pole_residue block): the refinement stays where it was
    _, m1 = _fit(tmp_path, D["path"], "first", "--method", "ml", "--order", n)
    _, m2 = _fit(tmp_path, D["path"], "again", "--method", "ml", "--start", tmp_path / "first.json")
    assert m2["order"] == n and m2["converged"]
    assert abs(m2["cost"]["value"] - m1["cost"]["value"]) <= 1e-6 * m1["cost"]["value"]
    p1 = np.array([complex(p["re"], p["im"]) for p in m1["pole_residue"]["poles"]])
    p2 = np.array([complex(p["re"], p["im"]) for p in m2["pole_residue"]["poles"]])
    assert len(p1) == len(p2) and np.max(np.abs(np.sort_complex(p1) - np.sort_complex(p2)) / np.abs(p1).min()) < 1e-5
    # (c) why ml's error against the truth is above vector fitting's at an over-sized order
    # (docs/fitting.md, "ml against vector fitting over noise seeds"): the 10-mode SISO structure's
    # data identify 9 modes. Started at the true poles, ml stays in a basin near the truth, with a
    # higher cost than the default starts reach but a lower error: the lower-cost estimate spends the
    # free pole pair on the noise. No cost minimiser without the truth prefers the higher cost.
    st = S.structure("siso", SEED, n_modes=10)
    p = S.write(tmp_path / "s10.json", S.frf_doc(st, 0))
    om, G, _ = S.load_frf(p)
    G0 = S.frf(st, 1j * om)
    Cp10 = S.pooled_cov(p)
    truth = _model_with_poles(tmp_path / "truth.json", _true_poles(st))
    res = {}
    for name, extra in (("default", ("--order", 20)), ("truth", ("--start", truth))):
        _, mm = _fit(tmp_path, p, f"s10-{name}", "--method", "ml", *extra)
        Gm = np.array([h.cplx(e["G"]) for e in mm["frf"]])
        res[name] = (S.rel_error(Gm, G0), S.weighted_cost(G, Gm, Cp10))
    print("10-mode SISO, order 20, seed 0: (error, pooled cost) default", res["default"], "from the truth", res["truth"])
    assert res["truth"][0] < 0.95 * res["default"][0]    # measured 1.0241 / 1.1123 of vector fitting's
    assert res["truth"][1] > res["default"][1]
    # (d) refusals naming the cause
    for args, msg in ((("--order", 22, "--start", truth), "--order 22 and the start model"),
                      (("--order", "auto", "--start", truth), "starts one order"),
                      (("--param", "poles", "--order", 20, "--start", "subspace"), "chooses the start of --param lmfd"),
                      (("--order", 20, "--start", tmp_path / "missing.json"), "missing.json")):
        r, out = _fit(tmp_path, p, "refused", "--method", "ml", *args, ok=False)
        assert r.returncode != 0 and msg in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert out is None
    r, _ = _fit(tmp_path, p, "refused", "--method", "subspace", "--order", 20, "--start", truth, ok=False)
    assert r.returncode == 2 and "--start belongs to --method ml" in r.stderr, r.stderr
    dt = h.load_json(truth)
    dt.update(domain="dt", sample_time=1 / 64)
    S.write(tmp_path / "dt.json", dt)
    r, _ = _fit(tmp_path, p, "refused", "--method", "ml", "--start", tmp_path / "dt.json", ok=False)
    assert r.returncode != 0 and "is discrete-time and the fit continuous-time" in r.stderr, r.stderr


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """4-mode SISO and 2x2 accelerance structures on 120 lines: quick fits for the start-model checks."""
    d = tmp_path_factory.mktemp("small")
    return {kind: S.write(d / f"{kind}.json", S.frf_doc(S.structure(kind, SEED, n_modes=4), SEED, n_lines=120))
            for kind in ("siso", "2x2")}


def test_start_from_a_realisation_takes_each_pole_once(small, tmp_path):
    # A model with several inputs realised as msid writes it (pole-residue and multi models repeat each
    # pole once per input in A) and read without its pole_residue block (another tool's A, B, C, D):
    # each pole once, not a start of twice the order with coincident poles
    _, m1 = _fit(tmp_path, small["2x2"], "first", "--method", "ml", "--order", 8)
    assert m1["order"] == 16 and len(m1["pole_residue"]["poles"]) == 4
    abcd = dict(m1)
    del abcd["pole_residue"]
    p = S.write(tmp_path / "abcd.json", abcd)
    _, m2 = _fit(tmp_path, small["2x2"], "again", "--method", "ml", "--start", p)
    assert m2["order"] == 16 and len(m2["pole_residue"]["poles"]) == 4 and m2["converged"]
    assert abs(m2["cost"]["value"] - m1["cost"]["value"]) <= 1e-6 * m1["cost"]["value"]
    _fit(tmp_path, small["2x2"], "again8", "--method", "ml", "--order", 8, "--start", p)
    # a pole listed twice (hand-written) is one pole: SISO, three distinct pairs
    true = _true_poles(S.structure("siso", SEED, n_modes=4))
    twice = _model_with_poles(tmp_path / "twice.json", [true[0], true[0], true[2], true[3]])
    _, m3 = _fit(tmp_path, small["siso"], "twice", "--method", "ml", "--start", twice)
    assert m3["order"] == 6 and m3["converged"]
    r, out = _fit(tmp_path, small["siso"], "twice8", "--method", "ml", "--order", 8, "--start", twice, ok=False)
    assert r.returncode == 2 and "has 6 distinct poles" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert out is None


def test_start_file_refusals_name_the_entry(small, tmp_path):
    # a directory given as the model (was "'DIR' is empty"); a pole_residue list holding both members
    # of a pair (another tool's habit) names the entry and what to write (was "not finite or has Im < 0")
    true = _true_poles(S.structure("siso", SEED, n_modes=4))
    doc = h.load_json(_model_with_poles(tmp_path / "m.json", true))
    doc["pole_residue"] = {"poles": [{"re": q.real, "im": s * q.imag} for q in true for s in (1, -1)]}
    both = S.write(tmp_path / "both.json", doc)
    for start, msg in ((tmp_path, f"'{tmp_path}' is a directory, not a file"),
                       (both, "pole_residue.poles[1] has Im < 0: list each complex pair once")):
        r, out = _fit(tmp_path, small["siso"], "refused", "--method", "ml", "--start", start, ok=False)
        assert r.returncode == 1 and msg in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert out is None


def test_start_of_order_0_and_scan_usage_errors(small, tmp_path):
    # an order-0 model (A 0 x 0) as the start crashed (Eigen's eigen-solver on an empty matrix, SIGSEGV)
    doc = h.load_json(_model_with_poles(tmp_path / "m.json", _true_poles(S.structure("siso", SEED, n_modes=4))))
    doc.update(order=0, A=[], B=[], C=[[]])
    r, out = _fit(tmp_path, small["siso"], "o0", "--method", "ml", "--start", S.write(tmp_path / "zero.json", doc), ok=False)
    assert r.returncode == 1 and "has no poles (order 0)" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert out is None
    # an order scan whose fit refuses its options (the same at every order): one message, exit 2, no
    # file (was one "failed:" row per order, 40 here, then exit 1)
    for args, msg in ((("--param", "poles", "--start", "sk"), "--start sk chooses the start of --param lmfd"),
                      (("--pin", "N0=0"), "--nd/--nn/--pin belong to the LMFD parametrisation")):
        r, out = _fit(tmp_path, small["siso"], "scan", "--method", "ml", "--order", "auto", *args, ok=False)
        assert r.returncode == 2 and msg in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert "failed:" not in r.stdout and out is None and not (tmp_path / "scan.json.order-scan.tmp").exists()


def test_model_start_with_the_lmfd_parametrisation_names_param_poles(small, tmp_path):
    # --param lmfd (explicit, or ml's default for DT with several inputs) with a model file: the cause
    # named (was "give --order or --nd/--nn" without --order)
    m = _model_with_poles(tmp_path / "m.json", _true_poles(S.structure("siso", SEED, n_modes=4)))
    for extra in ((), ("--order", 8)):
        r, out = _fit(tmp_path, small["siso"], "lmfd", "--method", "ml", "--param", "lmfd", "--start", m, *extra, ok=False)
        assert r.returncode == 2 and "add --param poles" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert out is None


@pytest.mark.parametrize("param", ["poles", "lmfd"])
def test_weight_none_feedthrough_auto_keeps_d(small, tmp_path, param):
    # docs/fitting.md: with --weight none the likelihood-ratio test has no noise scale and auto keeps D.
    # ml ran the test on the unweighted cost (units of G squared) and dropped the accelerance's D
    # (p = 0.27), a cost 260 times the fit with D
    _, m = _fit(tmp_path, small["siso"], "none", "--method", "ml", "--param", param, "--order", 8, "--weight", "none")
    _, y = _fit(tmp_path, small["siso"], "yes", "--method", "ml", "--param", param, "--order", 8, "--weight", "none",
                "--feedthrough", "yes")
    assert m["feedthrough"] == {"mode": "auto", "included": True, "lr_p_value": None}
    assert abs(m["cost"]["value"] - y["cost"]["value"]) <= 1e-9 * y["cost"]["value"]
