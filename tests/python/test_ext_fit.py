"""msid.fit, msid.validate and Model.validate (the compiled module msid._msid) against `msid fit` and
`msid validate` on the same FRF file: the same model document, bit for bit, the same report and text,
the same error messages; an FRF held in memory gives the same model; cissim and multi on the arrays
give the model `msid fit` gives on the same samples in .npy files; no process started. The FRF is
measured by `msid frf` from seeded records of a 2x2 FIR plant. ctest runs this file with
MSID_PYTHON_DIR = the staged package (build/python)."""
import json
import re
import warnings

import numpy as np
import pytest

from conftest import msid as cli, refuse_processes

import msid

P = 256
PERIODS = 8
TAPS = [[[1.0, 0.5, 0.25], [0.2, -0.1, 0.05]], [[0.3, 0.2, 0.0], [1.0, -0.4, 0.1]]]


@pytest.fixture(scope="module")
def frf_path(bench):
    return bench / "frf.json"


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    """A directory with design.json, the records e0.npy, e1.npy (2x2 plant, 2 experiments, noisy
    outputs: u1, u2, y1, y2) and frf.json, the FRF `msid frf` estimates from them."""
    tmp = tmp_path_factory.mktemp("fit")
    d = msid.design(period=P, lines="1:40", inputs=2, seed=5, periods=PERIODS)
    d.save(tmp / "design.json")
    rng = np.random.default_rng(3)
    args = []
    for e in range(d.n_experiments):
        u = d.samples(e, PERIODS)
        y = np.zeros((u.shape[0], 2))
        for i in range(2):
            for j in range(2):
                for k, c in enumerate(TAPS[i][j]):
                    y[:, i] += c * np.roll(u[:, j], k)
        np.save(tmp / f"e{e}.npy", np.hstack([u, y + 0.02 * rng.standard_normal(y.shape)]))
        args += ["--experiment", tmp / f"e{e}.npy"]
    cli("frf", *args, "--design", tmp / "design.json", "--columns", "u1=1,u2=2,y1=3,y2=4", "--skip-periods", "1",
        "--fs", "1000", "-o", tmp / "frf.json")
    return tmp


def cli_model(tmp, frf_path, *args):
    out = tmp / "model.json"
    r = cli("fit", *args, frf_path, "-o", out, check=False)
    assert r.returncode in (0, 3), r.stderr
    return json.loads(out.read_text()), r


FITS = [("subspace", ["--order", "6"], dict(order=6)),
        ("subspace", ["--order", "4", "--refine", "none"], dict(order=4, refine="none")),
        ("subspace", ["--order", "auto"], dict(order="auto")),
        ("ml", ["--order", "6", "--param", "poles"], dict(order=6, param="poles")),
        ("ml", ["--order", "6"], dict(order=6)),
        ("ml", ["--order", "4:6"], dict(order=range(4, 7))),
        ("ml", ["--order", "6", "--weight", "known-input", "--feedthrough", "yes"],
         dict(order=6, weight="known-input", feedthrough="yes"))]


@pytest.mark.parametrize("method,cli_args,py_kw", FITS, ids=[" ".join([m] + a) for m, a, _ in FITS])
def test_fit_file_same_model_as_cli(tmp_path, frf_path, method, cli_args, py_kw):
    want, _ = cli_model(tmp_path, frf_path, "--method", method, *cli_args)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m = msid.fit(frf_path, method=method, **py_kw)
    assert m.doc == want   # every key and number, bit for bit (json compares floats exactly)
    # an FRF in memory: the same model; only the source names the file
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m2 = msid.fit(msid.read_frf(frf_path), method=method, **py_kw)
    d2 = dict(m2.doc)
    assert d2.pop("source") == "(in-memory FRF)"
    assert d2 == {k: v for k, v in want.items() if k != "source"}
    for k in "ABCD":
        assert np.array_equal(getattr(m2, k), np.array(want[k], float).reshape(getattr(m2, k).shape))


