"""`msid validate` on LPM files: neighbouring LPM lines share 2W of their 2W+1
window bins, so validate's statistic sums every (2W+1)-th line (independent). Monte Carlo with
fixed seeds: the true model is rejected at 5% in about 5% of the records (every line, today's
`--lpm-lines all`, is the negative control: far off), and a model with a 1% frequency error is
rejected. Also the noisy-input LPM (`--reference`) file end to end: schema, references recorded,
its true model accepted."""
import json

import numpy as np
import helpers as h

R0, ANG = 0.95, 0.3
B = [0.1, 0.05]


def _ss(ang):
    """Observable canonical form of (B0 + B1 z^-1) / (1 + a1 z^-1 + a2 z^-2): y(t) = x1 + B0 u(t)."""
    a1, a2 = -2 * R0 * np.cos(ang), R0 ** 2
    return {"format": "msid-model/1", "domain": "dt", "method": "subspace", "order": 2, "n_inputs": 1,
            "n_outputs": 1, "A": [[-a1, 1.0], [-a2, 0.0]], "B": [[B[1] - a1 * B[0]], [-a2 * B[0]]],
            "C": [[1.0, 0.0]], "D": [[B[0]]], "n_params": 0}


def _sim(rng, N, sigma=0.2, ar=0.0):
    a1, a2 = -2 * R0 * np.cos(ANG), R0 ** 2
    u = rng.standard_normal(N)
    y = np.zeros(N)
    x0, x1 = 3.0 * rng.standard_normal(2)        # random initial state: a transient
    e = sigma * rng.standard_normal(N)
    v = 0.0
    for t in range(N):
        v = ar * v + e[t]
        y[t] = x0 + B[0] * u[t] + v
        x0, x1 = -a1 * x0 + x1 + (B[1] - a1 * B[0]) * u[t], -a2 * x0 - a2 * B[0] * u[t]
    return u, y


def _rates(tmp_path, runs, seed, ar=0.0):
    (tmp_path / "true.json").write_text(json.dumps(_ss(ANG)))
    (tmp_path / "wrong.json").write_text(json.dumps(_ss(ANG * 1.01)))   # 1% frequency error
    rng = np.random.default_rng(seed)
    rej = {"independent": 0, "all": 0, "wrong": 0}
    n_wrong, n_all = min(runs, 40), min(runs, 100)
    for r in range(runs):
        u, y = _sim(rng, 2048, sigma=0.05 if not ar else 0.02, ar=ar)
        p, f = tmp_path / "e.csv", tmp_path / "f.json"
        h.write_csv(p, h.experiment_columns(u[:, None], y[:, None]))
        h.run_ok("frf", "--method", "lpm", "--experiment", p, "-o", f)
        for key, model, extra in (("independent", "true.json", []), ("all", "true.json", ["--lpm-lines", "all"]),
                                  ("wrong", "wrong.json", [])):
            if (key == "wrong" and r >= n_wrong) or (key == "all" and r >= n_all):
                continue
            o = tmp_path / "v.json"
            h.run_ok("validate", tmp_path / model, f, *extra, "-o", o)
            doc = h.load_json(o)
            rej[key] += not doc["consistent_at_5pct"]
            if key == "independent":
                assert doc["line_stride"] == 11 and "every 11-th line" in doc["lines_in_statistic"]
    return {k: v / {"wrong": n_wrong, "all": n_all}.get(k, runs) for k, v in rej.items()}


def test_validate_lpm_rejection_rate_white(tmp_path):
    rates = _rates(tmp_path, 200, 10)
    print("white:", rates)
    assert 0.02 <= rates["independent"] <= 0.085      # 5% at 200 runs: MC std 1.5%
    assert rates["all"] >= 0.10                       # negative control: every line, far off
    assert rates["wrong"] >= 0.95                     # a 1% frequency error is rejected


def test_validate_lpm_rejection_rate_coloured(tmp_path):
    rates = _rates(tmp_path, 120, 11, ar=0.8)
    print("AR(1) 0.8:", rates)
    assert 0.01 <= rates["independent"] <= 0.10      # 120 runs: MC std 2%
    assert rates["wrong"] >= 0.95


