"""Every experiment-file reader is bounded by its file's size: small crafted files whose sizes claim
gigabytes to terabytes (tests/fuzz/hostile_files.py: compressed and uncompressed .mat v5, v7.3/HDF5
(datasets never written, a reference to an object no link names),
.npz, .npy, CSV) each give one message naming the file, a non-zero exit, nothing on stdout, and a peak
RSS of a few MB through `msid frf`. Peak RSS is msid's own ru_maxrss (wait4, in peak_rss_run.c), a
bound of 64 MB that a busy machine does not move (it is memory, not time). Negative control: the same measurement of
a legitimate .npz whose 130 KB inflate to 64 MB sees more than the bound, so the bound would catch a
reader that allocated what a hostile file claims."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import helpers as h

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fuzz"))
import hostile_files as hf  # noqa: E402

LIMIT_KB = 64 * 1024
# a sanitizer build (MSID_SANITIZED=1, scripts/sanitize.sh) or a cross build under qemu-user (MSID_EMULATOR,
# whose process's RSS is the emulator's): the messages, the exit and the absent output are checked, not the RSS
SANITIZED = os.environ.get("MSID_SANITIZED") == "1" or bool(os.environ.get("MSID_EMULATOR"))


def _frf(path, command="frf"):
    """`msid frf` on one experiment file (command "import": `msid import` of an FRF file), writing next
    to it: (exit code, stdout, stderr, peak RSS in kB); a failure must leave no output file. Run through
    peak_rss_run (MSID_PEAK_RSS_RUN): a child forked from this process would start with pytest's RSS as
    its high-water mark."""
    out_json = path.parent / "frf.json"
    rss_file = path.parent / "peak_rss_kb"
    runner = os.environ.get("MSID_PEAK_RSS_RUN")
    if not runner:
        pytest.skip("set MSID_PEAK_RSS_RUN to tests/integration/peak_rss_run (ctest does this)")
    args = ["frf", "--period", "64", "--lines", "1,3", "--experiment", str(path)] if command == "frf" \
        else [command, str(path)]
    emulated = bool(os.environ.get("MSID_EMULATOR"))   # the launcher is the target's: msid alone, RSS 0
    r = subprocess.run(([] if emulated else [runner, str(rss_file)]) + [h.msid_bin()] + args + ["-o", str(out_json)],
                       capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        assert not out_json.exists(), f"{path.name}: an output was written"
    return r.returncode, r.stdout, r.stderr, 0 if emulated else int(rss_file.read_text())


# (file name in hostile_files.FILES, what the one message must say); {f} is the file's path
EXPECTED = {
    # libmatio asked for malloc(3,187,802,121) here (the out-of-memory the readers are bounded against); msid's v5 reader
    # never reads inside a cell: the variable is skipped as not numeric
    "regress-mat-v5-cell-name-3g": "'{f}' holds no real numeric vectors or matrices (skipped: c)",
    "regress-mat-v5-nested-cell-count": "'{f}' holds no real numeric vectors or matrices (skipped: c)",
    "regress-mat-v5-uncompressed-nested-cell": "'{f}' holds no real numeric vectors or matrices (skipped: c)",
    "regress-mat-v5-struct-field-names": "'{f}' holds no real numeric vectors or matrices (skipped: s)",
    "regress-mat-v5-double-claims": "'{f}' variable 'u1' claims 40000 x 40000 values (12800000000 bytes) but the "
                                    "file can hold at most 8 bytes of it",
    "regress-mat-v5-matrix-beyond-ratio": "'{f}' is not a MATLAB .mat file or is corrupt: variable 1 claims "
                                          "4294967295 bytes, more than its",
    "regress-npy-shape-claims": "'{f}': truncated: the header says 2147483648 x 2 <f8 (34359738368 bytes of data) "
                                "but 16 are there",
    "regress-npz-two-entries-one-member": "'{f}': corrupt zip: its members claim",
    "npz-overlapping-members-2g": "'{f}': corrupt zip: its members claim",
    "regress-npz-member-size-lies": "'{f}' variable 'u1': corrupt zip member: it claims 3221225472 bytes inflated",
    "csv-long-cell": "'{f}' line 2, column y1: '9999999999999999999999999999999999999999... (2000000 characters)' "
                     "is not a number",
}
FILES = {name: (suffix, make) for name, suffix, _, make in hf.FILES}


def _assert_bounded(path, phrase, claimed, command="frf"):
    rc, out, err, rss = _frf(path, command)
    assert rc != 0 and out == "", f"{path.name}: exit {rc}, stdout {out!r}"
    lines = err.strip().splitlines()
    assert len(lines) == 1, f"{path.name}: not one message: {err!r}"
    assert phrase.format(f=path) in lines[0], f"{path.name}: {lines[0]!r}"
    assert SANITIZED or rss < LIMIT_KB, f"{path.name}: peak RSS {rss} kB (claimed {claimed} bytes)"
    # the file claims far more than the bound: a reader that allocated it would fail the check
    assert claimed > 8 * LIMIT_KB * 1024 or path.suffix == ".csv" or "two-entries" in path.name, claimed
    return rss


def test_hostile_files_are_one_message_in_a_few_mb(tmp_path):
    assert set(EXPECTED) == set(FILES), "every crafted file has its expected message"
    corpus = Path(__file__).resolve().parents[1] / "fuzz" / "corpus" / "fuzz_files"
    for name, _, sel, make in hf.FILES:   # the fuzz seeds are these files (python3 hostile_files.py writes them)
        if name.startswith("regress-"):
            assert (corpus / name).read_bytes() == bytes([sel]) + make()[0], f"seed {name} differs from its maker"
    rss = {}
    for name, (suffix, make) in FILES.items():
        data, claimed = make()
        p = tmp_path / (name + suffix)
        p.write_bytes(data)
        rss[name] = _assert_bounded(p, EXPECTED[name], claimed)
    print({k: f"{v} kB" for k, v in rss.items()})


@pytest.mark.parametrize("kind", ["double", "cell"])
def test_mat_v73_dataset_claiming_more_than_the_file(tmp_path, kind):
    """A v7.3 dataset (chunked, never written: HDF5 reads it as fill values) claiming 8 TiB of doubles
    or 32 GiB of cell references: checked through HDF5 before libmatio lists or reads it."""
    pytest.importorskip("h5py")
    p = tmp_path / f"huge-{kind}.mat"
    claimed = hf.mat_v73_huge(p, kind)
    name = "u1" if kind == "double" else "c"
    assert p.stat().st_size < 64 * 1024
    _assert_bounded(p, f"'{{f}}' variable '{name}' claims {claimed} bytes, more than 1032 x the file's", claimed)


def test_mat_v73_reference_to_an_unlinked_object(tmp_path):
    """A v7.3 cell whose reference points at a dataset no link names (32 GiB of references): the check
    follows references as libmatio does; the message names the variable that refers to it."""
    pytest.importorskip("h5py")
    p = tmp_path / "unlinked.mat"
    claimed = hf.mat_v73_unlinked_cell(p)
    if claimed is None:
        pytest.skip("h5py's HDF5 library cannot be called to keep an unlinked object")
    _assert_bounded(p, f"'{{f}}' variable 'c' refers to an object that claims {claimed} bytes, more than 1032 x", claimed)



def test_mat_v73_cell_of_more_references_than_the_file_holds(tmp_path):
    """A v7.3 cell of 2^21 references to one object, compressed into about 40 kB: libmatio's listing
    grows with the references (424 bytes each, measured: 3.5 GB for 2^23), so their number is bounded
    by the file's size / 8; a cell of a few references passes."""
    pytest.importorskip("h5py")
    p = tmp_path / "many-refs.mat"
    size = hf.mat_v73_many_references(p, count=1 << 21)
    assert size < 64 * 1024
    _assert_bounded(p, "'{f}' variable 'c' holds 2097152 cell elements (object references", 424 << 21)
    # the same cell with 4 elements to one object: within the bound, read past (not numeric)
    ok = tmp_path / "few-refs.mat"
    hf.mat_v73_many_references(ok, count=4)
    r = h.run("frf", "--period", 10, "--lines", 1, "--experiment", ok, "-o", tmp_path / "o.json")
    assert "cell elements" not in r.stderr and "no power at line 1" in r.stderr, r.stderr

