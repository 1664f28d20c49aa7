"""`msid frf` on CSV records streams them through the core block by block (estimate_frf_files,
docs/records.md, docs/reliability.md): the document is the same bits as from the same samples read whole (a
.npy file, which takes the whole-record path), every problem gets the same message, and peak memory
does not grow with the samples.

Peak RSS is msid's own ru_maxrss (peak_rss_run.c): memory, not time, so a busy machine does not move
it. The negative control is the whole-record path on the same samples, which must exceed the bound."""
import os
import subprocess

import numpy as np
import pytest
from scipy.signal import lfilter

import helpers as h

# ASan (MSID_SANITIZED) or qemu-user (MSID_EMULATOR): the process's RSS is not msid's
SANITIZED = os.environ.get("MSID_SANITIZED") == "1" or bool(os.environ.get("MSID_EMULATOR"))
P = 1000
BINS = "1:7:300"            # 43 lines
FMT = "%.17g"               # every double written exactly: the CSV and the .npy hold the same samples


def _plant_rows(periods, seed, nu=1, ny=1, extra=0):
    """`periods` periods (+ `extra` samples) of a random-phase multisine per input through a first-order
    filter per output, with white noise: rows of [u.., y..]."""
    rng = np.random.default_rng(seed)
    n = np.arange(P)
    bins = np.arange(1, 300, 7)
    N = periods * P + extra
    cols = []
    for j in range(nu):
        ph = rng.uniform(0, 2 * np.pi, bins.size)
        u1 = np.cos(2 * np.pi * np.outer(n, bins) / P + ph).sum(axis=1) / np.sqrt(bins.size)
        cols.append(u1[np.arange(N) % P])
    u = np.column_stack(cols)
    ys = []
    for i in range(ny):
        a = 0.8 + 0.05 * i
        y = lfilter([1 - a], [1, -a], u.sum(axis=1) * (1 + 0.5 * i))   # y[t] = a y[t-1] + (1-a) x[t]
        ys.append(y + 0.01 * rng.standard_normal(N))
    return np.column_stack([u] + ys)


def _write(d, name, rows, nu, ny):
    hdr = ",".join([f"u{j+1}" for j in range(nu)] + [f"y{i+1}" for i in range(ny)])
    np.savetxt(d / f"{name}.csv", rows, delimiter=",", fmt=FMT, header=hdr, comments="")
    np.save(d / f"{name}.npy", rows)
    return d / f"{name}.csv", d / f"{name}.npy"


def _same_doc(a, b):
    """The two documents agree in every member, the sources' names aside."""
    a, b = dict(a), dict(b)
    ea, eb = a.pop("experiments"), b.pop("experiments")
    assert a == b
    for x, y in zip(ea, eb):
        x, y = dict(x), dict(y)
        x.pop("source")
        y.pop("source")
        assert x == y


def _mimo_csv_and_npy(tmp_path, args, seed):
    """`msid frf args` on 2 experiments of 2 inputs and 2 outputs (130 periods and 321 samples each),
    written as CSV (streamed) and as .npy (read whole): the two runs, after checking that their
    documents are the same bits; returns (CSV run, .npy run, CSV document)."""
    csv, npy = [], []
    for e in range(2):
        rows = _plant_rows(130, seed=seed + e, nu=2, ny=2, extra=321)
        c, n = _write(tmp_path, f"e{e+1}", rows, 2, 2)
        csv.append(c)
        npy.append(n)
    a = ["--experiment"] * 2
    r1 = h.run_ok("frf", *args, *[x for p in zip(a, csv) for x in p], "-o", tmp_path / "s.json")
    r2 = h.run_ok("frf", *args, *[x for p in zip(a, npy) for x in p], "--columns", "u1=1,u2=2,y1=3,y2=4",
                  "-o", tmp_path / "w.json")
    s = h.load_json(tmp_path / "s.json")
    _same_doc(s, h.load_json(tmp_path / "w.json"))
    return r1, r2, s


