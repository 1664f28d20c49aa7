"""msid-frf/1 has one writer and one reader (tools/frffile): every document the
estimators write and every model fitted from one is byte-identical to the files the code
before that change wrote (commit 1fc65f9) for the same fixed seeds. The golden files in
golden/ were produced by that commit; MSID_GOLDEN_WRITE=1 rewrites them (only do that on
purpose, after a reviewed change of the format). The subspace models and their validations
(periodic-/direct-model.json, -validate.json) were rewritten on 2026-11-24 when subspace began to run
on noise-normalised channels (unit invariance): the same model FRF to 3e-11 and cost to
1e-13, another state basis (A, B, C are not unique), validate's numbers in the last digits.
The two model files were rewritten again on 2026-11-27 when stable models became the default of
subspace and ml: `settings.stability` ("stable (default)") added and `subspace.stable_mode` "auto"
renamed "default"; no number changed.

Covered writers: the periodic job (msid frf with detection lines, sample rate, a start-up
transient), the direct time-domain estimator (records cut to partial periods),
the LPM and the ETFE, the robust BLA (--realisations); the reader through msid fit and
msid validate on those files. The line DFT is pinned to the streaming path (--dft stream).
Negative control: a file that differs in one byte is told apart.

On another architecture (msid cross-built and run under qemu-user, MSID_EMULATOR) the periodic and
skip/drop documents (the streaming line DFT) must still equal x86-64's bytes; the LPM, ETFE and direct
estimators' documents hold every number within 1e-5 of the largest entry of its matrix and each G within
1e-5 of its standard deviation (measured on AArch64: the LPM's G moves by up to 1.5e-6 of its standard
deviation at weakly excited bins, whose local least squares is ill-conditioned), and the subspace models
their FRF and cost within 1e-6 (docs/target.md)."""
import json
import os
import shutil

import numpy as np
import pytest

import helpers as h
from test_modal_cli import realisation_bench

GOLDEN = h.HERE / "golden"
WRITE = os.environ.get("MSID_GOLDEN_WRITE") == "1"
# msid built for another architecture and run under qemu-user (scripts/cross_test.sh): the golden files hold
# x86-64's bytes; the streaming FRF must still equal them bit for bit, the C++ estimators' documents and the
# models within the tolerances of docs/target.md ("What must not depend on the architecture")
FOREIGN = bool(os.environ.get("MSID_EMULATOR"))
ARCH_TOL = 1e-5   # LPM, ETFE, the direct estimator: of each matrix's largest entry, G of its standard deviation
ARCH_MODEL_TOL = 1e-6   # a fitted model's FRF and cost (its state basis is not unique)


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    d = tmp_path_factory.mktemp("golden")
    bench = h.make_dt_bench(d, seed=5, periods=6)
    return {"dir": d, **bench}


def _matrix_scale(a):
    """The largest magnitude of a list of numbers or of lists of numbers (a vector or a matrix), else None."""
    flat = []
    for x in a:
        if isinstance(x, list):
            if not all(isinstance(y, (int, float)) and not isinstance(y, bool) for y in x):
                return None
            flat += x
        elif isinstance(x, (int, float)) and not isinstance(x, bool):
            flat.append(x)
        else:
            return None
    return max((abs(x) for x in flat), default=None)