def test_idfrd_mat73_claiming_more_than_the_file(tmp_path):
    """`msid import` of an idfrd-shaped v7.3 file whose ResponseData (complex, chunked, never written)
    claims 16 TiB: refused by the HDF5 check before libmatio reads a variable, in a few MB."""
    pytest.importorskip("h5py")
    p = tmp_path / "huge-idfrd.mat"
    claimed = hf.mat_v73_idfrd_huge(p)
    assert p.stat().st_size < 64 * 1024
    _assert_bounded(p, f"'{{f}}' variable 'ResponseData' claims {claimed} bytes, more than 1032 x the file's", claimed,
                    "import")


def test_negative_control_the_bound_sees_a_large_allocation(tmp_path):
    """A legitimate .npz: two deflated members of 4,194,304 float64 each (32 MiB apiece, 130 KB of file).
    msid must inflate them: the measured peak RSS is above the bound, so the bound can fail."""
    if SANITIZED:
        pytest.skip("RSS is not checked under the sanitizers or qemu-user")
    p = tmp_path / "large.npz"
    n = 1 << 22
    np.savez_compressed(p, u1=np.zeros(n), y1=np.zeros(n))
    assert p.stat().st_size < 200 * 1024
    rc, out, err, rss = _frf(p)
    assert rss > LIMIT_KB, f"peak RSS {rss} kB: the measurement does not see a 64 MiB allocation"
