"""One exception type per kind of fault, with the file named. Before the fix a
binary or Latin-1 file gave a raw UnicodeDecodeError or an empty ValueError; a missing, unreadable or
directory path was a FormatError/ValueError in read_frf, read_model, import_frf, export and
fit(start=...); a truncated JSON file in fit, validate or modes was "RuntimeError: internal error";
an empty block or DataFrame an internal error; a seed of -1 or 2**70 a pybind11 signature dump and
seed=1.7 silently truncated."""
import os

import numpy as np
import pytest

import msid
from child import small_frf

P, LINES = 64, "1:3:20"


def test_binary_and_latin1_files_name_the_file(tmp_path):
    npy = tmp_path / "rec.npy"
    np.save(npy, np.arange(6.0).reshape(3, 2))
    with pytest.raises(ValueError, match="rec.npy' is not an msid-frf/1 file: byte 0x93 at offset 0") as e:
        msid.read_frf(npy)
    assert not isinstance(e.value, UnicodeDecodeError)
    with pytest.raises(ValueError, match="rec.npy' is not an msid-model/1 file") as e:
        msid.read_model(npy)
    assert not isinstance(e.value, UnicodeDecodeError)
    with pytest.raises(ValueError, match="rec.npy' line 1") as e:   # read as another tool's CSV, as msid fit reads it
        msid.fit(str(npy), method="ml", order=2)
    assert not isinstance(e.value, UnicodeDecodeError)
    bad = tmp_path / "bad8.csv"
    bad.write_bytes(b"u1,y1\n1.0,2\xb0C\n" + b"".join(b"%d,%d\n" % (k, k) for k in range(P * 4)))
    with pytest.raises(ValueError) as e:
        msid.frf(str(bad), period=P, lines=LINES)
    text = str(e.value)
    assert not isinstance(e.value, UnicodeDecodeError)
    assert "bad8.csv' line 2, column y1" in text and "is not a number" in text and "\\xb0" in text, text


def test_paths_that_cannot_be_read_are_oserrors(tmp_path):
    d, rec, f = small_frf(P, LINES)
    missing, folder = tmp_path / "missing.json", tmp_path / "folder.json"
    folder.mkdir()
    for p in (missing, folder):
        for call in (msid.read_frf, msid.read_model, msid.import_frf, msid.read_design):
            with pytest.raises(OSError, match=os.path.basename(p)):
                call(p)
        with pytest.raises(OSError, match=os.path.basename(p)):
            msid.export(p, tmp_path / "out.csv")
        with pytest.raises(OSError, match=os.path.basename(p)):
            msid.fit(f, method="ml", order=2, start=str(p))
        with pytest.raises(OSError, match=os.path.basename(p)):
            msid.fit(p, method="ml", order=2)
    assert not (tmp_path / "out.csv").exists()


def test_truncated_json_is_a_valueerror_naming_the_file(tmp_path):
    d, rec, f = small_frf(P, LINES)
    msid.write_frf(tmp_path / "frf.json", f)
    m = msid.fit(f, method="ml", order=2)
    msid.write_model(tmp_path / "model.json", m)
    for name in ("frf.json", "model.json"):
        text = (tmp_path / name).read_text()
        (tmp_path / ("cut_" + name)).write_text(text[: len(text) // 2])
    cut_frf, cut_model = tmp_path / "cut_frf.json", tmp_path / "cut_model.json"
    with pytest.raises(ValueError, match="cut_frf.json' is not valid JSON"):
        msid.fit(cut_frf, method="ml", order=2)
    with pytest.raises(ValueError, match="cut_frf.json' is not valid JSON"):
        msid.validate(m, cut_frf)
    with pytest.raises(ValueError, match="cut_model.json' is not valid JSON"):
        msid.validate(cut_model, f)
    with pytest.raises(ValueError, match="cut_model.json' is not valid JSON"):
        msid.modes(cut_model)


def test_empty_blocks_and_frames():
    d, rec, f = small_frf(P, LINES)
    m = msid.Measurement(design=d)
    m.push(np.zeros((0, 2)), experiment=0)                       # a callback's block of 0 frames
    m.push(np.column_stack([np.zeros(0), np.zeros((0, 1))]), experiment=0)
    m.push(rec, experiment=0)
    assert m.frf().n_lines == d.n_lines
    pd = pytest.importorskip("pandas")
    with pytest.raises(ValueError, match="'records\\[0\\]' holds no samples"):
        msid.frf(pd.DataFrame({"u1": [], "y1": []}), design=d)


def test_seeds_are_checked():
    with pytest.raises(ValueError, match="seed must be a non-negative integer, not -1"):
        msid.design(period=P, lines=LINES, seed=-1)
    with pytest.raises(ValueError, match="seed must be at most 18446744073709551615"):
        msid.design(period=P, lines=LINES, seed=2 ** 70)
    with pytest.raises(TypeError, match="seed must be an integer, not float 1.7"):
        msid.design(period=P, lines=LINES, seed=1.7)
    assert msid.design(period=P, lines=LINES, seed=2 ** 64 - 1).period == P
