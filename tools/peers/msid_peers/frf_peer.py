"""Independent NumPy implementation of the `msid frf` job.

Written from the estimator definitions (lib/include/msid/msid_frf.h and the
msid-frf/1 schema), not from the C code, so that the integration tests can
compare the two. Plain NumPy, one line at a time, for readability.

Job, per experiment e (one CSV each):
  * keep whole periods of P samples, drop the first `skip` periods;
  * per period, X = np.fft.rfft(x) for every column (convention
    X[b] = sum_n x[n] exp(-2j pi b n / P)) and pick the bins;
  * z = [U_1..U_nu, Y_1..Y_ny] per line: mean over the K_e periods and the
    sample covariance C_Z,e = scatter / (K_e - 1),
    scatter = sum_p (z_p - zbar)(z_p - zbar)^H.
Per excited line, with Ubar (nu x m) and Ybar (ny x m) the experiment means:
  * G = Ybar Ubar^H (Ubar Ubar^H)^-1, W = Ubar^H (Ubar Ubar^H)^-1 (m x nu);
  * cov of vec(G) (vec stacks columns: G[i][j] -> i + ny*j,
    Cov[a][b] = E[(v_a - E v_a) conj(v_b - E v_b)]):
        sum_e kron(outer(W[e], conj(W[e])), S_e),  S_e = B C_Z,e B^H / K_e,
    with B = [-G, I] acting on z = [u; y];
  * cov_known_input = sum_e kron(outer(W[e], conj(W[e])), Sp / K_e),
    Sp = sum_e Syy_e / sum_e (K_e - 1), Syy_e the y block of the scatter;
  * dof_known_input = sum_e (K_e - 1);
    dof = (sum c_e)^2 / sum(c_e^2 / (K_e - 1)), c_e = |W[e]|^2 / K_e;
  * noise_cov = Sp, snr_i = 10 log10(sum_e |Ybar_ie|^2 / sum_e Sp_ii / K_e),
    cond = condition number of Ubar;
  * continuous-time lines that fold above Nyquist (bin P - b) carry
    G(-j w) = conj(G(j w)): G, both covariances and noise_cov are conjugated.
Top level noise_cov = mean over lines of the reported noise_cov / P (after the
conjugation of folded lines).
Detection lines: Y_mean (m x ny), noise_var = pooled y variance, p-value of
F = (sum_e K_e |Ybar_e|^2 / m) / noise_var against F(2m, 2 sum(K_e - 1)).

The transient test of `msid frf` is not reproduced: the peer matches
`msid frf --transient flag|off` (which keep every period).

Use:  estimate(experiments, period, bins, ...) -> dict shaped like msid-frf/1
      estimate_files(paths, design=..., ...) reads CSVs and a design file.
CLI:  python3 -m msid_peers.frf_peer (--design D | --period P --lines L) \
          --experiment e1.csv [--experiment e2.csv ...] [-o out.json]
"""
import argparse
import json
import math
import sys

import numpy as np

TIME_COLUMNS = ("t", "time", "n", "sample", "index")


class Experiment:
    """One experiment record: u (N x nu) and y (N x ny) sample arrays."""

    def __init__(self, u, y, source=""):
        self.u = np.asarray(u, dtype=float).reshape(len(u), -1)
        self.y = np.asarray(y, dtype=float).reshape(len(y), -1)
        if self.u.shape[0] != self.y.shape[0]:
            raise ValueError("u and y must have the same number of samples")
        self.source = source

    @property
    def n_samples(self):
        return self.u.shape[0]


def read_experiment(path):
    """Read an experiment CSV: header u1..u<nu>, y1..y<ny>, optional time column."""
    with open(path, "r", encoding="utf-8") as f:
        rows = [r for r in f.read().splitlines() if r.strip()]
    if not rows:
        raise ValueError(f"{path}: empty file")
    names = [c.strip().lower() for c in rows[0].split(",")]
    where = {"u": {}, "y": {}}
    for col, name in enumerate(names):
        if name in TIME_COLUMNS:
            continue
        kind, num = name[:1], name[1:]
        if kind not in where or not num.isdigit() or int(num) < 1:
            raise ValueError(f"{path}: unknown column {name!r}")
        if int(num) in where[kind]:
            raise ValueError(f"{path}: duplicate column {name!r}")
        where[kind][int(num)] = col
    for kind in "uy":
        if not where[kind] or sorted(where[kind]) != list(range(1, len(where[kind]) + 1)):
            raise ValueError(f"{path}: columns {kind}1..{kind}<n> missing or with gaps")
    data = np.array([[float(c) for c in r.split(",")] for r in rows[1:]], dtype=float)
    if data.ndim != 2 or data.shape[1] != len(names):
        raise ValueError(f"{path}: ragged rows")
    if not np.all(np.isfinite(data)):
        raise ValueError(f"{path}: non-finite values")
    u = data[:, [where["u"][k] for k in sorted(where["u"])]]
    y = data[:, [where["y"][k] for k in sorted(where["y"])]]
    return Experiment(u, y, source=str(path))


