"""msid.frf, msid.Measurement and msid.design (the compiled module msid._msid) against the command line
on the same samples: the same FRF bits, the same design file and samples, the same error messages;
block-size invariance of Measurement; no process started. Fixed seeds; ctest runs this file with
MSID_PYTHON_DIR = the staged package (build/python)."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import msid as cli, refuse_processes
from npy_cli import cli_error, cli_frf

import msid

# the interpreter of a child Python: this one, or in a cross build the script that runs the target's
# interpreter under the emulator (sys.executable is then a foreign binary this machine cannot start)
PYTHON = os.environ.get("MSID_TARGET_PYTHON") or sys.executable
P = 256
LINES = "1:40"
PERIODS = 8
# output i from input j: taps of a short FIR filter (applied circularly: the records are in steady state)
TAPS = [[[1.0, 0.5, 0.25], [0.2, -0.1, 0.05]], [[0.3, 0.2, 0.0], [1.0, -0.4, 0.1]]]


def records(d, periods=PERIODS, seed=1, noise=0.02):
    """One record per experiment of the design: columns u1..u_nu, y1, y2 (noisy inputs and outputs)."""
    rng = np.random.default_rng(seed)
    out = []
    for e in range(d.n_experiments):
        u = d.samples(e, periods)
        y = np.zeros((u.shape[0], 2))
        for i in range(2):
            for j in range(d.n_inputs):
                for k, c in enumerate(TAPS[i][j]):
                    y[:, i] += c * np.roll(u[:, j], k)
        out.append(np.hstack([u + 0.1 * noise * rng.standard_normal(u.shape), y + noise * rng.standard_normal(y.shape)]))
    return out


@pytest.fixture(scope="module")
def d2():
    return msid.design(period=P, lines=LINES, inputs=2, seed=5, periods=PERIODS)


@pytest.fixture(scope="module")
def recs(d2):
    return records(d2)


def assert_same_bits(a, b):
    for k in ("G", "cov", "dof", "cov_known_input", "dof_known_input", "freq", "bins", "real"):
        x, y = getattr(a, k), getattr(b, k)
        assert (x is None) == (y is None), k
        if x is not None:
            assert x.shape == y.shape and np.array_equal(x, y), k
    for k in ("periods_used", "periods_rejected", "noise_cov", "n_inputs", "n_outputs", "period_samples"):
        assert a.meta.get(k) == b.meta.get(k), k


# ---- the same bits as msid frf ----

@pytest.mark.parametrize("py_opts, cli_opts", [
    ({"skip_periods": 1}, ["--skip-periods", "1"]),
    ({"skip_periods": 2, "transient": "drop", "alpha": 0.05, "detect_lines": "41:44", "fs": 1000.0},
     ["--skip-periods", "2", "--transient", "drop", "--alpha", "0.05", "--detect-lines", "41:44", "--fs", "1000"]),
    ({"dft": "fft"}, ["--dft", "fft"]),
    ({"dft": "stream", "block": 100}, ["--dft", "stream", "--block", "100"]),
])
def test_frf_design_same_bits_as_cli(tmp_path, d2, recs, py_opts, cli_opts):
    d2.save(tmp_path / "design.json")
    want = cli_frf(tmp_path, recs, 2, "--design", tmp_path / "design.json", *cli_opts)
    got = msid.frf(recs, design=d2, **py_opts)
    assert_same_bits(got, want)
    # a design file works as well as the object
    assert_same_bits(msid.frf(recs, design=tmp_path / "design.json", **py_opts), want)


def test_frf_period_lines_and_auto_same_bits_as_cli(tmp_path, recs):
    want = cli_frf(tmp_path, recs, 2, "--period", P, "--lines", LINES)
    assert_same_bits(msid.frf(recs, period=P, lines=LINES, n_inputs=2), want)
    assert_same_bits(msid.frf(recs, period=P, lines=list(range(1, 41)), n_inputs=2), want)
    want = cli_frf(tmp_path, recs, 2, "--period", "auto", "--lines", "auto")
    got = msid.frf(recs, period="auto", lines="auto", n_inputs=2)
    assert_same_bits(got, want)
    assert any(r.startswith("--period auto") for r in got.reports)


def test_frf_direct_same_bits_as_cli(tmp_path, d2, recs):
    part = [r[: 5 * P + 37] for r in recs]   # the direct estimator takes any length
    d2.save(tmp_path / "design.json")
    want = cli_frf(tmp_path, part, 2, "--design", tmp_path / "design.json", "--direct")
    with pytest.warns(msid.NoteWarning, match="not whole periods"):
        got = msid.frf(part, design=d2, direct=True)
    assert_same_bits(got, want)
    assert any("not whole periods" in n for n in got.notes)


def test_frf_realisations_same_bits_as_cli(tmp_path):
    # two random-phase realisations of a one-input multisine, one record each
    recs1 = [records(msid.design(period=P, lines=LINES, seed=s), seed=s)[0] for s in (9, 10)]
    want = cli_frf(tmp_path, recs1, 1, "--period", P, "--lines", LINES, "--realisations", 2)
    assert_same_bits(msid.frf(recs1, period=P, lines=LINES, n_inputs=1, realisations=2), want)


def test_frf_realisations_one_period_same_bits_as_cli(tmp_path):
    # the benchmark layout: random-phase realisations of ONE period each; the BLA and its total covariance
    # only (dof R - 1), the missing noise part in a note, and msid.fit weighs with the total covariance
    R = 5
    recs1 = [records(msid.design(period=P, lines=LINES, seed=s), periods=1, seed=s)[0] for s in range(20, 20 + R)]
    want = cli_frf(tmp_path, recs1, 1, "--period", P, "--lines", LINES, "--realisations", R)
    with pytest.warns(msid.NoteWarning, match="one period per realisation: noise and nonlinear distortion cannot"):
        got = msid.frf(recs1, period=P, lines=LINES, n_inputs=1, realisations=R)
    assert_same_bits(got, want)
    assert got.cov_known_input is None and "noise_cov" not in got.meta and np.all(got.dof == R - 1)
    assert got.meta["nonlinear_distortion"]["noise_separated"] is False
    m = msid.fit(got, order=2)
    assert m.order == 2


def test_frf_dataframe_and_copies_same_bits(d2, recs):
    pd = pytest.importorskip("pandas")
    want = msid.frf(recs, design=d2)
    frames = [pd.DataFrame({"t": np.arange(len(r)), "Acc1": r[:, 2], "Force1": r[:, 0], "Force2": r[:, 1],
                            "Acc2": r[:, 3]}) for r in recs]
    assert_same_bits(msid.frf(frames, design=d2, columns="u1=Force1,u2=Force2,y1=Acc1,y2=Acc2"), want)
    assert_same_bits(msid.frf(frames, design=d2, columns={"u1": "Force1", "u2": "Force2", "y1": "Acc1", "y2": "Acc2"}),
                     want)
    # Fortran order, a strided view and float32-exact values are copied once, to the same samples
    assert_same_bits(msid.frf([np.asfortranarray(r) for r in recs], design=d2), want)
    wide = [np.repeat(r, 2, axis=1) for r in recs]
    assert_same_bits(msid.frf([w[:, ::2] for w in wide], design=d2), want)
    # columns picked from a wider array, numbered from 1 as in a .npy
    extra = [np.hstack([r[:, 2:], r[:, :2]]) for r in recs]
    assert_same_bits(msid.frf(extra, design=d2, columns="u1=3,u2=4,y1=1,y2=2"), want)



def test_frf_dataframe_names_and_units(d2, recs):
    """A DataFrame's column names are the signals' names, "Force [N]" a name and a unit, as in a CSV."""
    pd = pytest.importorskip("pandas")
    frames = [pd.DataFrame({"Force1 [N]": r[:, 0], "Force2 [N]": r[:, 1], "Acc1 [m/s^2]": r[:, 2],
                            "Acc2": r[:, 3]}) for r in recs]
    f = msid.frf(frames, design=d2, columns="u1=Force1 [N],u2=Force2 [N],y1=Acc1 [m/s^2],y2=Acc2")
    assert f.signal_names() == (["Force1", "Force2"], ["Acc1", "Acc2"])
    assert f.signal_units() == (["N", "N"], ["m/s^2", ""])
    assert f.gain_unit(0, 1) == "m/s^2/N" and f.gain_unit(1, 0) == ""
    # plain arrays say nothing: the default names, no units
    g = msid.frf(recs, design=d2)
    assert g.signal_names() == (["u1", "u2"], ["y1", "y2"]) and "input_units" not in g.meta


def test_frf_reads_c_float64_in_place(d2, recs):
    from msid import compute
    for r in recs:
        assert compute._real_samples(r, "x") is r
    assert compute._real_samples(np.asfortranarray(recs[0]), "x") is not recs[0]


def test_frf_starts_no_process(monkeypatch, d2, recs):
    refuse_processes(monkeypatch)
    f = msid.frf(recs, design=d2, skip_periods=1)
    assert f.G.shape == (40, 2, 2)
    m = msid.Measurement(design=d2, skip_periods=1)
    for e, r in enumerate(recs):
        m.push(r, experiment=e)
    assert_same_bits(m.frf(), f)


def test_frf_of_files_same_bits_as_cli(tmp_path, monkeypatch, d2, recs):
    """Experiment files given as paths: msid.frf runs the job `msid frf --experiment` runs (a CSV record
    streamed through the core), in process: the same bits as the command line on the same files and as
    the arrays; a missing file is an OSError with msid's message, a bad cell a ValueError."""
    csvs = []
    for k, r in enumerate(recs):
        p = tmp_path / f"e{k + 1}.csv"
        np.savetxt(p, r, delimiter=",", fmt="%.17g", header="u1,u2,y1,y2", comments="")
        csvs.append(p)
    d2.save(tmp_path / "design.json")
    cli("frf", "--design", tmp_path / "design.json", "--experiment", csvs[0], "--experiment", csvs[1],
        "--skip-periods", 1, "-o", tmp_path / "cli.json")
    want = msid.read_frf(tmp_path / "cli.json")
    cli("frf", "--period", "auto", "--lines", "auto", "--experiment", csvs[0], "--experiment", csvs[1],
        "--skip-periods", 1, "-o", tmp_path / "cli_auto.json")
    want_auto = msid.read_frf(tmp_path / "cli_auto.json")
    refuse_processes(monkeypatch)
    got = msid.frf(csvs, design=d2, skip_periods=1)
    assert_same_bits(got, want)
    assert_same_bits(got, msid.frf(recs, design=d2, skip_periods=1))
    assert_same_bits(msid.frf([str(p) for p in csvs], period=P, lines=LINES, skip_periods=1), got)
    # period and lines found by a first pass over the streamed files, as the command line finds them
    auto = msid.frf(csvs, period="auto", lines="auto", skip_periods=1)
    assert_same_bits(auto, want_auto)
    assert any(r.startswith("--period auto") for r in auto.reports)
    with pytest.raises(OSError, match="cannot open .*nope.csv"):
        msid.frf([tmp_path / "nope.csv", csvs[1]], design=d2)
    bad = tmp_path / "bad.csv"
    lines = csvs[0].read_text().split("\n")
    lines[5] = "x" + lines[5][lines[5].index(","):]
    bad.write_text("\n".join(lines))
    with pytest.raises(ValueError, match=r"bad.csv' line 6, column u1: 'x' is not a number"):
        msid.frf([bad, csvs[1]], design=d2)


