"""Regressions of the hardening review through the command line: every field read from a file or an option is
range-checked before it sizes memory or work, and a result is never written with NaN/Inf (JSON null).
Each case: one clear message, non-zero exit, no output file and no temporary left behind."""
import json
import resource
import subprocess

import numpy as np
import pytest

import helpers as h


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp("hardbench")
    b = h.make_dt_bench(d, periods=6)
    h.run_ok(*h.frf_args(b, d / "frf.json"))
    h.run_ok("fit", "--method", "subspace", "--order", 4, d / "frf.json", "-o", d / "model.json")
    return {"dir": d, "bench": b, "frf": d / "frf.json", "model": d / "model.json"}


def fails(tmp, r, *needles, out=None):
    assert r.returncode != 0, r.stdout
    lines = [l for l in r.stderr.splitlines() if l.strip()]
    assert len(lines) == 1, r.stderr
    for n in needles:
        assert n in r.stderr, r.stderr
    if out is not None:
        assert not out.exists()
    assert not list(tmp.glob("*.tmp.*")), list(tmp.glob("*"))


def scaled_csvs(bench, tmp, su, sy):
    paths = []
    for p in bench["experiments"]:
        cols = h.read_csv(p)
        c = {k: np.asarray(v) * (su if k.startswith("u") else sy if k.startswith("y") else 1.0) for k, v in cols.items()}
        q = tmp / p.name
        h.write_csv(q, c)
        paths.append(q)
    return paths


def frf(bench, exps, out, *extra):
    args = ["frf", "--design", bench["design"]]
    for p in exps:
        args += ["--experiment", p]
    return h.run(*args, *extra, "-o", out)


@pytest.mark.parametrize("nN", [4294967295, 2147483647])
def test_validate_crafted_lmfd_order(bench, tmp_path, nN):
    """Hardening finding 3 (docs/reliability.md): lmfd.nN cast to int without a range check crashed `msid validate` (SIGSEGV; UBSan overflow)."""
    m = json.loads(bench["model"].read_text())
    m["lmfd"] = {"nD": 1, "nN": nN, "D": [[[1, 0], [0, 1]]], "N": []}
    p = tmp_path / "crafted.json"
    p.write_text(json.dumps(m))
    r = h.run("validate", p, bench["frf"], "-o", tmp_path / "v.json")
    fails(tmp_path, r, "lmfd.nD and lmfd.nN must be at most 400", out=tmp_path / "v.json")


def test_scaled_data_gives_finite_results_or_one_error(bench, tmp_path):
    """Inputs and outputs scaled by 1e78 give the same dof (it was null from csum^2/c2); outputs near 1e155
    and inputs of 1e160 are refused at read, and inputs of 1e-200, which underflow |U|^2, get one range error
    (they were JSON null with exit 0, or a misleading "singular ... condition number 1")."""
    base = h.load_json(bench["frf"])
    out = tmp_path / "f.json"
    r = frf(bench["bench"], scaled_csvs(bench["bench"], tmp_path, 1e78, 1e78), out)
    assert r.returncode == 0, r.stderr
    doc = h.load_json(out)
    h.validate(doc, "msid-frf-1")
    for a, b in zip(doc["lines"], base["lines"]):
        assert a["dof"] == pytest.approx(b["dof"], rel=1e-12)
    out.unlink()
    # samples beyond 1e150 are refused where they are read (file, line and column named); an input of 1e-200
    # underflows |U|^2 in the estimate
    for su, sy, needles in ((1.0, 1e155, ("column y1", "beyond the samples' range")),
                            (1e160, 1.0, ("column u1", "beyond the samples' range")),
                            (1e-200, 1.0, ("beyond what double precision can process",))):
        r = frf(bench["bench"], scaled_csvs(bench["bench"], tmp_path, su, sy), out)
        fails(tmp_path, r, *needles, out=out)
        assert "singular" not in r.stderr


def test_denormal_sample_rate(bench, tmp_path):
    """Hardening finding 5 (docs/reliability.md): --fs 4.9e-324 wrote null frequencies with exit 0."""
    out = tmp_path / "f.json"
    r = frf(bench["bench"], bench["bench"]["experiments"], out, "--fs", "4.9e-324")
    if r.returncode == 0:   # an accepted rate must give a finite, schema-valid file
        h.validate(h.load_json(out), "msid-frf-1")
    else:
        fails(tmp_path, r, out=out)


