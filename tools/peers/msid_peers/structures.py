"""Simulated structures as a bench engineer meets them in a ground-vibration test:
force inputs, acceleration outputs (so a direct feedthrough), two rigid-body
(suspension) modes plus elastic modes with 0.5-2% damping, 60-80 dB of dynamic
range, 250+ lines, and a noise floor of 0.2% of the response level. The FRF
file carries the sample covariance of M periods, as `msid frf` writes it.

Accelerance of mode k (mass-normalised shapes phi_k, input shapes psi_k):
    H(s) = sum_k s^2 phi_k psi_k^T / (s^2 + 2 zeta_k w_k s + w_k^2) + G_rb,
where G_rb is the free-free rigid-body term (a constant for acceleration:
s^2 / (m s^2) = 1/m). Every term tends to phi psi^T as s -> inf: the feedthrough.
Fixed seeds make every file reproducible.
"""
import json
import math

import numpy as np

FS = 64.0          # Hz sample rate of the simulated acquisition
P = 1024           # samples per period: line spacing FS/P = 0.0625 Hz


def modes(seed, n_modes=12):
    """Natural frequencies (Hz), damping ratios: 2 rigid-body (suspension) modes below 2.5 Hz,
    the rest elastic in 3-14 Hz."""
    rng = np.random.default_rng(seed)
    f_rb = np.array([1.4, 2.2])
    f_el = np.sort(rng.uniform(3.0, 14.0, n_modes - 2))
    while np.min(np.diff(f_el)) < 0.35:          # resolvable with the line spacing
        f_el = np.sort(rng.uniform(3.0, 14.0, n_modes - 2))
    f = np.concatenate([f_rb, f_el])
    zeta = np.concatenate([[0.02, 0.015], rng.uniform(0.005, 0.02, n_modes - 2)])
    return f, zeta


def structure(kind, seed=1, n_modes=12, quantity="acc"):
    """kind: 'siso', '1x3', '2x2' or '2x3'; quantity 'acc' (accelerance: direct feedthrough) or 'vel'
    (mobility, strictly proper, no rigid-body term). Returns a dict with f (Hz), zeta, phi (ny x K),
    psi (nu x K), grb (ny x nu)."""
    nu, ny = {"siso": (1, 1), "1x3": (1, 3), "2x2": (2, 2), "2x3": (2, 3)}[kind]
    rng = np.random.default_rng(100 + seed)
    f, zeta = modes(seed, n_modes)
    amp = 10 ** np.random.default_rng(9 + seed).uniform(-0.7, 0.3, n_modes)   # modal participation: the dynamic range
    phi = rng.standard_normal((ny, n_modes)) * amp
    psi = phi[:nu].copy() if nu <= ny else rng.standard_normal((nu, n_modes)) * amp   # driving points (reciprocity)
    grb = 0.3 * rng.standard_normal((ny, nu)) if quantity == "acc" else np.zeros((ny, nu))
    return {"kind": kind, "nu": nu, "ny": ny, "f": f, "zeta": zeta, "phi": phi, "psi": psi, "grb": grb,
            "power": 2 if quantity == "acc" else 1}


def frf(st, s):
    """Accelerance at complex frequencies s (rad/s): array len(s) x ny x nu."""
    s = np.asarray(s)[:, None, None]
    H = np.broadcast_to(st["grb"], (s.shape[0], st["ny"], st["nu"])).astype(complex)
    for k in range(len(st["f"])):
        w = 2 * math.pi * st["f"][k]
        R = np.outer(st["phi"][:, k], st["psi"][:, k])
        H = H + s ** st["power"] * R / (s ** 2 + 2 * st["zeta"][k] * w * s + w ** 2)
    return H


def order(st):
    """The true state order (two states per mode; the rigid-body term is the constant).
    Not always the order the data identify: with seed 2 the SISO 10- and 12-mode structures hold a
    mode whose driving-point residue is 1e-4 (peak 0.1 and 0.2 times the noise sd of the 16-period
    mean), so their data identify order(st) - 2 (docs/fitting.md, "ml against vector fitting over
    noise seeds")."""
    return 2 * len(st["f"])


def bins(n_lines=267, first=16):
    return np.arange(first, first + n_lines)


def dynamic_range_db(G):
    a = np.abs(G).reshape(len(G), -1)
    return float(20 * np.log10(a.max() / a.min()))


