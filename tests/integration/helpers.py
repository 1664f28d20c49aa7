"""Shared helpers of the integration tests: run the CLI, schemas, plants, CSVs."""
import json
import math
import os
import subprocess
from pathlib import Path

import sys

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
sys.path.insert(0, str(ROOT / "tests" / "fuzz"))
from hostile_files import mat73_header, matlab_class  # noqa: E402,F401  (MATLAB v7.3 files, with h5py)
SCHEMAS = ROOT / "docs" / "schemas"


def msid_bin():
    b = os.environ.get("MSID_BIN")
    if not b:
        raise RuntimeError("set MSID_BIN to the msid executable (ctest does this)")
    if not os.access(b, os.X_OK):
        raise RuntimeError(f"MSID_BIN={b} is not an executable")
    return b


def run(*args, cwd=None, timeout=600):
    """Run `msid args...`; returns CompletedProcess with text stdout/stderr."""
    cmd = [msid_bin()] + [str(a) for a in args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)


def run_ok(*args, cwd=None):
    r = run(*args, cwd=cwd)
    assert r.returncode == 0, f"msid {' '.join(map(str, args))} failed ({r.returncode}):\n{r.stderr}"
    return r


def load_json(path):
    with open(path, "r", encoding="utf-8") as f:
        return json.load(f)


_validators = {}


def validator(name):
    """Draft 2020-12 validator of docs/schemas/<name>.schema.json."""
    import jsonschema
    if name not in _validators:
        schema = load_json(SCHEMAS / f"{name}.schema.json")
        jsonschema.Draft202012Validator.check_schema(schema)
        _validators[name] = jsonschema.Draft202012Validator(schema)
    return _validators[name]


def validate(doc, name):
    errs = sorted(validator(name).iter_errors(doc), key=lambda e: list(e.path))
    assert not errs, f"{name}: " + "; ".join(f"{list(e.path)}: {e.message}" for e in errs[:5])


def cplx(obj):
    return np.asarray(obj["re"], dtype=float) + 1j * np.asarray(obj["im"], dtype=float)