@pytest.mark.parametrize("block", [None, 777])
def test_streamed_csv_is_the_whole_record_bits_mimo(tmp_path, block):
    """2 inputs, 2 outputs, 2 experiments (two lanes), ~12 MB of CSV each (several 4 MiB blocks and
    a partial period at the end), detection lines, optional --block: the same document as the .npy."""
    args = ["--period", P, "--lines", BINS, "--skip-periods", 1, "--detect-lines", "2,4,6"]
    if block:
        args += ["--block", block]
    r1, r2, _ = _mimo_csv_and_npy(tmp_path, args, seed=10)
    assert "321 samples after the last whole period are not used" in r1.stderr
    assert r1.stderr.replace(".csv", "") == r2.stderr.replace(".npy", "")


def _same_run(r1, r2, ext1, ext2):
    """The two runs printed the same, the files' extensions and the output's name aside."""
    def out(r, ext):
        return [x.replace(ext, "") for x in r.stdout.splitlines() if not x.startswith("wrote ")]
    assert out(r1, ext1) == out(r2, ext2)
    assert r1.stderr.replace(ext1, "") == r2.stderr.replace(ext2, "")


def test_streamed_period_and_lines_auto_are_the_whole_record_bits_mimo(tmp_path):
    """--period auto --lines auto on 2 inputs, 2 outputs, 2 experiments with a skipped period: the CSV
    files stream (the period from the first file's first rows, the lines from a pass of their own over
    every file) and give the .npy's document and reports."""
    r1, r2, s = _mimo_csv_and_npy(tmp_path, ["--period", "auto", "--lines", "auto", "--skip-periods", 1], seed=20)
    _same_run(r1, r2, ".csv", ".npy")
    assert f"--period auto: period {P} samples" in r1.stdout
    assert s["lines_auto"]["found"] == 43 and s["lines_auto"]["undecided_bins"] == []


def test_streamed_lines_auto_from_the_reference_column(tmp_path):
    """An input with noise 0 dB below its multisine and the excitation's reference r1 in the file: the
    streamed CSV takes the lines from its own r1 column, a stream of its own; the .npy (read whole) is
    given the same column by --reference: the same lines and document."""
    rng = np.random.default_rng(31)
    rows = _plant_rows(40, seed=31)
    ref = rows[:, 0].copy()
    rows[:, 0] += rng.standard_normal(ref.size)
    rows = np.column_stack([rows, ref])
    np.savetxt(tmp_path / "r.csv", rows, delimiter=",", fmt=FMT, header="u1,y1,r1", comments="")
    np.save(tmp_path / "r.npy", rows)
    args = ["--period", P, "--lines", "auto"]
    r1 = h.run_ok("frf", *args, "--experiment", tmp_path / "r.csv", "-o", tmp_path / "s.json")
    r2 = h.run_ok("frf", *args, "--experiment", tmp_path / "r.npy", "--columns", "u1=1,y1=2", "--reference", "r1=3",
                  "-o", tmp_path / "w.json")
    s, w = h.load_json(tmp_path / "s.json"), h.load_json(tmp_path / "w.json")
    assert s["lines_auto"].pop("from") == "the reference r1=r1" and w["lines_auto"].pop("from") == "the reference r1=3"
    _same_doc(s, w)
    assert s["lines_auto"]["found"] == 43 and "of the reference" in r1.stdout