def frf_doc(st, seed=1, n_lines=267, periods=16, noise=0.002, out_scale=1.0, in_scale=1.0):
    """msid-frf/1 document: the structure's FRF with M = periods noisy periods averaged, the sample
    covariance of the mean (dof M - 1 per experiment), and the time-domain noise level.
    out_scale/in_scale express the same data in other units (outputs times a, inputs times b:
    G -> a/b G) for the unit-invariance tests."""
    nu, ny = st["nu"], st["ny"]
    g = nu * ny
    b = bins(n_lines)
    w = 2 * math.pi * b * FS / P
    G0 = frf(st, 1j * w)
    sigma = noise * math.sqrt(np.mean(np.abs(G0) ** 2))
    rng = np.random.default_rng(7000 + seed)
    lines = []
    sc = out_scale / in_scale
    for k in range(n_lines):
        # experiment e drives input e: column e of G from M periods, its ny x ny sample covariance /M;
        # vec(G) covariance = sum_e (e_e e_e^T) kron S_e (the structure msid frf writes, dof M - 1 each)
        m = np.zeros(g, complex)
        S = np.zeros((g, g), complex)
        for e in range(nu):
            x = G0[k][:, e][None, :] + sigma / math.sqrt(2) * (
                rng.standard_normal((periods, ny)) + 1j * rng.standard_normal((periods, ny)))
            me = x.mean(axis=0)
            d = x - me
            m[e * ny:(e + 1) * ny] = me
            S[e * ny:(e + 1) * ny, e * ny:(e + 1) * ny] = (d.T @ d.conj()) / ((periods - 1) * periods)
        Gm = m.reshape((ny, nu), order="F") * sc
        S = S * sc ** 2
        lines.append({"bin": int(b[k]), "freq": float(b[k] / P), "omega": float(w[k]),
                      "G": {"re": Gm.real.tolist(), "im": Gm.imag.tolist()},
                      "cov": {"re": S.real.tolist(), "im": S.imag.tolist()},
                      "dof": (periods - 1) * nu, "snr": []})
    return {"format": "msid-frf/1", "period_samples": P, "n_inputs": nu, "n_outputs": ny, "n_experiments": nu,
            "domain": "ct", "sample_time": 1.0 / FS, "periods_used": periods, "periods_rejected": 0,
            "noise_cov": {"re": (np.eye(ny) * (sigma * out_scale) ** 2 / P).tolist(), "im": np.zeros((ny, ny)).tolist()},
            "experiments": [], "lines": lines}


def write(path, doc):
    with open(path, "w") as fh:
        json.dump(doc, fh)
    return path


def load_frf(path):
    """omega (rad/s), G (F x ny x nu), cov (F x g x g) of an msid-frf/1 file."""
    d = json.load(open(path))
    om = np.array([ln["omega"] for ln in d["lines"]])
    G = np.array([np.asarray(ln["G"]["re"]) + 1j * np.asarray(ln["G"]["im"]) for ln in d["lines"]])
    C = np.array([np.asarray(ln["cov"]["re"]) + 1j * np.asarray(ln["cov"]["im"]) for ln in d["lines"]])
    return om, G, C


def weighted_cost(G, Gm, C):
    """Eq. (40): sum_l vec(G - Gm)^H C_l^-1 vec(G - Gm) (complex lines)."""
    V = 0.0
    for l in range(len(G)):
        e = (G[l] - Gm[l]).flatten(order="F")
        V += float(np.real(e.conj() @ np.linalg.solve(C[l], e)))
    return V