def test_validate_same_report_and_text_as_cli(tmp_path, frf_path):
    cli("fit", "--method", "ml", "--order", "6", frf_path, "-o", tmp_path / "m.json")
    r = cli("validate", tmp_path / "m.json", frf_path, "-o", tmp_path / "v.json")
    v = msid.validate(str(tmp_path / "m.json"), frf_path)
    assert v.report == json.loads((tmp_path / "v.json").read_text())
    assert v.text == r.stdout.splitlines()
    assert v.consistent == v.report["consistent_at_5pct"] and v.p_value == v.report["p_value"]
    # objects in memory: the same numbers, named as in memory
    m = msid.read_model(tmp_path / "m.json")
    v2 = m.validate(msid.read_frf(frf_path))
    for k in ("cost", "expected", "dof", "p_value", "weight", "lines", "line_stride"):
        assert v2.report[k] == v.report[k], k
    assert v2.report["frf"] == "(in-memory FRF)"
    # an undermodelled fit is rejected by both
    cli("fit", "--method", "ml", "--order", "2", frf_path, "-o", tmp_path / "m1.json")
    r = cli("validate", tmp_path / "m1.json", frf_path, "--weight", "cov")
    v1 = msid.read_model(tmp_path / "m1.json").validate(frf_path, weight="cov")
    assert not v1.consistent and "NOT consistent" in r.stdout
    assert v1.text[1:] == r.stdout.splitlines()[1:]
    assert v1.normalised_residuals.shape == (40,)


def cli_error(*args):
    r = cli(*args, check=False)
    assert r.returncode not in (0, 3), r.stdout
    m = re.search(r"msid \w+: error: (.*)", r.stderr)
    assert m, r.stderr
    return m.group(1)