def test_compare_against_zero_reference(bench, tmp_path):
    """Hardening finding 5 (docs/reliability.md): relative distances to an all-zero model were written as null with exit 0."""
    z = json.loads(bench["model"].read_text())
    for k in ("B", "C", "D"):
        z[k] = [[0.0] * len(row) for row in z[k]]
    z.pop("lmfd", None)
    p = tmp_path / "zero.json"
    p.write_text(json.dumps(z))
    r = h.run("compare", bench["model"], p, "-o", tmp_path / "c.json")
    fails(tmp_path, r, "relative distances need a reference with finite, non-zero norms", out=tmp_path / "c.json")


@pytest.mark.parametrize("field,value,msg", [
    ("dof", 0, "dof must be at least 1"),
    ("dof", -3.5, "dof must be at least 1"),
    ("n_experiments", 2 ** 31, "'n_experiments' must be 1..64"),
])
def test_fit_range_checks_frf_fields(bench, tmp_path, field, value, msg):
    """Hardening finding 5 (docs/reliability.md): fit/validate accepted dof <= 0 and n_experiments = 2^31."""
    d = json.loads(bench["frf"].read_text())
    if field == "dof":
        d["lines"][1]["dof"] = value
    else:
        d[field] = value
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(d))
    r = h.run("fit", "--method", "ml", "--order", 2, p, "-o", tmp_path / "m.json")
    fails(tmp_path, r, msg, out=tmp_path / "m.json")


def test_file_size_limit_leaves_no_temporary(bench, tmp_path):
    """Hardening finding 10 (docs/reliability.md): a run killed by SIGXFSZ left out.json.tmp.PID behind; now write() fails (EFBIG) and the
    temporary is removed: one error, no file."""
    out = tmp_path / "f.json"
    args = ["frf", "--design", bench["bench"]["design"]]
    for p in bench["bench"]["experiments"]:
        args += ["--experiment", p]

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (4096, 4096))

    r = subprocess.run([h.msid_bin()] + [str(a) for a in args] + ["-o", str(out)], capture_output=True, text=True,
                       preexec_fn=limit, timeout=600)
    fails(tmp_path, r, "cannot write", out=out)


def test_huge_skip_periods(bench, tmp_path):
    """Hardening finding 10 (docs/reliability.md): a huge --skip-periods wrapped the first check (skip + 2 in 32 bits)."""
    out = tmp_path / "f.json"
    r = frf(bench["bench"], bench["bench"]["experiments"], out, "--skip-periods", 4294967295)
    fails(tmp_path, r, out=out)


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_signal_while_writing_leaves_no_temporary(tmp_path, sig):
    """Ctrl-C or SIGTERM while a result is being written ended the process and left e1.csv.tmp.PID behind.
    The signal is placed inside the write, whatever the machine's load: the command is stopped (SIGSTOP) as
    soon as its temporary file appears, the signal is sent, and the command continued. The temporary is gone,
    the file it would have replaced is the earlier one byte for byte, and the process ended by that signal."""
    import os
    import signal
    import time
    csv = tmp_path / "csv"
    csv.mkdir()
    old = csv / "e1.csv"
    old.write_text("u1\n0.5\n")
    landed = False
    for periods in (64, 256, 1024):   # a larger file if the write was over before it could be stopped
        p = subprocess.Popen([h.msid_bin(), "excite", "--period", "65536", "--lines", "1:2:2001", "--periods",
                              str(periods), "-o", str(tmp_path / "d.json"), "--csv", str(csv)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            tmp = []
            while p.poll() is None and not tmp:
                tmp = [f for f in os.listdir(csv) if ".tmp." in f]
            if not tmp:
                continue
            p.send_signal(signal.SIGSTOP)
            landed = (csv / tmp[0]).exists()   # stopped inside the write (not already renamed)
            p.send_signal(getattr(signal, sig))
            p.send_signal(signal.SIGCONT)
            p.wait(timeout=300)
        finally:
            if p.poll() is None:
                p.kill()
                p.wait()
        if landed:
            break
        old.write_text("u1\n0.5\n")   # the write was complete before the stop: the file was replaced
    assert landed, "the command was never stopped inside its write"
    assert p.returncode == -getattr(signal, sig), (p.returncode, p.stderr.read())
    assert not [f for f in os.listdir(csv) if ".tmp." in f], os.listdir(csv)
    assert old.read_text() == "u1\n0.5\n"
