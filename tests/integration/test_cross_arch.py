"""Results that must not depend on the architecture (docs/target.md "Linux bench controller"): the same
test runs on x86-64 (ctest), and on aarch64 and armhf under qemu-user (scripts/cross_test.sh), against
the one golden file golden/cross_arch.json written on x86-64:
  * excitation designs and sample CSVs byte for byte (random and Schroeder phases, DFT and Hadamard
    patterns, bins and continuous-time lines);
  * the FRF of the streaming line DFT byte for byte (lib/ adds each term in sample order with no
    fused multiply-add, and prints with the same digits);
  * the FRF of the FFT path (FFTW picks other codelets on another CPU) within 1e-12 of each array's
    largest magnitude (G, each covariance matrix, ...).
The input records are simulated by NumPy on the machine that runs pytest, so they are the same bytes
for every architecture under test. MSID_GOLDEN_WRITE=1 rewrites the golden file (on x86-64 only, after a
reviewed change of what msid writes). Negative control: a one-byte change is told apart."""
import hashlib
import json
import os

import pytest

import helpers as h
from test_frf_golden import _close

GOLDEN = h.HERE / "golden" / "cross_arch.json"
WRITE = os.environ.get("MSID_GOLDEN_WRITE") == "1"

EXCITE = {
    "random-dft": ["--period", 256, "--lines", "1:2:41", "--inputs", 2, "--experiments", 2, "--seed", 11,
                   "--periods", 2],
    "schroeder-hadamard": ["--period", 1000, "--lines", "0,3,5:5:200,499", "--amplitudes", 0.5,
                           "--phases", "schroeder", "--inputs", 3, "--experiments", 4, "--pattern", "hadamard",
                           "--periods", 1],
    "omega": ["--period", 500, "--omega", "6.283185307179586,31.41592653589793,125.66370614359172",
              "--sample-time", 0.002, "--seed", 3, "--periods", 1],
}


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def golden():
    if WRITE:
        doc = {}
        yield doc
        GOLDEN.write_text(json.dumps(doc, indent=1) + "\n")
    else:
        yield json.loads(GOLDEN.read_text())


@pytest.mark.parametrize("name", sorted(EXCITE))
def test_excitation_bytes(golden, tmp_path, name):
    h.run_ok("excite", *EXCITE[name], "-o", "design.json", "--csv", "gen", cwd=tmp_path)
    files = ["design.json"] + sorted(f"gen/{p.name}" for p in (tmp_path / "gen").iterdir())
    got = {f"excite/{name}/{f}": _sha(tmp_path / f) for f in files}
    if WRITE:
        golden.update(got)
        return
    want = {k: v for k, v in golden.items() if k.startswith(f"excite/{name}/")}
    assert sorted(got) == sorted(want), f"files {sorted(got)} vs {sorted(want)}"
    bad = [k for k in got if got[k] != want[k]]
    assert not bad, f"differ from the x86-64 bytes: {bad}"


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    d = tmp_path_factory.mktemp("cross")
    h.make_dt_bench(d, seed=3, periods=4)
    return d


def _frf(d, dft, out):
    h.run_ok("frf", "--design", "design.json", "--experiment", "e1.csv", "--experiment", "e2.csv",
             "--dft", dft, "-o", out, cwd=d)
    return d / out


def test_frf_stream_bytes(golden, bench):
    got = _sha(_frf(bench, "stream", "stream.json"))
    if WRITE:
        golden["frf/stream.json"] = got
        return
    assert got == golden["frf/stream.json"], "the streaming FRF differs from the x86-64 bytes"


def _numeric(x):
    return isinstance(x, list) and all(_numeric(v) if isinstance(v, list) else
                                       isinstance(v, (int, float)) and not isinstance(v, bool) for v in x)


def _flat(x):
    return [w for v in x for w in (_flat(v) if isinstance(v, list) else [v])]


def _close_normwise(a, b, tol, where="$"):
    """Same structure and strings; each numeric array (a vector or matrix: G, a covariance, ...) within
    tol of the largest magnitude in it, |a - b| <= tol * max|b|: an element that is a small difference of
    large terms (an off-diagonal covariance) carries the rounding of those terms, not of itself."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), f"{where}: keys {list(a)} vs {list(b)}"
        for k in a:
            _close_normwise(a[k], b[k], tol, f"{where}.{k}")
    elif _numeric(a) and a:
        fa, fb = _flat(a), _flat(b) if isinstance(b, list) else None
        assert fb is not None and len(fa) == len(fb), f"{where}: shapes differ"
        scale = max(abs(v) for v in fb)
        err = max(abs(x - y) for x, y in zip(fa, fb))
        assert err <= tol * scale, f"{where}: max difference {err:.3g} > {tol:g} * {scale:.3g}"
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"{where}: lengths differ"
        for i, (x, y) in enumerate(zip(a, b)):
            _close_normwise(x, y, tol, f"{where}[{i}]")
    else:
        _close(a, b, tol, where)


def test_frf_fft_within_1e12(golden, bench):
    doc = json.loads(_frf(bench, "fft", "fft.json").read_text())
    if WRITE:
        golden["frf/fft.json"] = doc
        return
    _close_normwise(doc, golden["frf/fft.json"], 1e-12)


def test_negative_control(golden, bench, tmp_path):
    """One changed digit in the streaming FRF: the hash and the 1e-12 comparison both tell it apart."""
    if WRITE:
        pytest.skip("writing the golden file")
    text = (bench / "stream.json").read_text()
    k = text.index('"re"') + 10
    while not text[k].isdigit():
        k += 1
    bad = text[:k] + ("1" if text[k] != "1" else "2") + text[k + 1:]
    p = tmp_path / "bad.json"
    p.write_text(bad)
    assert _sha(p) != golden["frf/stream.json"]
    with pytest.raises(AssertionError):
        _close_normwise(json.loads(bad), json.loads(text), 1e-12)