def pooled_cov(path, half=4):
    """The weights `msid fit --method ml` uses by default (--weight-smooth 4), computed here
    independently of msid: each complex line's covariance averaged, dof-weighted, with those of its
    2 half + 1 neighbouring complex lines (the window shifted at the band's ends), where
    - the line's own weights are imprecise: its n dof give a sample-ML factor n/(n - ny - 1) above 1.02;
    - the neighbour's covariance equals the line's: one entry (g = 1), the variance ratio inside the
      central 99% of F(2d, 2d), d = min of the two dof; a matrix, the Bartlett-corrected likelihood-ratio
      statistic of two complex Wishart matrices below chi2's 95% quantile with g b dof (b the Wishart
      block: ny for several experiments, else g).
    Real lines (DC, Nyquist) keep their own. Only where msid pools: at least 4 (2 half + 1) lines."""
    from scipy.stats import chi2
    from scipy.stats import f as fdist
    d = json.load(open(path))
    C = np.array([np.asarray(ln["cov"]["re"]) + 1j * np.asarray(ln["cov"]["im"]) for ln in d["lines"]])
    C = 0.5 * (C + np.conj(np.transpose(C, (0, 2, 1))))                  # the Hermitian part, as msid weighs
    dof = np.array([float(ln["dof"]) for ln in d["lines"]])
    ny = d["n_outputs"]
    g = C.shape[1]
    # several inputs from several experiments (periodic, no realisations): msid's weights take the
    # dof of one experiment's Wishart, dof / m (tools/fit/frf_data.cpp, weigh), and its blocks are ny x ny
    multi = (d["n_inputs"] > 1 and d.get("n_experiments", 1) > 1 and d.get("method", "periodic") not in ("lpm", "etfe")
             and d.get("nonlinear_distortion", {}).get("realisations", 1) < 2)
    if multi:
        dof = dof / d["n_experiments"]
    b = ny if multi and ny < g else g
    real = np.array([bool(ln.get("real", False)) for ln in d["lines"]])
    C[real] = C[real].real
    if len(C) < 4 * (2 * half + 1):
        return C
    cx = np.flatnonzero(~real)
    n = len(cx)
    win = min(n, 2 * half + 1)
    out = C.copy()
    ld = np.array([np.linalg.slogdet(C[i])[1] for i in range(len(C))])
    qa = chi2.isf(0.05, g * b)

    def equal(k, j):
        if g == 1:
            q = float(np.real(C[j][0, 0] / C[k][0, 0]))
            dd = 2.0 * min(dof[j], dof[k])
            return not (fdist.sf(q, dd, dd) < 0.005 or fdist.sf(1.0 / q, dd, dd) < 0.005)
        nk, nj = dof[k], dof[j]
        npool = nk + nj
        lp = np.linalg.slogdet((nk * C[k] + nj * C[j]) / npool)[1]
        rho = 1.0 - (2.0 * b * b - 1.0) / (6.0 * b) * (1.0 / nk + 1.0 / nj - 1.0 / npool)
        return rho * 2.0 * (npool * lp - nk * ld[k] - nj * ld[j]) <= qa

    for k in range(n):
        nk = dof[cx[k]]
        if nk > ny + 1 and nk / (nk - ny - 1) - 1.0 <= 0.02:
            continue
        lo = min(max(k - half, 0), n - win)
        S = np.zeros_like(C[0])
        nd = 0.0
        for j in range(lo, lo + win):
            if j != k and not equal(cx[k], cx[j]):
                continue
            S += dof[cx[j]] * C[cx[j]]
            nd += dof[cx[j]]
        out[cx[k]] = S / nd
    return out


def rel_error(Gm, G0):
    return float(np.linalg.norm(Gm - G0) / np.linalg.norm(G0))


def model_frf(doc, omega):
    """FRF of an msid-model/1 document (its A, B, C, D) at omega (rad/s, CT)."""
    A, B, C, D = (np.asarray(doc[k], float).reshape(-1, len(doc[k][0]) if doc[k] and doc[k][0] else 0)
                  if doc[k] else np.zeros((0, 0)) for k in "ABCD")
    nu, ny = doc["n_inputs"], doc["n_outputs"]
    n = doc["order"]
    A = A.reshape(n, n); B = B.reshape(n, nu); C = C.reshape(ny, n); D = np.asarray(doc["D"], float).reshape(ny, nu)
    out = []
    for w in omega:
        out.append(C @ np.linalg.solve(1j * w * np.eye(n) - A, B) + D)
    return np.array(out)


def vector_fit(path, n, fit_constant=True):
    """The peer: scikit-rf's VectorFitting (Gustavsen & Semlyen's relocation) on
    the same FRF at the same order (n poles, pairs counted twice, common to all responses).
    Non-square FRFs are padded with zero responses to a square network (they decouple).
    Returns the model FRF at the file's lines."""
    import skrf
    from skrf.vectorFitting import VectorFitting
    om, G, _ = load_frf(path)
    F, ny, nu = G.shape
    p = max(ny, nu)
    S = np.zeros((F, p, p), complex)
    S[:, :ny, :nu] = G
    freq = skrf.Frequency.from_f(om / (2 * math.pi), unit="hz")
    net = skrf.Network(frequency=freq, s=S)
    vf = VectorFitting(net)
    vf.max_iterations = 200
    vf.vector_fit(n_poles_real=n % 2, n_poles_cmplx=n // 2, init_pole_spacing="lin", fit_constant=fit_constant,
                  enforce_dc=False)
    Gm = np.zeros_like(G)
    f_hz = om / (2 * math.pi)
    for i in range(ny):
        for j in range(nu):
            Gm[:, i, j] = vf.get_model_response(i, j, f_hz)
    return Gm, vf