def assert_rel(a, b, rel, what=""):
    """max|a - b| <= rel * max|b| (elementwise over the whole array)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, f"{what}: shape {a.shape} vs {b.shape}"
    scale = np.max(np.abs(b)) if b.size else 0.0
    err = np.max(np.abs(a - b)) if b.size else 0.0
    assert err <= rel * scale, f"{what}: max error {err:.3e} > {rel:g} * {scale:.3e}"


def fmt_num(v):
    return repr(float(v))


def write_csv(path, columns, order=None):
    """Write a CSV from {name: 1-D array}; `order` is the column order (default: dict order)."""
    names = list(order) if order else list(columns)
    n = len(next(iter(columns.values())))
    cols = [np.asarray(columns[c]) for c in names]
    lines = [",".join(names)]
    for k in range(n):
        lines.append(",".join(fmt_num(c[k]) for c in cols))
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def read_csv(path):
    """{name: array} of a numeric CSV with a header."""
    rows = Path(path).read_text(encoding="utf-8").splitlines()
    names = rows[0].split(",")
    data = np.array([[float(x) for x in r.split(",")] for r in rows[1:] if r], dtype=float)
    return {n: data[:, i] for i, n in enumerate(names)}


def experiment_columns(u, y, time=None):
    """{u1.., y1.., [t]} from arrays u (N x nu) and y (N x ny)."""
    cols = {}
    if time is not None:
        cols["t"] = time
    for i in range(u.shape[1]):
        cols[f"u{i + 1}"] = u[:, i]
    for i in range(y.shape[1]):
        cols[f"y{i + 1}"] = y[:, i]
    return cols


# ---- plants ---------------------------------------------------------------

def dt_plant_2x2():
    """A stable 4-state 2x2 discrete-time plant (two modes, poles |z| = 0.9, 0.8)."""
    r1, t1, r2, t2 = 0.9, 2 * math.pi * 0.03, 0.8, 2 * math.pi * 0.12
    A = np.array([[r1 * math.cos(t1), -r1 * math.sin(t1), 0, 0],
                  [r1 * math.sin(t1), r1 * math.cos(t1), 0, 0],
                  [0, 0, r2 * math.cos(t2), -r2 * math.sin(t2)],
                  [0, 0, r2 * math.sin(t2), r2 * math.cos(t2)]])
    B = np.array([[0.3, 0.05], [0.0, 0.2], [0.1, 0.4], [0.25, 0.0]])
    C = np.array([[1.0, 0.2, 0.5, 0.0], [0.1, 0.7, 0.0, 1.0]])
    D = np.array([[0.1, 0.0], [0.05, 0.2]])
    return A, B, C, D


def dt_frf(plant, bins, period):
    """G(e^{j 2 pi b / P}) for each bin: array L x ny x nu."""
    A, B, C, D = plant
    n = A.shape[0]
    out = []
    for b in bins:
        z = np.exp(2j * math.pi * b / period)
        out.append(C @ np.linalg.solve(z * np.eye(n) - A, B) + D)
    return np.array(out)


def dt_simulate(plant, u, warmup=0, period=None):
    """y(n) = C x(n) + D u(n), x(n+1) = A x(n) + B u(n), x = 0 before the warm-up.
    The warm-up repeats the first `period` samples of u `warmup` times (u periodic),
    so the returned y (same length as u) is the periodic steady state."""
    A, B, C, D = plant
    u = np.asarray(u, dtype=float)
    if warmup:
        u_full = np.vstack([np.tile(u[:period], (warmup, 1)), u])
    else:
        u_full = u
    x = np.zeros(A.shape[0])
    ys = np.empty((u_full.shape[0], C.shape[0]))
    Bu = u_full @ B.T
    for k in range(u_full.shape[0]):
        ys[k] = C @ x
        x = A @ x + Bu[k]
    ys += u_full @ D.T
    return ys[u_full.shape[0] - u.shape[0]:]


def ct_plant_2x2():
    """A stable 3-state 2x2 continuous-time plant: a resonance near 150 rad/s and a pole at -600."""
    A = np.array([[-40.0, 150.0, 0.0], [-150.0, -40.0, 0.0], [0.0, 0.0, -600.0]])
    B = np.array([[60.0, 0.0], [0.0, 80.0], [300.0, 500.0]])
    C = np.array([[1.0, 0.5, 1.0], [0.0, 1.0, -0.5]])
    D = np.array([[0.2, 0.0], [0.1, 0.3]])
    return A, B, C, D


def ct_frf(plant, omegas):
    """G(j omega) for each omega: array L x ny x nu."""
    A, B, C, D = plant
    n = A.shape[0]
    return np.array([C @ np.linalg.solve(1j * w * np.eye(n) - A, B) + D for w in omegas])


def dft_pattern_turns(i, e, m):
    """Phase of the DFT pattern entry T[i][e] = exp(-j 2 pi i e / m), in turns."""
    return -((i * e) % m) / m


# ---- the standard DT bench: msid excite -> simulated 2x2 plant -> CSVs -------

DT_P = 256
DT_LINES = "1:2:41"
DT_SIGMA_Y = 0.05      # output noise std
DT_SIGMA_U = 0.002     # input measurement noise std


def make_dt_bench(d, seed=7, periods=8, warmup=6, nonlinear=0.0):
    """Design with `msid excite`, simulate the 2x2 DT plant in steady state, add
    seeded noise, write d/e1.csv (with a time column) and d/e2.csv (columns
    shuffled). Returns dict(design=path, experiments=[paths], plant=...)."""
    d = Path(d)
    run_ok("excite", "--period", DT_P, "--lines", DT_LINES, "--inputs", 2, "--experiments", 2,
           "--periods", periods, "--seed", 11, "--csv", d / "gen", "-o", d / "design.json")
    plant = dt_plant_2x2()
    rng = np.random.default_rng(seed)
    paths = []
    for e in (1, 2):
        cols = read_csv(d / "gen" / f"e{e}.csv")
        u = np.column_stack([cols["u1"], cols["u2"]])
        assert u.shape == (periods * DT_P, 2)
        y = dt_simulate(plant, u, warmup=warmup, period=DT_P)
        if nonlinear:
            y = y + nonlinear * y ** 3
        y = y + DT_SIGMA_Y * rng.standard_normal(y.shape)
        um = u + DT_SIGMA_U * rng.standard_normal(u.shape)
        p = d / f"e{e}.csv"
        if e == 1:
            write_csv(p, experiment_columns(um, y, time=np.arange(len(u)) * 1e-3))
        else:
            write_csv(p, experiment_columns(um, y), order=["y2", "u1", "y1", "u2"])
        paths.append(p)
    return {"design": d / "design.json", "experiments": paths, "plant": plant}


def frf_args(bench, out, *extra):
    args = ["frf", "--design", bench["design"]]
    for p in bench["experiments"]:
        args += ["--experiment", p]
    return args + list(extra) + ["-o", out]


def compare_with_peer(doc, peer, rel=1e-9):
    """Compare an msid-frf/1 document with the NumPy peer's dict."""
    assert len(doc["lines"]) == len(peer["lines"])
    assert_rel(cplx(doc["noise_cov"]), cplx(peer["noise_cov"]), rel, "noise_cov (top level)")
    assert doc["periods_used"] == peer["periods_used"]
    for a, b in zip(doc["lines"], peer["lines"]):
        w = f"bin {a['bin']}"
        assert a["bin"] == b["bin"], w
        assert a["freq"] == b["freq"], w
        for k in ("omega", "folded", "real"):
            assert a.get(k) == b.get(k), f"{w}: {k}"
        for k in ("G", "cov", "cov_known_input", "noise_cov"):
            assert_rel(cplx(a[k]), cplx(b[k]), rel, f"{w}: {k}")
        for k in ("dof", "dof_known_input", "cond"):
            assert abs(a[k] - b[k]) <= rel * abs(b[k]), f"{w}: {k} {a[k]!r} vs {b[k]!r}"
        assert np.allclose(a["snr"], b["snr"], rtol=0, atol=1e-9), f"{w}: snr"



