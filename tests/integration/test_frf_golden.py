"""msid-frf/1 has one writer and one reader (tools/frffile, issue 11): every document the
estimators write and every model fitted from one is byte-identical to the files the code
before that change wrote (commit 1fc65f9) for the same fixed seeds. The golden files in
golden/ were produced by that commit; MSID_GOLDEN_WRITE=1 rewrites them (only do that on
purpose, after a reviewed change of the format).

Covered writers: the periodic job (msid frf with detection lines, sample rate, a start-up
transient), the direct time-domain estimator (records cut to partial periods),
the LPM and the ETFE, the robust BLA (--realisations); the reader through msid fit and
msid validate on those files. The line DFT is pinned to the streaming path (--dft stream).
Negative control: a file that differs in one byte is told apart."""
import os
import shutil

import numpy as np
import pytest

import helpers as h
from test_modal_cli import realisation_bench

GOLDEN = h.HERE / "golden"
WRITE = os.environ.get("MSID_GOLDEN_WRITE") == "1"


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    d = tmp_path_factory.mktemp("golden")
    bench = h.make_dt_bench(d, seed=5, periods=6)
    return {"dir": d, **bench}


def _check(path, name):
    got = path.read_bytes()
    ref = GOLDEN / name
    if WRITE:
        GOLDEN.mkdir(exist_ok=True)
        shutil.copyfile(path, ref)
        return
    want = ref.read_bytes()
    if got != want:
        k = next((i for i, (a, b) in enumerate(zip(got, want)) if a != b), min(len(got), len(want)))
        pytest.fail(f"{name}: differs from golden/{name} at byte {k}: "
                    f"{got[max(0, k - 60):k + 60]!r} vs {want[max(0, k - 60):k + 60]!r}")


def _exps(paths):
    a = []
    for p in paths:
        a += ["--experiment", p]
    return a


def run(d, *args):
    # file names relative to d: the documents name their sources, and the names must not depend on tmp paths
    return h.run_ok(*args, cwd=d)


def _names(paths):
    return [p.name for p in paths]


def _fit_and_validate(d, frf, stem, order=4):
    model = f"{stem}-model.json"
    run(d, "fit", "--method", "subspace", "--order", order, frf, "-o", model)
    _check(d / model, model)
    val = f"{stem}-validate.json"
    run(d, "validate", model, frf, "-o", val)
    _check(d / val, val)


def test_periodic(work):
    d = work["dir"]
    run(d, "frf", "--design", "design.json", *_exps(_names(work["experiments"])), "--dft", "stream", "--fs", 1000,
        "--detect-lines", "2,4,60", "-o", "periodic.json")
    _check(d / "periodic.json", "periodic.json")
    _fit_and_validate(d, "periodic.json", "periodic")


def test_periodic_skip_drop(work):
    d = work["dir"]
    run(d, "frf", "--design", "design.json", *_exps(_names(work["experiments"])), "--dft", "stream",
        "--skip-periods", 1, "--transient", "drop", "-o", "drop.json")
    _check(d / "drop.json", "drop.json")


def test_direct(work, tmp_path):
    d = work["dir"]
    cut = []
    for e in (1, 2):
        cols = h.read_csv(d / f"e{e}.csv")
        cut.append(f"c{e}.csv")
        h.write_csv(tmp_path / cut[-1], {k: np.asarray(v)[:256 * 4 + 77] for k, v in cols.items() if k != "t"})
    shutil.copyfile(d / "design.json", tmp_path / "design.json")
    run(tmp_path, "frf", "--direct", "--design", "design.json", *_exps(cut), "-o", "direct.json")
    _check(tmp_path / "direct.json", "direct.json")
    _fit_and_validate(tmp_path, "direct.json", "direct")


def test_lpm(work):
    run(work["dir"], "frf", "--method", "lpm", "--band", "0.01:0.03", *_exps(_names(work["experiments"])),
        "-o", "lpm.json")
    _check(work["dir"] / "lpm.json", "lpm.json")


def test_etfe(tmp_path):
    # every line of the period excited (the ETFE divides by each line's input)
    h.run_ok("excite", "--period", 256, "--lines", "1:12", "--inputs", 2, "--experiments", 2, "--periods", 4,
             "--seed", 12, "--csv", tmp_path / "g", "-o", tmp_path / "d.json")
    rng, recs = np.random.default_rng(8), []
    for e in (1, 2):
        c = h.read_csv(tmp_path / "g" / f"e{e}.csv")
        u = np.column_stack([c["u1"], c["u2"]])
        y = h.dt_simulate(h.dt_plant_2x2(), u, warmup=6, period=256) + h.DT_SIGMA_Y * rng.standard_normal((len(u), 2))
        recs.append(f"p{e}.csv")
        h.write_csv(tmp_path / recs[-1], h.experiment_columns(u, y))
    run(tmp_path, "frf", "--method", "etfe", "--period", 256, "--band", "0.008:0.08", "--fs", 2, *_exps(recs),
        "-o", "etfe.json")
    _check(tmp_path / "etfe.json", "etfe.json")


def test_realisations(tmp_path):
    paths = realisation_bench(tmp_path, 2, 0.3, periods=3)
    run(tmp_path, "frf", "--design", "design0.json", "--realisations", 2, *_exps(_names(paths)), "--dft", "stream",
        "-o", "bla.json")
    _check(tmp_path / "bla.json", "bla.json")


def test_negative_control(tmp_path):
    # one changed byte must be told apart (the comparison above can fail)
    if WRITE:
        pytest.skip("writing golden files")
    src = (GOLDEN / "periodic.json").read_bytes()
    i = src.index(b'"dof"') + 8
    bad = tmp_path / "bad.json"
    bad.write_bytes(src[:i] + bytes([src[i] ^ 1]) + src[i + 1:])
    with pytest.raises(pytest.fail.Exception):
        _check(bad, "periodic.json")


def test_numbers_shortest_round_trip():
    """The writer prints every double with std::to_chars' shortest round-trip digits
    (msidfrf::dump; nlohmann's Grisu2 printed e.g. 2.9799461957317632e-06 for
    2.979946195731763e-06): each number token of every golden file has exactly the
    significant digits of Python's repr (the shortest that reads back to the same
    double), in nlohmann's layout (1.0, 0.001, 1e-05, 1.5e+20). The golden files
    were rewritten for this change (commit 'frffile: direct JSON text'), with every
    value bit-identical to the files before it. Negative control: a 17-digit
    token is told apart."""
    import re

    def digits(tok):
        m = tok.lstrip("-").split("e")[0].replace(".", "").lstrip("0").rstrip("0")
        return m or "0"

    def shortest(tok):
        v = float(tok)
        return digits(tok) == digits(repr(v)) and ("." in tok or "e" in tok)

    n = 0
    for f in sorted(GOLDEN.glob("*.json")):
        text = f.read_text()
        for tok in re.findall(r'(?<=[\s\[:])-?\d+\.\d+(?:e[+-]\d+)?|(?<=[\s\[:])-?\d+e[+-]\d+', text):
            assert shortest(tok), (f.name, tok)
            n += 1
    assert n > 10000
    assert not shortest("2.9799461957317632e-06")   # the Grisu2 text of the same double