def _close(a, b, tol, where="$", by_matrix=False, scale=0.0):
    """Same structure and strings, numbers within tol relative (None for null). by_matrix: relative to
    the largest entry of the vector or matrix a number belongs to (a covariance's near-zero entries are
    rounding residues of its large ones)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), f"{where}: keys {list(a)} vs {list(b)}"
        if by_matrix and list(a) == ["re", "im"]:   # a complex matrix: one scale for both parts
            parts = [_matrix_scale(x[k]) if isinstance(x[k], list) else None for x in (a, b) for k in ("re", "im")]
            if None not in parts:
                scale = max([scale] + parts)
        for k in a:
            _close(a[k], b[k], tol, f"{where}.{k}", by_matrix, scale)
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"{where}: lengths differ"
        if by_matrix and _matrix_scale(a) is not None and _matrix_scale(b) is not None:
            scale = max(scale, _matrix_scale(a), _matrix_scale(b))
        for i, (x, y) in enumerate(zip(a, b)):
            _close(x, y, tol, f"{where}[{i}]", by_matrix, scale)
    elif isinstance(a, (int, float)) and not isinstance(a, bool):
        assert isinstance(b, (int, float)) and abs(a - b) <= tol * max(abs(a), abs(b), scale), \
            f"{where}: {a!r} vs {b!r}"
    else:
        assert a == b, f"{where}: {a!r} vs {b!r}"


def _close_arch(got, want, tol):
    """Another architecture's estimator document against x86-64's: numbers within tol of the largest
    entry of their vector or matrix, and each line's G within tol of its own standard deviation where
    that is larger (at a weakly excited bin the local least squares is ill-conditioned: its rounding
    moves G by a fraction of the uncertainty the document states, not by a fraction of |G|)."""
    if isinstance(got, dict) and isinstance(want, dict) and isinstance(got.get("lines"), list) \
            and isinstance(want.get("lines"), list) and len(got["lines"]) == len(want["lines"]):
        for i, (a, b) in enumerate(zip(got["lines"], want["lines"])):
            if isinstance(a, dict) and isinstance(b, dict) and "G" in a and "G" in b and "cov" in b:
                var = [row[k] for k, row in enumerate(b["cov"]["re"])]
                sd = max(abs(v) for v in var) ** 0.5 if var else 0.0
                _close(a["G"], b["G"], tol, f"$.lines[{i}].G", by_matrix=True, scale=sd)
                a, b = {k: v for k, v in a.items() if k != "G"}, {k: v for k, v in b.items() if k != "G"}
            _close(a, b, tol, f"$.lines[{i}]", by_matrix=True)
        got = {k: v for k, v in got.items() if k != "lines"}
        want = {k: v for k, v in want.items() if k != "lines"}
    _close(got, want, tol, by_matrix=True)


def _check(path, name, fft_tol=0.0, arch_tol=0.0):
    """Byte-identical to golden/NAME. fft_tol > 0: a document whose numbers come through FFTW (or whose
    input records come through NumPy's FFT) may differ in the last bits on another CPU, whose SIMD
    codelets FFTW picks (FFTW_ESTIMATE is deterministic on one machine, not across machines): then
    the same structure and strings and every number within fft_tol relative is required instead.
    arch_tol > 0: on another architecture (msid under MSID_EMULATOR) a document of the C++ estimators
    (Eigen's kernels fuse multiply-adds on AArch64 and order sums otherwise than on x86-64's SSE2) holds
    every number within arch_tol of the largest entry of its vector or matrix (docs/target.md)."""
    got = path.read_bytes()
    ref = GOLDEN / name
    if WRITE:
        GOLDEN.mkdir(exist_ok=True)
        shutil.copyfile(path, ref)
        return
    want = ref.read_bytes()
    if got != want and FOREIGN and arch_tol > 0:
        _close_arch(json.loads(got), json.loads(want), arch_tol)
        return
    if got != want and fft_tol > 0:
        _close(json.loads(got), json.loads(want), fft_tol)
        return
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


def _fit_and_validate(d, frf, stem, order=4, fft_tol=0.0):
    model = f"{stem}-model.json"
    run(d, "fit", "--method", "subspace", "--order", order, frf, "-o", model)
    tol = fft_tol if fft_tol > 0 else (ARCH_MODEL_TOL if FOREIGN else 0.0)
    if tol > 0 and not WRITE and (d / model).read_bytes() != (GOLDEN / model).read_bytes():
        # last-bit differences of the FRF (or of the fit's own arithmetic on another CPU) move the
        # state-space basis (A, B, C are not unique): the same keys, and the model's FRF and cost within tol
        got, want = json.loads((d / model).read_text()), json.loads((GOLDEN / model).read_text())
        assert list(got) == list(want), f"{model}: keys {list(got)} vs {list(want)}"
        for k in ("frf", "cost", "order", "domain"):
            _close(got[k], want[k], tol, f"{model}:{k}", by_matrix=FOREIGN)
    else:
        _check(d / model, model)
    val = f"{stem}-validate.json"
    run(d, "validate", model, frf, "-o", val)
    _check(d / val, val, fft_tol, arch_tol=ARCH_TOL)


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
    _check(tmp_path / "direct.json", "direct.json", fft_tol=1e-10, arch_tol=ARCH_TOL)
    _fit_and_validate(tmp_path, "direct.json", "direct", fft_tol=1e-6)


def test_lpm(work):
    run(work["dir"], "frf", "--method", "lpm", "--band", "0.01:0.03", *_exps(_names(work["experiments"])),
        "-o", "lpm.json")
    _check(work["dir"] / "lpm.json", "lpm.json", arch_tol=ARCH_TOL)


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
    _check(tmp_path / "etfe.json", "etfe.json", arch_tol=ARCH_TOL)


def test_realisations(tmp_path):
    paths = realisation_bench(tmp_path, 2, 0.3, periods=3)
    run(tmp_path, "frf", "--design", "design0.json", "--realisations", 2, *_exps(_names(paths)), "--dft", "stream",
        "-o", "bla.json")
    _check(tmp_path / "bla.json", "bla.json", fft_tol=1e-10)


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
    # the tolerant comparison of FFTW documents: a number off by 1e-6 relative is told apart
    doc = json.loads((GOLDEN / "direct.json").read_text())
    doc["lines"][0]["G"]["re"][0][0] *= 1 + 1e-6
    bad.write_text(json.dumps(doc, indent=1))
    with pytest.raises(AssertionError):
        _check(bad, "direct.json", fft_tol=1e-10)
    # the comparison of another architecture's documents, relative to each matrix's largest entry: a
    # covariance entry moved by 1e-4 of its matrix's largest is told apart, a rounding residue is not
    doc = json.loads((GOLDEN / "lpm.json").read_text())
    cov = doc["lines"][0]["cov"]["re"]
    top = max(abs(x) for row in cov for x in row)
    cov[0][1] += 1e-4 * top
    with pytest.raises(AssertionError):
        _close(doc, json.loads((GOLDEN / "lpm.json").read_text()), ARCH_TOL, by_matrix=True)
    cov[0][1] -= 1e-4 * top - 1e-9 * top
    _close(doc, json.loads((GOLDEN / "lpm.json").read_text()), ARCH_TOL, by_matrix=True)


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