def test_frf_threads_same_bits(d2, recs):
    """Jobs on several Python threads at once (the GIL is released; FFTW's planner is shared) give the
    bits of one job alone."""
    import threading
    want = msid.frf(recs, design=d2, dft="fft")
    got, errors = [], []

    def run():
        try:
            for _ in range(5):
                got.append(msid.frf(recs, design=d2, dft="fft"))
                m = msid.Measurement(design=d2, dft="fft")
                for e, r in enumerate(recs):
                    m.push(r, experiment=e)
                got.append(m.frf())
        except Exception as e:   # reported below, on the main thread
            errors.append(e)
    th = [threading.Thread(target=run) for _ in range(3)]
    for t in th:
        t.start()
    for t in th:
        t.join()
    assert not errors and len(got) == 30
    for f in got:
        assert_same_bits(f, want)


# ---- bad input: msid's messages ----

def test_frf_nan_message_as_cli(tmp_path, d2, recs):
    bad = [recs[0].copy(), recs[1].copy()]
    bad[1][300, 2] = np.nan
    d2.save(tmp_path / "design.json")
    want = cli_error(tmp_path, bad, 2, "--design", tmp_path / "design.json")
    assert want == "'records[1]' row 301, column 3: NaN or Inf is not allowed"
    with pytest.raises(ValueError) as e:
        msid.frf(bad, design=d2)
    assert str(e.value) == msid._msid._python_words(want)
    # the paths that read the samples before the job (period "auto") scan them first, as the reader does
    want = cli_error(tmp_path, bad, 2, "--period", "auto", "--lines", LINES)
    with pytest.raises(ValueError) as e:
        msid.frf(bad, period="auto", lines=LINES, n_inputs=2)
    assert str(e.value) == msid._msid._python_words(want)