def test_reference_lpm_file_and_validate(tmp_path):
    rng = np.random.default_rng(5)
    N = 4096
    r = rng.standard_normal(N)
    u0 = r
    a1, a2 = -2 * R0 * np.cos(ANG), R0 ** 2
    x = np.zeros(2)
    y = np.zeros(N)
    for t in range(N):                                 # y = G u0, u measured with noise at 0 dB
        y[t] = x[0] + B[0] * u0[t]
        x = np.array([-a1 * x[0] + x[1] + (B[1] - a1 * B[0]) * u0[t], -a2 * x[0] - a2 * B[0] * u0[t]])
    y += 0.2 * rng.standard_normal(N)
    u = u0 + rng.standard_normal(N)
    p = tmp_path / "e.csv"
    h.write_csv(p, {"Cmd": r, "u1": u, "y1": y}, order=["Cmd", "u1", "y1"])
    f, fp = tmp_path / "f.json", tmp_path / "plain.json"
    h.run_ok("frf", "--method", "lpm", "--reference", "r1=Cmd", "--columns", "u1=u1,y1=y1", "--experiment", p, "-o", f)
    doc = h.load_json(f)
    h.validate(doc, "msid-frf-1")
    assert doc["method"] == "lpm" and doc["lpm"]["reference_signals"] == ["r1=Cmd"]
    assert doc["lpm"]["inputs"] == "noisy (reference)" and doc["lpm"]["window"] == 6
    assert len(doc["lines"][0]["noise_z"]["re"]) == 2
    (tmp_path / "true.json").write_text(json.dumps(_ss(ANG)))
    h.run_ok("validate", tmp_path / "true.json", f, "-o", tmp_path / "v.json")
    assert h.load_json(tmp_path / "v.json")["consistent_at_5pct"]
    # negative control: the plain LPM of y on the noisy u (gain halved) is rejected
    h.run_ok("frf", "--method", "lpm", "--columns", "u1=u1,y1=y1", "--experiment", p, "-o", fp)
    h.run_ok("validate", tmp_path / "true.json", fp, "-o", tmp_path / "vp.json")
    assert not h.load_json(tmp_path / "vp.json")["consistent_at_5pct"]
    # the same record as .npz (named members) and .npy (numbered columns): the same file
    np.savez(tmp_path / "e.npz", Cmd=r, u1=u, y1=y)
    np.save(tmp_path / "e.npy", np.c_[u, y, r])
    for src, args in ((tmp_path / "e.npz", ["--reference", "r1=Cmd", "--columns", "u1=u1,y1=y1"]),
                      (tmp_path / "e.npy", ["--reference", "r1=3", "--columns", "u1=1,y1=2"])):
        o = tmp_path / "o.json"
        h.run_ok("frf", "--method", "lpm", *args, "--experiment", src, "-o", o)
        assert h.load_json(o)["lines"][50]["G"] == doc["lines"][50]["G"]
    # bad input: one message, no file
    bad = h.run("frf", "--method", "lpm", "--reference", "r1=Nope", "--columns", "u1=u1,y1=y1", "--experiment", p,
                "-o", tmp_path / "bad.json")
    assert bad.returncode == 1 and "no column 'Nope' (for r1)" in bad.stderr and not (tmp_path / "bad.json").exists()


def test_reference_lpm_2x2_record_columns(tmp_path):
    """2x2, references mixed into the inputs, inputs measured at 0 dB, the record's own r1, r2 columns."""
    rng = np.random.default_rng(8)
    N = 8192
    plant = h.dt_plant_2x2()
    r = rng.standard_normal((N, 2))
    u0 = r @ np.array([[1.0, 0.5], [0.3, 1.0]]).T
    y = h.dt_simulate(plant, u0) + 0.05 * rng.standard_normal((N, 2))
    u = u0 + np.std(u0, axis=0) * rng.standard_normal((N, 2))
    p = tmp_path / "e.csv"
    cols = {"r1": r[:, 0], "r2": r[:, 1], **h.experiment_columns(u, y)}
    h.write_csv(p, cols)
    f, fp = tmp_path / "f.json", tmp_path / "plain.json"
    h.run_ok("frf", "--method", "lpm", "--reference", "r1,r2", "--experiment", p, "-o", f)
    h.run_ok("frf", "--method", "lpm", "--experiment", p, "-o", fp)   # r<k> columns skipped without --reference
    doc = h.load_json(f)
    h.validate(doc, "msid-frf-1")
    assert doc["lpm"]["reference_signals"] == ["r1=r1", "r2=r2"] and doc["lpm"]["window"] == 8
    W = doc["lpm"]["window"]
    lines = doc["lines"][::2 * W + 1]
    G0 = h.dt_frf(plant, [l["bin"] for l in lines], N)
    z, zp = [], []
    plain = h.load_json(fp)["lines"][::2 * W + 1]
    for l, lp, g0 in zip(lines, plain, G0):
        for which, out in ((l, z), (lp, zp)):
            G, C, q = h.cplx(which["G"]), h.cplx(which["cov"]), which["dof"]
            e = (G - g0).flatten(order="F")                 # vec stacks columns
            out.extend(abs(e) ** 2 / np.real(np.diag(C)) <= q * (0.05 ** (-1 / q) - 1))
    cover, cover_plain = np.mean(z), np.mean(zp)
    print("2x2 0 dB reference cover", cover, "plain", cover_plain)
    assert 0.9 <= cover <= 0.99              # one record: ~970 element tests, MC std 0.7%
    assert cover_plain < 0.8                 # negative control: the plain LPM is biased


