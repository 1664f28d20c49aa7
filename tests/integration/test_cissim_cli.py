"""msid fit --method cissim end to end (issue 14): a periodic chirp record through the CLI,
checked against the true system with `msid compare`, the model file against the schema,
and the bad inputs (not periodic, too few periods, lines that do not identify the order):
one message, non-zero exit, no file."""
import json

import numpy as np

from helpers import run, run_ok, validate, load_json

T = 400


def simulate(tmp_path, K=12, periodic=True, seed=1, name="e.csv"):
    rng = np.random.default_rng(seed)
    A = np.array([[0.9 * np.cos(0.4), -0.9 * np.sin(0.4)], [0.9 * np.sin(0.4), 0.9 * np.cos(0.4)]])
    B = np.array([1.0, 0.5])
    C = np.array([0.7, -0.3])
    D = 0.2
    n = np.arange(T)
    u1 = np.sin(0.2 * np.pi * n * n / T)
    u = np.tile(u1, K) if periodic else rng.standard_normal(T * K)
    x = np.zeros(2)
    y = np.zeros(len(u))
    for k in range(len(u)):
        y[k] = C @ x + D * u[k]
        x = A @ x + B * u[k]
    y += 0.01 * np.std(y) * rng.standard_normal(len(y))
    p = tmp_path / name
    np.savetxt(p, np.c_[u, y], delimiter=",", header="u1,y1", comments="")
    truth = {"format": "msid-model/1", "domain": "dt", "method": "subspace", "order": 2, "n_inputs": 1,
             "n_outputs": 1, "A": A.tolist(), "B": [[b] for b in B], "C": [C.tolist()], "D": [[D]]}
    (tmp_path / "true.json").write_text(json.dumps(truth))
    return p


def test_cissim_end_to_end(tmp_path):
    e = simulate(tmp_path)
    for extra in ([], ["--reduced"]):
        out = tmp_path / "m.json"
        run_ok("fit", "--method", "cissim", "--period", T, "--lines", "1:80", "--experiment", e, "--order", 2,
               *extra, "-o", out)
        doc = load_json(out)
        validate(doc, "msid-model-1")
        assert doc["method"] == "cissim" and doc["order"] == 2
        assert doc["settings"]["frequency_set"] == ("reduced" if extra else "full")
        nc = doc["noise_covariance"]
        assert nc["nominal"] is True and "Assumption 7" in nc["note"]   # SISO: C has rank 1 < n
        r = run_ok("compare", out, tmp_path / "true.json")
        h2 = float(r.stdout.split("relative H2 distance ")[1].split(",")[0])
        assert h2 < 0.01, r.stdout
    # the order estimated from the singular values
    run_ok("fit", "--method", "cissim", "--period", T, "--lines", "1:80", "--experiment", e, "-o", tmp_path / "a.json")
    assert load_json(tmp_path / "a.json")["order"] == 2


def bad(tmp_path, *args, want):
    out = tmp_path / "bad.json"
    r = run("fit", "--method", "cissim", *args, "-o", out)
    assert r.returncode != 0
    assert want in r.stderr, r.stderr
    assert r.stderr.count("error") == 1, r.stderr
    assert not out.exists()


def test_cissim_bad_input(tmp_path):
    e = simulate(tmp_path, periodic=False, name="noise.csv")
    bad(tmp_path, "--period", T, "--lines", "1:80", "--experiment", e, "--order", 2, want="not periodic")
    e = simulate(tmp_path, K=2, name="short.csv")
    bad(tmp_path, "--period", T, "--lines", "1:80", "--experiment", e, "--order", 2, want="whole period")
    e = simulate(tmp_path, K=6, name="ok.csv")
    bad(tmp_path, "--period", T, "--lines", "5,6", "--reduced", "--experiment", e, "--order", 4,
        want="do not identify order 4")
    bad(tmp_path, "--period", T, "--lines", "250", "--experiment", e, want="not below P/2")


def test_cissim_noise_covariance_y2(tmp_path):
    """Case Y2 through the CLI (1 input, 2 outputs, strongly detectable): Sigma_vv and Sigma_tt
    within 20% of the truth at N = 60 000, the basis-free ones; Sigma_ww is basis dependent."""
    rng = np.random.default_rng(7)
    T2, K = 600, 101
    A = np.diag([0.8, 0.2])
    Bv = np.array([1.0, 1.0])
    C = np.array([[1.0, 0.0], [1.0, 1.0]])
    sw, sv, st = np.array([2.30e-3, 0.16e-3]), np.array([2.30e-3, 3.64e-3]), 0.11e-3
    u1 = rng.standard_normal(T2)
    N = T2 * K
    u = np.tile(u1, K)
    w = rng.standard_normal((N, 2)) * np.sqrt(sw)
    x = np.zeros(2)
    X = np.zeros((N, 2))
    for k in range(N):
        X[k] = x
        x = A @ x + Bv * u[k] + w[k]
    y = X @ C.T + rng.standard_normal((N, 2)) * np.sqrt(sv)
    um = u + rng.standard_normal(N) * np.sqrt(st)
    p = tmp_path / "y2.npy"
    np.save(p, np.c_[um, y])
    out = tmp_path / "y2.json"
    run_ok("fit", "--method", "cissim", "--period", T2, "--lines", "1:299", "--experiment", p,
           "--columns", "u1=1,y1=2,y2=3", "--order", 2, "-o", out)
    nc = load_json(out)["noise_covariance"]
    assert nc["strongly_detectable"] is True and nc["nominal"] is False
    Svv = np.array(nc["Sigma_vv"])
    Stt = np.array(nc["Sigma_tt"])
    assert np.linalg.norm(Svv - np.diag(sv)) / np.linalg.norm(np.diag(sv)) < 0.2
    assert abs(Stt[0, 0] - st) / st < 0.2
    assert np.all(np.linalg.eigvalsh(np.array(nc["Sigma_ww"])) > -1e-12)