def ct_bin(omega, period, sample_time):
    """DT bin and fold flag of a continuous-time line omega (rad/s) sampled every h."""
    cycles = omega * period * sample_time / (2 * math.pi)
    r = int(round(cycles))
    b = r % period
    if 2 * b > period:
        return period - b, True
    return b, False


def cjson(a):
    """{re, im} of a complex matrix."""
    a = np.atleast_2d(np.asarray(a, dtype=complex))
    return {"re": a.real.tolist(), "im": a.imag.tolist()}


def as_complex(obj):
    """Complex ndarray from a {re, im} object."""
    return np.asarray(obj["re"], dtype=float) + 1j * np.asarray(obj["im"], dtype=float)


def f_tail_2m_2n(m, n, f):
    """P(F(2m, 2n) > f) for integer m, n >= 1 (negative binomial form of I_x(n, m))."""
    if not f > 0:
        return 1.0
    if math.isinf(f):
        return 0.0
    x = n / (n + m * f)           # P(F > f) = I_x(n, m) = P(Beta(n, m) <= x)
    # I_x(n, m) = sum_{k=0}^{m-1} C(n+k-1, k) x^n (1-x)^k
    total = 0.0
    for k in range(m):
        lt = (math.lgamma(n + k) - math.lgamma(k + 1) - math.lgamma(n) + n * math.log(x)
              + (k * math.log1p(-x) if k else 0.0))
        total += math.exp(lt)
    return min(total, 1.0)


def period_stats(x, period, bins, skip):
    """Mean (nb x q) and scatter (nb x q x q) across whole periods of x (N x q)."""
    K_total = x.shape[0] // period
    K = K_total - skip
    if K < 2:
        raise ValueError(f"{K} usable periods: need at least 2")
    seg = x[skip * period:K_total * period].reshape(K, period, x.shape[1])
    Z = np.fft.rfft(seg, axis=1)[:, np.asarray(bins, dtype=int), :]   # K x nb x q
    mean = Z.mean(axis=0)
    dev = Z - mean
    scatter = np.einsum("kla,klb->lab", dev, dev.conj())             # sum dev dev^H
    return mean, scatter, K


def estimate(experiments, period, bins, skip=0, detect=(), folded=None, omega=None,
             sample_time=None, fs=None):
    """msid-frf/1-shaped dict from a list of Experiment objects."""
    P = int(period)
    bins = [int(b) for b in bins]
    detect = [int(b) for b in detect]
    L = len(bins)
    m = len(experiments)
    nu = experiments[0].u.shape[1]
    ny = experiments[0].y.shape[1]
    g = nu * ny
    if m < nu:
        raise ValueError(f"{nu} inputs need at least {nu} experiments")
    folded = [bool(f) for f in folded] if folded is not None else [False] * L
    allbins = bins + detect

    means, scats, Ks, exps = [], [], [], []
    for ex in experiments:
        z = np.hstack([ex.u, ex.y])
        mu, sc, K = period_stats(z, P, allbins, skip)
        means.append(mu)
        scats.append(sc)
        Ks.append(K)
        exps.append({"source": ex.source, "samples": ex.n_samples,
                     "periods_total": ex.n_samples // P, "periods_skipped": skip,
                     "periods_used": K, "leftover_samples": ex.n_samples % P})
    Ks = np.array(Ks, dtype=float)
    dofk = float(np.sum(Ks - 1))

    lines = []
    noise_time = np.zeros((ny, ny), dtype=complex)
    for l, b in enumerate(bins):
        U = np.array([means[e][l, :nu] for e in range(m)]).T      # nu x m
        Y = np.array([means[e][l, nu:] for e in range(m)]).T      # ny x m
        UH = U.conj().T
        Minv = np.linalg.inv(U @ UH)
        G = Y @ UH @ Minv                                          # ny x nu
        W = UH @ Minv                                              # m x nu
        B = np.hstack([-G, np.eye(ny)])                            # ny x (nu+ny)
        Sp = sum(scats[e][l, nu:, nu:] for e in range(m)) / dofk
        cov = np.zeros((g, g), dtype=complex)
        cov_ki = np.zeros((g, g), dtype=complex)
        c = np.zeros(m)
        for e in range(m):
            CZ = scats[e][l] / (Ks[e] - 1)
            Se = B @ CZ @ B.conj().T / Ks[e]
            ww = np.outer(W[e], W[e].conj())
            cov += np.kron(ww, Se)
            cov_ki += np.kron(ww, Sp / Ks[e])
            c[e] = np.sum(np.abs(W[e]) ** 2) / Ks[e]
        dof = np.sum(c) ** 2 / np.sum(c ** 2 / (Ks - 1))
        sv = np.linalg.svd(U, compute_uv=False)
        cond = sv[0] / sv[-1] if sv[-1] > 0 else math.inf
        snr = []
        for i in range(ny):
            sig = np.sum(np.abs(Y[i]) ** 2)
            noi = np.sum(Sp[i, i].real / Ks)
            snr.append(10 * math.log10(sig / noi) if noi > 0 else None)
        noise = Sp
        if folded[l]:
            G, cov, cov_ki, noise = G.conj(), cov.conj(), cov_ki.conj(), noise.conj()
        noise_time += noise
        line = {"bin": b, "freq": b / P}
        if omega is not None:
            line["omega"] = float(omega[l])
            line["folded"] = folded[l]
            line["freq_hz"] = float(omega[l]) / (2 * math.pi)
        elif fs:
            line["freq_hz"] = b / P * fs
        if b == 0:
            line["real"] = True
        line.update({"G": cjson(G), "cov": cjson(cov), "dof": float(dof),
                     "cov_known_input": cjson(cov_ki), "dof_known_input": dofk,
                     "noise_cov": cjson(noise), "snr": snr, "cond": float(cond)})
        lines.append(line)

    doc = {"format": "msid-frf/1", "period_samples": P, "n_inputs": nu, "n_outputs": ny,
           "n_experiments": m, "domain": "ct" if omega is not None else "dt"}
    if omega is not None:
        doc["sample_time"] = float(sample_time)
    elif fs:
        doc["sample_time"] = 1.0 / fs
        doc["fs_hz"] = fs
    doc["periods_used"] = int(np.sum(Ks))
    doc["noise_cov"] = cjson(noise_time / (L * P))
    doc["experiments"] = exps
    doc["lines"] = lines
    if detect:
        dl = []
        for d, b in enumerate(detect):
            l = L + d
            ymean = np.array([means[e][l, nu:] for e in range(m)])            # m x ny
            var, pv = [], []
            for i in range(ny):
                v = sum(scats[e][l, nu + i, nu + i].real for e in range(m)) / dofk
                num = sum(Ks[e] * abs(ymean[e, i]) ** 2 for e in range(m)) / m
                stat = num / v if v > 0 else (math.inf if num > 0 else 0.0)
                var.append(float(v))
                pv.append(f_tail_2m_2n(m, int(dofk), stat))
            entry = {"bin": b, "freq": b / P}
            if fs:
                entry["freq_hz"] = b / P * fs
            entry.update({"Y_mean": cjson(ymean), "noise_var": var, "p_value": pv})
            dl.append(entry)
        doc["detection_lines"] = dl
    return doc