def write_mat73(path, variables):
    """A MATLAB v7.3 file as `save -v7.3` writes it: HDF5 with a 512-byte user block holding the MATLAB
    header; each variable a dataset whose dimensions are MATLAB's reversed (MATLAB is column-major, so
    an array's transpose in C order), with a MATLAB_class attribute (a fixed-length NULLTERM string, as
    MATLAB writes it). Values in MATLAB's shape: a number or numeric array (complex: an HDF5 compound
    {real, imag}), a str (a 1 x N char row: uint16 codes, MATLAB_int_decode 2; '' as MATLAB writes an
    empty array: its dimensions as uint64 data, MATLAB_empty 1), a list of str (an
    N x 1 cell: object references to char datasets in '#refs#', beside MATLAB's canonical empty 'a')."""
    import pytest
    h5py = pytest.importorskip("h5py")

    def char(group, name, s):
        if not s:   # MATLAB's empty array: its dimensions as data, MATLAB_empty set
            ds = group.create_dataset(name, data=np.array([1, 0], dtype="<u8"))
            ds.attrs.create("MATLAB_empty", 1, dtype="u1")
        else:
            ds = group.create_dataset(name, data=np.array([ord(c) for c in s], dtype="<u2").reshape(len(s), 1))
            ds.attrs.create("MATLAB_int_decode", 2, dtype="<i4")
        matlab_class(ds, "char")
        return ds

    with h5py.File(path, "w", userblock_size=512) as f:
        refs = None
        for name, v in variables.items():
            if isinstance(v, str):
                char(f, name, v)
            elif isinstance(v, (list, tuple)):
                if refs is None:
                    refs = f.create_group("#refs#")
                    e = refs.create_dataset("a", data=np.zeros(2, dtype="<u8"))
                    matlab_class(e, "canonical empty")
                    e.attrs.create("MATLAB_empty", 1, dtype="u1")
                targets = [char(refs, f"{name}_{k}", s).ref for k, s in enumerate(v)]
                ds = f.create_dataset(name, data=np.array([targets], dtype=h5py.ref_dtype))   # N x 1 reversed
                matlab_class(ds, "cell")
            else:
                a = np.asarray(v)
                a = a.reshape(1, -1) if a.ndim < 2 else a   # a vector: a row, as scipy.io.savemat
                t = a.T   # MATLAB's dimensions reversed, its column-major order as C order
                if np.iscomplexobj(a):
                    c = np.empty(t.shape, dtype=[("real", "<f8"), ("imag", "<f8")])
                    c["real"], c["imag"] = t.real, t.imag
                    t = c
                else:
                    t = t.astype("<f8")
                matlab_class(f.create_dataset(name, data=t), "double")
    mat73_header(path)
