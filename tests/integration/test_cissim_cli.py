"""msid fit --method cissim end to end: a periodic chirp record through the CLI,
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


# ---- independent peer: a NumPy re-implementation of Algorithms 1/3, 4 and 5 (the authors' MATLAB code is
# not available), written from the paper's equations, not from tools/fit/cissim.cpp's code paths ----

def peer_cissim(z, T, bins, n, skip=1, weighted=True):
    """z: N x 2 record [u, y] (SISO). Returns (A, B, C, D, singular values of R22^T)."""
    Kt = len(z) // T
    Z = z[skip * T:Kt * T]
    K = Kt - skip
    # ISP (25) by the simplified least squares of Alg. 1: R = 2/(K T) F^T Z, built explicitly
    k = np.arange(K * T)
    bins = np.asarray(bins)
    th = 2 * np.pi * np.outer(k, bins) / T
    # phasors P_r = b_r - j a_r with a_r = sin coefficient, b_r = cos coefficient (eq. 7)
    a = 2.0 / (K * T) * np.sin(th).T @ Z            # q x 2
    b = 2.0 / (K * T) * np.cos(th).T @ Z
    P = (b - 1j * a).T                               # 2 x q: rows u, y
    nbar = max(2 * n, n + 1)
    def cols(x, j):
        out = []
        for l, bn in enumerate(bins):
            v = x[l] * np.exp(2j * np.pi * bn * j / T)
            out += [v.real / np.sqrt(2)] if bn == 0 else [v.real, v.imag]
        return out
    # Alg. 4 steps 1-3: [U S^0 .. U S^(nbar-1); Y S^0 ..] and the QR of its transpose
    H = np.array([cols(P[0], j) for j in range(nbar)] + [cols(P[1], j) for j in range(nbar)])
    R = np.linalg.qr(H.T, mode="r")
    R22t = R[nbar:, nbar:].T
    L = None
    if weighted:
        # per-sample output noise variance from the period-to-period spread; covariance of the
        # block-row phasors sum_r c_r cos((j - i) theta_r) sigma^2 (whitening of R22)
        y = Z[:, 1].reshape(K, T)
        s2 = ((y - y.mean(axis=0)) ** 2).sum() / ((K - 1) * T)
        Cn = np.zeros((nbar, nbar))
        J = np.arange(nbar)
        for bn in bins:
            c = (0.5 if bn == 0 else 1.0) * 4.0 / (K * T)
            Cn += c * np.cos(np.subtract.outer(J, J) * 2 * np.pi * bn / T) * s2
        L = np.linalg.cholesky(Cn)
        R22t = np.linalg.solve(L, R22t)
    Us, sv, _ = np.linalg.svd(R22t)
    O = Us[:, :n] * np.sqrt(sv[:n])
    if L is not None:
        O = L @ O
    C = O[:1]
    A = np.linalg.lstsq(O[:-1], O[1:], rcond=None)[0]
    # Alg. 5: y = (C (zI - A)^-1 B + D) u, real least squares in vec(B), D
    rows, rhs = [], []
    for l, bn in enumerate(bins):
        zz = np.exp(2j * np.pi * bn / T)
        Kz = C @ np.linalg.inv(zz * np.eye(n) - A)
        phi = np.r_[Kz[0] * P[0, l], P[0, l]]
        w = 1 / np.sqrt(2) if bn == 0 else 1.0
        rows.append(w * phi.real); rhs.append(w * P[1, l].real)
        if bn != 0:
            rows.append(phi.imag); rhs.append(P[1, l].imag)
    th_bd = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)[0]
    return A, th_bd[:n].reshape(n, 1), C, th_bd[n:].reshape(1, 1), sv


def frf(A, B, C, D, T, bins):
    n = A.shape[0]
    return np.array([(C @ np.linalg.solve(np.exp(2j * np.pi * b / T) * np.eye(n) - A, B) + D)[0, 0] for b in bins])


def test_cissim_numpy_peer(tmp_path):
    """msid's plain cissim (--refine none) equals the NumPy peer to 1e-9 on the FRF of the model and on the
    singular values of Alg. 4, for the full and the reduced set, weighted and published (unweighted) Alg. 4."""
    e = simulate(tmp_path)
    z = np.loadtxt(e, delimiter=",", skiprows=1)
    worst = 0.0
    for reduced in (False, True):
        bins = list(range(1, 81)) if reduced else list(range(T // 2))
        for weighted in (True, False):
            out = tmp_path / "p.json"
            args = ["--reduced"] if reduced else []
            args += [] if weighted else ["--unweighted"]
            run_ok("fit", "--method", "cissim", "--period", T, "--lines", "1:80", "--experiment", e, "--order", 2,
                   "--refine", "none", "--no-covariance", *args, "-o", out)
            doc = load_json(out)
            m = [np.array(doc[k], dtype=float) for k in "ABCD"]
            A, B, C, D, sv = peer_cissim(z, T, bins, 2, weighted=weighted)
            g_msid, g_peer = frf(*m, T, bins), frf(A, B, C, D, T, bins)
            d_frf = np.max(np.abs(g_msid - g_peer)) / np.max(np.abs(g_peer))
            d_sv = np.max(np.abs(np.array(doc["cissim"]["singular_values"]) - sv)) / sv[0]
            print(f"reduced={reduced} weighted={weighted}: FRF {d_frf:.2e}, singular values {d_sv:.2e}")
            assert d_frf < 1e-9 and d_sv < 1e-9
            worst = max(worst, d_frf)
            # negative control: the other weighting is a different estimate (the comparison can fail)
            A2, B2, C2, D2, _ = peer_cissim(z, T, bins, 2, weighted=not weighted)
            assert np.max(np.abs(g_msid - frf(A2, B2, C2, D2, T, bins))) / np.max(np.abs(g_peer)) > 1e-8
    print(f"worst FRF difference msid vs NumPy peer: {worst:.2e}")


def test_cissim_refined_with_covariance(tmp_path):
    """Default --refine ml: the model file carries the FRF covariance at the lines and the ML cost."""
    e = simulate(tmp_path)
    out = tmp_path / "m.json"
    run_ok("fit", "--method", "cissim", "--period", T, "--lines", "1:80", "--reduced", "--experiment", e,
           "--order", 2, "-o", out)
    doc = load_json(out)
    validate(doc, "msid-model-1")
    assert doc["settings"]["refine"] == "ml"
    ref = doc["cissim"]["refinement"]
    assert ref["cost"] <= ref["cost_start"]
    for ln in doc["frf"]:
        c = np.array(ln["cov"]["re"], dtype=float)
        assert c.shape == (1, 1) and c[0, 0] > 0
    r = run_ok("compare", out, tmp_path / "true.json")
    assert float(r.stdout.split("relative H2 distance ")[1].split(",")[0]) < 0.01


def test_cissim_refined_few_periods_no_covariance(tmp_path):
    """3 periods after the skipped one: the per-line weights have 2 dof, too few for the sample-ML factor;
    the refined model is written, its FRF covariance is null and a note says why (no infinite numbers)."""
    e = simulate(tmp_path, K=4)
    out = tmp_path / "m.json"
    r = run_ok("fit", "--method", "cissim", "--period", T, "--lines", "1:80", "--reduced", "--experiment", e,
               "--order", 2, "-o", out)
    assert "too few for an uncertainty" in r.stderr
    doc = load_json(out)
    validate(doc, "msid-model-1")
    assert all(ln["cov"] is None for ln in doc["frf"])
    assert doc["cissim"]["refinement"]["cov_factor"] is None