def test_frf_too_few_periods_message_as_cli(tmp_path, recs):
    short = [recs[0], np.ascontiguousarray(recs[1][: P + P // 2])]
    want = cli_error(tmp_path, short, 2, "--period", P, "--lines", LINES)
    assert "at least 2 usable periods" in want
    with pytest.raises(ValueError) as e:
        msid.frf(short, period=P, lines=LINES, n_inputs=2)
    assert str(e.value) == msid._msid._python_words(want)


def test_frf_nonperiodic_input_message_as_cli(tmp_path, recs):
    rng = np.random.default_rng(3)
    noisy = [np.hstack([rng.standard_normal((r.shape[0], 2)), r[:, 2:]]) for r in recs]
    want = cli_error(tmp_path, noisy, 2, "--period", P, "--lines", LINES)
    with pytest.raises(ValueError) as e:
        msid.frf(noisy, period=P, lines=LINES, n_inputs=2)
    assert str(e.value) == msid._msid._python_words(want)


def test_frf_option_and_shape_errors(tmp_path, d2, recs):
    with pytest.raises(ValueError, match="1-dimensional array"):
        msid.frf([recs[0][:, 0], recs[1]], design=d2)
    with pytest.raises(ValueError, match="dtype complex128 is not supported"):
        msid.frf([recs[0].astype(complex), recs[1]], design=d2)
    with pytest.raises(ValueError, match="without column names: give n_inputs"):
        msid.frf(recs, period=P, lines=LINES)
    with pytest.raises(ValueError, match="leave no output column"):
        msid.frf(recs, period=P, lines=LINES, n_inputs=4)
    with pytest.raises(ValueError, match="holds no samples"):
        msid.frf([recs[0][:0], recs[1]], design=d2)
    with pytest.raises(ValueError, match="alpha must be in"):
        msid.frf(recs, design=d2, alpha=2)
    with pytest.raises(ValueError, match="give either design or period/lines"):
        msid.frf(recs, design=d2, period=P)
    with pytest.raises(ValueError, match="transient must be one of 'flag', 'drop', 'off', not 'maybe'"):
        msid.frf(recs, design=d2, transient="maybe")
    with pytest.raises(ValueError, match="skip_periods must be a non-negative integer"):
        msid.frf(recs, design=d2, skip_periods=-1)
    with pytest.raises(ValueError, match="bad range"):
        msid.frf(recs, period=P, lines="9:3", n_inputs=2)
    with pytest.raises(TypeError, match=r"lpm\(\) got an unexpected keyword argument 'design'"):
        msid.frf(recs, design=d2, method="lpm")
    with pytest.raises(ValueError, match="no column 'Force'"):
        msid.frf(recs, design=d2, columns="u1=Force,u2=2,y1=3,y2=4")
    with pytest.raises(OSError):
        msid.frf(recs, design=tmp_path / "missing.json")
    # the design's experiments, as the command line counts files
    want = cli_error(tmp_path, recs[:1], 2, "--period", P, "--lines", LINES)
    with pytest.raises(ValueError) as e:
        msid.frf(recs[:1], period=P, lines=LINES, n_inputs=2)
    assert str(e.value) == msid._msid._python_words(want)


def test_request_rules_once_in_keywords(tmp_path, d2, recs):
    """The request's rules are the job's alone (msidjob::check_plan, check_est_plan): the command line
    names the options by their flags, Python by its keywords, with the same message otherwise."""
    d2.save(tmp_path / "design.json")
    D = ("--design", tmp_path / "design.json")
    cases = [
        (D + ("--direct", "--realisations", 2), dict(design=d2, direct=True, realisations=2),
         "realisations does not apply to direct"),
        (D + ("--direct", "--alpha", 0.05), dict(design=d2, direct=True, alpha=0.05), "alpha does not apply to direct"),
        (D + ("--direct", "--detect-lines", 41), dict(design=d2, direct=True, detect_lines=[41]),
         "detect_lines does not apply to direct"),
        (("--period", P, "--lines", LINES, "--direct"), dict(period=P, lines=LINES, n_inputs=2, direct=True),
         "direct needs design (the input is the design's exact multisine)"),
        (("--period", "auto", "--lines", LINES, "--direct"), dict(period="auto", lines=LINES, n_inputs=2, direct=True),
         "direct needs design (no auto period/lines)"),
        (D + ("--block", 0), dict(design=d2, block=0), "block must be positive"),
        (D + ("--fs", -2), dict(design=d2, fs=-2.0), "fs must be positive"),
        (D + ("--alpha", 1.5), dict(design=d2, alpha=1.5), "alpha must be in (0, 1)"),
        (D + ("--period", P), dict(design=d2, period=P), "give either design or period/lines, not both"),
        (("--period", P), dict(period=P, n_inputs=2), "give design, or both period and lines"),
    ]
    for args, kw, want in cases:
        flags = cli_error(tmp_path, recs, 2, *args)
        assert "--" in flags and msid._msid._python_words(flags) == want, (args, flags)
        with pytest.raises(ValueError) as e:
            msid.frf(recs, **kw)
        assert str(e.value) == want, kw
    # the arbitrary-record estimators: the job's ranges of threads and fs
    for args, call, want in [
        (("--method", "lpm", "--threads", 0), lambda: msid.lpm(recs, n_inputs=2, threads=0), "threads must be 1..64"),
        (("--method", "lpm", "--fs", 0), lambda: msid.lpm(recs, n_inputs=2, fs=0.0), "fs must be positive"),
    ]:
        flags = cli_error(tmp_path, recs, 2, *args)
        assert "--" in flags and msid._msid._python_words(flags) == want, (args, flags)
        with pytest.raises(ValueError) as e:
            call()
        assert str(e.value) == want


# ---- Measurement ----

@pytest.mark.parametrize("block", [1, 7, 1000, None])
def test_measurement_block_sizes_same_bits(d2, recs, block):
    want = msid.frf(recs, design=d2, skip_periods=1, detect_lines="41:42")
    m = msid.Measurement(design=d2, skip_periods=1, detect_lines="41:42")
    for e, r in enumerate(recs):
        n = len(r) if block is None else block
        for k in range(0, len(r), n):
            m.push(r[k:k + n], experiment=e)
    assert m.progress == [PERIODS, PERIODS]
    assert "periods received [8, 8]" in repr(m)
    assert_same_bits(m.frf(), want)


def test_measurement_progress_and_errors(d2, recs):
    m = msid.Measurement(design=d2)
    m.push(recs[0][: P + 5], experiment=0)
    assert m.progress == [1, 0]
    bad = recs[0][P + 5: 2 * P].copy()
    bad[3, 1] = np.inf
    with pytest.raises(ValueError, match=re.escape(f"'experiment 0' row {P + 5 + 4}, column 2: NaN or Inf")):
        m.push(bad, experiment=0)
    with pytest.raises(ValueError, match="a block of 3 columns"):
        m.push(recs[0][:4, :3], experiment=0)
    with pytest.raises(ValueError, match="experiment 2: the design has 2"):
        m.push(recs[1][:4], experiment=2)
    m.push(recs[1][:10], experiment=1)
    with pytest.raises(ValueError, match="experiment 0 was closed"):
        m.push(recs[0][:4], experiment=0)
    with pytest.raises(ValueError, match="usable period"):
        m.frf()
    with pytest.raises(ValueError, match="finished"):
        m.push(recs[1][:4], experiment=1)


def test_measurement_history_capacity(d2, recs):
    m = msid.Measurement(design=d2, max_periods=4)
    with pytest.raises(ValueError, match="more than max_periods = 4"):
        m.push(recs[0], experiment=0)
    m = msid.Measurement(design=d2, max_periods=4, transient="off")
    for e, r in enumerate(recs):
        m.push(r, experiment=e)
    assert_same_bits(m.frf(), msid.frf(recs, design=d2, transient="off"))


# ---- designs ----

def test_design_file_and_samples_as_cli(tmp_path):
    d = msid.design(period=128, lines="1:3:40", inputs=2, experiments=3, seed=11, amplitudes=0.5, phases="random",
                    periods=3)
    d.save(tmp_path / "py.json")
    cli("excite", "--period", 128, "--lines", "1:3:40", "--inputs", 2, "--experiments", 3, "--seed", 11,
        "--amplitudes", 0.5, "--periods", 3, "-o", tmp_path / "cli.json", "--csv", tmp_path / "csv")
    assert (tmp_path / "py.json").read_bytes() == (tmp_path / "cli.json").read_bytes()
    for e in range(3):
        want = np.loadtxt(tmp_path / "csv" / f"e{e + 1}.csv", delimiter=",", skiprows=1)
        assert np.array_equal(d.samples(e, 3), want)
    r = msid.read_design(tmp_path / "cli.json")
    assert r.doc == d.doc and r.period == 128 and r.n_experiments == 3 and list(r.bins) == list(range(1, 41, 3))
    assert "P = 128" in repr(r)


def test_design_errors_as_cli(tmp_path):
    r = cli("excite", "--period", 64, "--lines", "1,40", "-o", tmp_path / "x.json", check=False)
    want = re.search(r"error: (.*)", r.stderr).group(1)
    with pytest.raises(ValueError) as e:
        msid.design(period=64, lines=[1, 40])
    assert str(e.value) == msid._msid._python_words(want)
    with pytest.raises(OSError):
        msid.read_design(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(ValueError):
        msid.read_design(tmp_path / "bad.json")


def test_import_without_extension_names_the_build(tmp_path):
    """The source tree's package (no compiled module): files work, msid.frf says how to build."""
    src = Path(__file__).resolve().parents[2] / "tools" / "python"
    code = ("import msid, numpy as np\n"
            "assert msid.FRF and msid.read_frf\n"
            "try:\n    msid.frf(np.zeros((8, 2)), period=4, lines=[1], n_inputs=1)\n"
            "except ImportError as e:\n    print(e)\n")
    r = subprocess.run([PYTHON, "-c", code], capture_output=True, text=True, timeout=600,
                       env={**os.environ, "PYTHONPATH": str(src)}, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "msid._msid" in r.stdout and "pip install ./tools/python" in r.stdout


def test_bench_script_runs(tmp_path):
    """scripts/bench_python_frf.py (docs/benchmarks.md) runs on this package and reports every figure;
    its times are not checked (a bench, not a test)."""
    src = Path(msid.__file__).resolve().parents[1]
    script = Path(__file__).resolve().parents[2] / "scripts" / "bench_python_frf.py"
    r = subprocess.run([PYTHON, str(script), "--min-seconds", "0", "--json"], capture_output=True, text=True,
                       timeout=600, env={**os.environ, "PYTHONPATH": str(src)}, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    for k in ("peer_cpu_s", "msid_frf_cpu_s", "ext_cpu_s", "tiny_call_cpu_s", "tiny_ext_cpu_s"):
        assert res[k] > 0, k