def _peak(tmp_path, *args):
    runner = os.environ.get("MSID_PEAK_RSS_RUN")
    if not runner:
        pytest.skip("set MSID_PEAK_RSS_RUN to tests/integration/peak_rss_run (ctest does this)")
    rss = tmp_path / "peak_kb"
    r = subprocess.run([runner, str(rss), h.msid_bin(), *map(str, args)], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    return int(rss.read_text())


@pytest.mark.skipif(SANITIZED, reason="the process's RSS is not msid's (ASan's shadow memory, or qemu-user)")
def test_peak_memory_does_not_grow_with_the_record(tmp_path):
    """A 3,000-period SISO record (3e6 rows: 46 MiB of doubles, 40 MB of CSV): streamed, msid's peak RSS
    stays under 40 MB (the binary, one 4 MiB window, the blocks and the transient test's 3,000 x 43 x 2
    spectra; 39 MiB was measured for a 10 M-row file); so does a .npy read in place from its mapping
    (the pages pushed go back to the kernel); the same samples read whole from a .npz need more than the
    samples (the control); the three documents are the same bits."""
    one = _plant_rows(100, seed=3)
    text = "".join(f"{a:.6g},{b:.6g}\n" for a, b in one)
    path = tmp_path / "long.csv"
    with open(path, "w") as f:
        f.write("u1,y1\n")
        for _ in range(30):
            f.write(text)
    args = ("frf", "--period", P, "--lines", BINS, "--experiment")
    streamed = _peak(tmp_path, *args, path, "-o", tmp_path / "s.json")
    assert streamed < 40 * 1024, f"streamed: {streamed} kB"
    doc = h.load_json(tmp_path / "s.json")
    assert doc["experiments"][0]["samples"] == 3_000_000
    samples = np.loadtxt(path, delimiter=",", skiprows=1)
    # a .npy read in place from its mapping: the pages pushed through the core are given back
    np.save(tmp_path / "long.npy", samples)
    mapped = _peak(tmp_path, *args, tmp_path / "long.npy", "--columns", "u1=1,y1=2", "-o", tmp_path / "m.json")
    assert mapped < 40 * 1024, f"mapped .npy: {mapped} kB"
    _same_doc(doc, h.load_json(tmp_path / "m.json"))
    # the control: the same samples from a .npz, read whole into memory
    np.savez(tmp_path / "long.npz", x=samples)
    whole = _peak(tmp_path, *args, tmp_path / "long.npz", "--columns", "u1=x:1,y1=x:2", "-o", tmp_path / "w.json")
    assert whole > 46 * 1024, f"whole: {whole} kB (the control must see the 45.8 MiB of samples)"
    w = h.load_json(tmp_path / "w.json")
    assert w.pop("input_names") == ["x:1"] and w.pop("output_names") == ["x:2"]   # named by --columns
    _same_doc(doc, w)


@pytest.mark.skipif(SANITIZED, reason="the process's RSS is not msid's (ASan's shadow memory, or qemu-user)")
def test_peak_memory_of_period_and_lines_auto(tmp_path):
    """A 2,300-period record (2.3e6 rows, 35 MiB of doubles), longer than --period auto's search
    (PERIOD_SEARCH_ROWS = 2^21 rows), input noise that never repeats:
    - --lines auto with a given period streams twice (the lines' pass, then the FRF's): under 40 MB
      as a given period and lines (measured: 27 MB); the same samples read whole from a .npz need more
      (the control, 78 MB);
    - --period auto too: the period from the inputs of the first 2^21 rows, whatever the record's
      length, under 100 MB (measured: 78 MB: those rows' inputs, an FFT
      of 3 * 2^20 points and FFTW's twiddle factors);
    - both give the documents of the .npy read in place."""
    rng = np.random.default_rng(17)
    K = 2300
    one = _plant_rows(1, seed=17)[:, 0]
    u = np.tile(one, K) + 0.1 * rng.standard_normal(K * P)
    y = lfilter([0.2], [1, -0.8], u) + 0.01 * rng.standard_normal(u.size)
    rows = np.column_stack([u, y])
    path = tmp_path / "long.csv"
    np.savetxt(path, rows, delimiter=",", fmt="%.9g", header="u1,y1", comments="")
    np.save(tmp_path / "long.npy", np.loadtxt(path, delimiter=",", skiprows=1))
    npy = ("--experiment", tmp_path / "long.npy", "--columns", "u1=1,y1=2")
    given = ("frf", "--period", P, "--lines", "auto")
    lines = _peak(tmp_path, *given, "--experiment", path, "-o", tmp_path / "l.json")
    assert lines < 40 * 1024, f"--lines auto streamed: {lines} kB"
    h.run_ok(*given, *npy, "-o", tmp_path / "lw.json")
    _same_doc(h.load_json(tmp_path / "l.json"), h.load_json(tmp_path / "lw.json"))
    np.savez(tmp_path / "long.npz", x=rows)
    whole = _peak(tmp_path, *given, "--experiment", tmp_path / "long.npz", "--columns", "u1=x:1,y1=x:2",
                  "-o", tmp_path / "w.json")
    assert whole > 40 * 1024, f"whole: {whole} kB (the control must see the 35 MiB of samples)"
    auto = ("frf", "--period", "auto", "--lines", "auto")
    both = _peak(tmp_path, *auto, "--experiment", path, "-o", tmp_path / "a.json")
    assert both < 100 * 1000, f"--period auto --lines auto streamed: {both} kB"
    r = h.run_ok(*auto, *npy, "-o", tmp_path / "aw.json")
    assert f"period {P} samples" in r.stdout and f"in the first {2**21} rows of" in r.stdout
    a = h.load_json(tmp_path / "a.json")
    _same_doc(a, h.load_json(tmp_path / "aw.json"))
    assert a["lines_auto"]["found"] == 43 and a["experiments"][0]["samples"] == K * P


def _long_bad(tmp_path, name, bad_row, cell=None, blank=False):
    rows = _plant_rows(60, seed=5)
    lines = [f"{a!r},{b!r}" for a, b in rows.tolist()]
    if cell is not None:
        lines[bad_row] = cell
    if blank:
        lines.insert(bad_row, "")
    p = tmp_path / name
    p.write_text("u1,y1\n" + "\n".join(lines) + "\n")
    return p


@pytest.mark.parametrize("auto", ["", "lines", "both"])
@pytest.mark.parametrize("what", ["cell", "blank"])
def test_a_problem_deep_in_a_streamed_file_is_named_and_nothing_written(tmp_path, what, auto):
    """A bad cell or an empty line at row 50,000 (far beyond the first block and the input checks'
    rows), with the lines given, --lines auto (its own pass meets it) or --period auto too: one
    message naming the line, exit 1, no output; the message is the reader's (read_record_csv)."""
    p = _long_bad(tmp_path, "bad.csv", 50_000, cell="0.5,x1" if what == "cell" else None, blank=what == "blank")
    out = tmp_path / "frf.json"
    how = {"": ("--period", P, "--lines", BINS), "lines": ("--period", P, "--lines", "auto"),
           "both": ("--period", "auto", "--lines", "auto")}[auto]
    r = h.run("frf", *how, "--experiment", p, "-o", out)
    assert r.returncode == 1 and not out.exists()
    line = 50_002   # the header, then rows from line 2
    want = (f"'{p}' line {line}, column y1: 'x1' is not a number" if what == "cell"
            else f"'{p}' line {line}: empty line inside the data")
    assert want in r.stderr, r.stderr
    assert r.stderr.count("error") == 1


def test_a_long_record_whose_input_is_not_periodic_is_read_whole_for_the_message(tmp_path):
    """Noise through the input of a 60-period record (beyond the rows the input checks read): the whole
    record is read to search its period, and the message is the one the .npy gets."""
    rng = np.random.default_rng(9)
    rows = np.column_stack([rng.standard_normal(60 * P), rng.standard_normal(60 * P)])
    c, n = _write(tmp_path, "noise", rows, 1, 1)
    r1 = h.run("frf", "--period", P, "--lines", BINS, "--experiment", c, "-o", tmp_path / "a.json")
    r2 = h.run("frf", "--period", P, "--lines", BINS, "--experiment", n, "--columns", "u1=1,y1=2",
               "-o", tmp_path / "b.json")
    assert r1.returncode == r2.returncode == 1
    assert "is not periodic" in r1.stderr
    assert r1.stderr.replace(".csv", "") == r2.stderr.replace(".npy", "")