def test_fit_errors_as_cli(tmp_path, frf_path):
    # an order the data cannot carry, and a request msid refuses: ValueError with msid's message
    want = cli_error("fit", "--method", "subspace", "--order", "90", frf_path, "-o", tmp_path / "x.json")
    with pytest.raises(ValueError) as e:
        msid.fit(frf_path, method="subspace", order=90)
    assert str(e.value) == msid._msid._python_words(want)
    want = cli_error("fit", "--method", "ml", "--order", "4", "--weight", "sometimes", frf_path, "-o", tmp_path / "x.json")
    with pytest.raises(ValueError) as e:
        msid.fit(frf_path, method="ml", order=4, weight="sometimes")
    assert "sometimes" in str(e.value) and "sometimes" in want
    with pytest.raises(ValueError, match="method must be one of 'subspace', 'lmfd', 'ml'"):
        msid.fit(frf_path, method="magic", order=4)
    with pytest.raises(OSError, match="cannot open"):
        msid.fit(tmp_path / "missing.json", method="ml", order=4)
    with pytest.raises(TypeError):
        msid.fit(np.zeros((3, 3)), method="ml", order=4)
    # a SISO model on the 2x2 FRF
    f = msid.read_frf(frf_path)
    siso = f.subsystem([0], [0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m = msid.fit(siso, method="ml", order=2)
    assert (m.n_inputs, m.n_outputs) == (1, 1)
    with pytest.raises(ValueError, match="the model has 1 inputs and 1 outputs, the FRF 2 and 2"):
        m.validate(f)
    # an FRF holding a NaN is refused before msid sees it
    f.G[3, 0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        msid.fit(f, method="ml", order=4)


def test_fit_not_converged_warns_and_marks(tmp_path, frf_path):
    want, r = cli_model(tmp_path, frf_path, "--method", "ml", "--order", "6", "--max-iter", "1")
    assert r.returncode == 3 and want["converged"] is False
    with pytest.warns(msid.ConvergenceWarning, match='did not converge in 1 iterations .*"converged": false'):
        m = msid.fit(frf_path, method="ml", order=6, max_iter=1)
    assert m.doc == want


def test_fit_and_validate_start_no_process(monkeypatch, frf_path):
    refuse_processes(monkeypatch)
    f = msid.read_frf(frf_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m = msid.fit(f, method="ml", order=6)
    assert m.validate(f).consistent


def named_as(doc, names):
    """The document with every string that names a file replaced by the name msid.fit gives its array."""
    if isinstance(doc, dict):
        return {k: named_as(v, names) for k, v in doc.items()}
    if isinstance(doc, list):
        return [named_as(v, names) for v in doc]
    return names.get(doc, doc) if isinstance(doc, str) else doc


def test_cissim_records_same_model_as_cli(tmp_path, bench):
    files = [str(bench / "e0.npy"), str(bench / "e1.npy")]
    cli("fit", "--method", "cissim", "--period", P, "--lines", "1:40", "--order", "4", "--experiment", files[0],
        "--experiment", files[1], "--columns", "u1=1,u2=2,y1=3,y2=4", "-o", tmp_path / "cissim.json")
    want = json.loads((tmp_path / "cissim.json").read_text())
    recs = [np.load(f) for f in files]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m = msid.fit(recs, method="cissim", order=4, design=msid.read_design(bench / "design.json"))
    assert m.doc == named_as(want, {files[0]: "records[0]", files[1]: "records[1]"})


def test_multi_records_same_model_as_cli(tmp_path, bench):
    # one input and one output of experiment 0, 1500 samples; and its output alone as a free response
    r = np.load(bench / "e0.npy")[:1500][:, [0, 2]].copy()
    np.save(tmp_path / "siso.npy", r)
    out = tmp_path / "multi.json"
    cli("fit", "--method", "multi", "--order", "2", "--experiment", tmp_path / "siso.npy", "--columns", "u1=1,y1=2",
        "--fs", "1000", "-o", out)
    want = json.loads(out.read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m = msid.fit(r, method="multi", order=2, columns="u1=1,y1=2", fs=1000)
    assert m.doc == named_as(want, {str(tmp_path / "siso.npy"): "records[0]"})
    with pytest.raises(TypeError, match="takes no option weight"):
        msid.fit(r, method="multi", order=2, n_inputs=1, weight="cov")
    with pytest.raises(ValueError, match="records\\[0\\]"):
        bad = r.copy()
        bad[100, 1] = np.inf
        msid.fit(bad, method="multi", order=2, n_inputs=1)


def test_multi_long_stack_same_model_as_cli(tmp_path, bench):
    """Two white inputs through four resonances (order 8), 20,000 samples: a stacked least squares of
    20,000 rows by 18 columns (past the 2^20 multiply-adds from which the extension runs it abandonable,
    on a thread of its own; the command line runs it in place): the same model, bit for bit."""
    from scipy.signal import lfilter
    n = 20000
    rng = np.random.default_rng(8)
    u = rng.standard_normal((n, 2))
    y = 0.02 * rng.standard_normal(n)
    for th in (0.3, 0.8, 1.4, 2.2):
        p = 0.93 * np.exp(1j * th)
        for j in range(2):
            y += lfilter([0.1 + 0.05 * j, 0.05], [1, -2 * p.real, abs(p) ** 2], u[:, j])
    assert n * (2 * 9) ** 2 >= 1 << 20
    np.save(tmp_path / "long.npy", np.column_stack([u, y]))
    out = tmp_path / "multi.json"
    cli("fit", "--method", "multi", "--order", "8", "--experiment", tmp_path / "long.npy", "--columns",
        "u1=1,u2=2,y1=3", "-o", out)
    want = json.loads(out.read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m = msid.fit(np.load(tmp_path / "long.npy"), method="multi", order=8, columns="u1=1,u2=2,y1=3")
    assert m.doc == named_as(want, {str(tmp_path / "long.npy"): "records[0]"})


def test_modes_same_report_and_text_as_cli(tmp_path, frf_path):
    cli("fit", "--method", "ml", "--order", "6", frf_path, "-o", tmp_path / "m.json")
    r = cli("modes", tmp_path / "m.json", "-o", tmp_path / "modes.json")
    m = msid.read_model(tmp_path / "m.json").modes()
    assert m.report == json.loads((tmp_path / "modes.json").read_text())
    assert m.text == r.stdout and str(m) == r.stdout
    assert len(m.modes) == len(m.report["modes"]) >= 1
    with pytest.raises(ValueError, match="not an msid-model/1 file"):
        bad = tmp_path / "bad.json"
        bad.write_text('{"format": "msid-frf/1"}')
        msid.modes(bad)


def siso_record(seed, n=1500):
    """A white input through the FIR path u1 -> y1 of the plant, output noise: columns u1, y1."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    return np.column_stack([u, np.convolve(u, TAPS[0][0])[:n] + 0.02 * rng.standard_normal(n)])


def test_multi_validate_on_records_and_modes_as_cli(tmp_path, bench):
    r, fresh = siso_record(11), siso_record(12)
    np.save(tmp_path / "siso.npy", r)
    np.save(tmp_path / "fresh.npy", fresh)
    cli("fit", "--method", "multi", "--order", "2", "--experiment", tmp_path / "siso.npy", "--columns", "u1=1,y1=2",
        "-o", tmp_path / "multi.json")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", msid.NoteWarning)
        m = msid.fit(r, method="multi", order=2, columns="u1=1,y1=2")
    # on its own records (named alike: the file, the array) and on a fresh one: the same numbers as the CLI
    for cli_rec, py_rec, own in (("siso.npy", r, True), ("fresh.npy", fresh, False)):
        c = cli("validate", tmp_path / "multi.json", "--experiment", tmp_path / cli_rec, "--columns", "u1=1,y1=2",
                "-o", tmp_path / "v.json")
        want = json.loads((tmp_path / "v.json").read_text())
        v = m.validate(records=[py_rec], columns="u1=1,y1=2", own_records=own)
        assert want["own_records"] is own and v.report["own_records"] is own
        for k in ("cost", "dof", "noise_variance", "p_value_cost", "p_value_whiteness", "p_value", "autocorrelation",
                  "consistent_at_5pct"):
            assert v.report[k] == want[k], k
        assert v.text[1:] == c.stdout.splitlines()[1:]
    # msid modes of the multi model
    c = cli("modes", tmp_path / "multi.json", "-o", tmp_path / "mm.json")
    mm = msid.modes(str(tmp_path / "multi.json"))
    assert mm.report == json.loads((tmp_path / "mm.json").read_text()) and mm.text == c.stdout
    # a model whose prediction diverges on the records (u1 -> y1 of the 2x2 plant, u2 left out: model
    # error, an unstable fit): no verdict from residuals that are not numbers, from either
    bad = np.load(bench / "e0.npy")[:1500][:, [0, 2]].copy()
    np.save(tmp_path / "bad.npy", bad)
    cli("fit", "--method", "multi", "--order", "2", "--experiment", tmp_path / "bad.npy", "--columns", "u1=1,y1=2",
        "-o", tmp_path / "bad_model.json")
    want = cli_error("validate", tmp_path / "bad_model.json", "--experiment", tmp_path / "bad.npy", "--columns", "u1=1,y1=2")
    assert "not finite" in want and "no verdict" in want
    with pytest.raises(ValueError, match="not finite .* no verdict"):
        msid.validate(str(tmp_path / "bad_model.json"), records=[bad], columns="u1=1,y1=2")
    # an FRF model on records, and records and an FRF at once: refused
    with pytest.raises(ValueError, match="validation on records needs a model written by msid fit --method multi"):
        msid.validate(msid.fit(bench / "frf.json", method="ml", order=4), records=[r], n_inputs=1)
    with pytest.raises(ValueError, match="not both"):
        m.validate(bench / "frf.json", records=[r], n_inputs=1)