def design_request(design):
    """period, bins, folded, omega, sample_time from an msid-design/1 dict."""
    P = int(design["period_samples"])
    if design["domain"] == "ct":
        h = float(design["sample_time"])
        omega = [float(l["omega"]) for l in design["lines"]]
        bf = [ct_bin(w, P, h) for w in omega]
        return {"period": P, "bins": [b for b, _ in bf], "folded": [f for _, f in bf],
                "omega": omega, "sample_time": h}
    return {"period": P, "bins": [int(l["bin"]) for l in design["lines"]]}


def estimate_files(paths, design=None, period=None, bins=None, skip=0, detect=(), fs=None):
    """Read experiment CSVs (and a design file or dict) and run ::estimate."""
    kw = {}
    if design is not None:
        if not isinstance(design, dict):
            with open(design, "r", encoding="utf-8") as f:
                design = json.load(f)
        kw = design_request(design)
    else:
        kw = {"period": period, "bins": bins}
    exps = [read_experiment(p) for p in paths]
    return estimate(exps, skip=skip, detect=detect, fs=fs, **kw)


def parse_uint_list(s):
    out = []
    for item in s.split(","):
        parts = [int(p) for p in item.split(":")]
        if len(parts) == 1:
            out.append(parts[0])
        else:
            a, b = parts[0], parts[-1]
            step = parts[1] if len(parts) == 3 else 1
            out.extend(range(a, b + 1, step))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python3 -m msid_peers.frf_peer", description=__doc__.split("\n")[0])
    ap.add_argument("--design")
    ap.add_argument("--period", type=int)
    ap.add_argument("--lines")
    ap.add_argument("--experiment", action="append", required=True)
    ap.add_argument("--skip-periods", type=int, default=0)
    ap.add_argument("--detect-lines")
    ap.add_argument("--fs", type=float)
    ap.add_argument("-o", "--output")
    a = ap.parse_args(argv)
    if a.design is None and (a.period is None or a.lines is None):
        ap.error("give --design, or --period and --lines")
    doc = estimate_files(a.experiment, design=a.design, period=a.period,
                         bins=parse_uint_list(a.lines) if a.lines else None, skip=a.skip_periods,
                         detect=parse_uint_list(a.detect_lines) if a.detect_lines else (), fs=a.fs)
    text = json.dumps(doc, indent=1) + "\n"
    if a.output:
        with open(a.output, "w", encoding="utf-8") as f:
            f.write(text)
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