def test_fit_reports_independent_line_cost(tmp_path):
    """msid fit on an LPM file: cost.independent_lines is validate's statistic for the fitted model."""
    u, y = _sim(np.random.default_rng(3), 2048, sigma=0.05)
    p, f, m, v = tmp_path / "e.csv", tmp_path / "f.json", tmp_path / "m.json", tmp_path / "v.json"
    h.write_csv(p, h.experiment_columns(u[:, None], y[:, None]))
    h.run_ok("frf", "--method", "lpm", "--experiment", p, "-o", f)
    r = h.run_ok("fit", "--method", "ml", "--order", 2, f, "-o", m)
    assert "every 11-th line" in r.stdout
    h.run_ok("validate", m, f, "-o", v)
    ic, vd = h.load_json(m)["cost"]["independent_lines"], h.load_json(v)
    h.validate(h.load_json(m), "msid-model-1")
    assert ic["line_stride"] == vd["line_stride"] == 11
    for a, b in (("value", "cost"), ("expected", "expected"), ("dof", "dof"), ("p_value", "p_value")):
        assert abs(ic[a] - vd[b]) <= 1e-9 * max(1.0, abs(vd[b]))


def test_order_selection_uses_independent_lines(tmp_path):
    """msid fit --order auto on an LPM file: the p-value rule on validate's statistic (every (2W+1)-th
    line, validation_stat.hpp), not on every line. Record seed 11: the true order 2 has p = 0.0019 over
    all 1023 correlated lines (the old rule went on to order 8) and p = 0.21 over the 93 independent ones."""
    u, y = _sim(np.random.default_rng(11), 2048, sigma=0.05)
    p, f, m, v = tmp_path / "e.csv", tmp_path / "f.json", tmp_path / "m.json", tmp_path / "v.json"
    h.write_csv(p, h.experiment_columns(u[:, None], y[:, None]))
    h.run_ok("frf", "--method", "lpm", "--experiment", p, "-o", f)
    r = h.run_ok("fit", "--method", "ml", "--order", "auto", f, "-o", m)
    assert "every 11-th line" in r.stdout
    h.validate(h.load_json(m), "msid-model-1")
    sel = h.load_json(m)["order_selection"]
    assert sel["chosen"] == 2 and sel["rule"] == "p-value", sel["chosen"]
    assert sel["line_stride"] == 11 and "every 11-th line" in sel["lines_in_statistic"]
    row = next(x for x in sel["orders"] if x["order"] == 2)
    h.run_ok("validate", m, f, "-o", v)
    vd = h.load_json(v)
    assert vd["line_stride"] == 11 and vd["consistent_at_5pct"]
    for a in ("cost", "expected", "dof", "p_value"):   # the table's row is validate's statistic
        assert abs(row[a] - vd[a]) <= 1e-9 * max(1.0, abs(vd[a])), (a, row[a], vd[a])
    # negative control: over every line the same fits reject orders 2, 3 and 4 at 5% (the all-lines
    # rule picks a wrong order), while every order's independent-line p-value is validate's
    for n in (2, 3, 4):
        h.run_ok("fit", "--method", "ml", "--order", n, f, "-o", tmp_path / f"m{n}.json")
        c = h.load_json(tmp_path / f"m{n}.json")["cost"]
        assert c["p_value"] < 0.05, (n, c["p_value"])
        assert abs(c["independent_lines"]["p_value"] - next(x for x in sel["orders"] if x["order"] == n)["p_value"]) < 1e-9
