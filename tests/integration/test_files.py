"""Experiment files as they come: named columns (--columns), ';' and tab
delimiters, trailing commas, time and extra columns, NumPy .npy/.npz and
MATLAB .mat v5 (written by SciPy) and v7.3 (HDF5, written by h5py). Every
format must give the FRF bit-identical to the plain CSV of the same samples;
every bad file one message naming file, row/line and column/variable, and no
output file."""
import json
import os
import subprocess
import sys
import zipfile

import numpy as np
import pytest

import helpers as h

P = 64
BINS = [1, 3, 5, 7, 11]
K = 6


def _samples(seed=3):
    """A 2x2 record: periodic multisine inputs (K periods) and a noisy static mix."""
    rng = np.random.default_rng(seed)
    n = np.arange(P)
    per = np.stack([sum(np.cos(2 * np.pi * b * n / P + rng.uniform(0, 2 * np.pi)) for b in BINS) for _ in range(2)], 1)
    u = np.tile(per, (K, 1)) + 1e-3 * rng.standard_normal((K * P, 2))
    y = u @ np.array([[0.5, -0.2], [0.3, 1.0]]) + 0.01 * rng.standard_normal((K * P, 2))
    return u, y


def _frf(tmp_path, files, extra=(), name="frf.json"):
    out = tmp_path / name
    args = ["frf", "--period", P, "--lines", ",".join(map(str, BINS))]
    for f in files:
        args += ["--experiment", f]
    h.run_ok(*args, *extra, "-o", out)
    doc = h.load_json(out)
    h.validate(doc, "msid-frf-1")
    return doc


def _lines(doc):
    return [(l["G"], l["cov"]) for l in doc["lines"]]


@pytest.fixture(scope="module")
def data():
    return [_samples(3), _samples(4)]


@pytest.fixture
def reference(tmp_path, data):
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"ref{e}.csv"
        h.write_csv(p, h.experiment_columns(u, y))
        files.append(p)
    return _lines(_frf(tmp_path, files, name="ref.json"))


def _text(u, y, header, delim=",", trailing="", time=False, extra=None):
    rows = [delim.join(header) + trailing]
    for k in range(u.shape[0]):
        cells = ([repr(k * 1e-3)] if time else []) + [repr(float(v)) for v in (*u[k], *y[k])]
        if extra is not None:
            cells.append(extra if k == 0 else "")
        rows.append(delim.join(cells) + trailing)
    return "\n".join(rows) + "\n"


def test_named_columns_semicolons_trailing_commas_time_and_rate(tmp_path, data, reference):
    """A logger's export: time column, named channels in another order, ';',
    trailing delimiters, a sample-rate column filled in the first row only."""
    files = []
    for e, (u, y) in enumerate(data):
        # columns: Time;Acc2;Force1;Acc1;Force2;Fs  (mapped by name, order differs)
        rows = ["Time;Acc2;Force1;Acc1;Force2;Fs;"]
        for k in range(u.shape[0]):
            rows.append(";".join([repr(k * 1e-3), repr(float(y[k, 1])), repr(float(u[k, 0])), repr(float(y[k, 0])),
                                  repr(float(u[k, 1])), "1000" if k == 0 else ""]) + ";")
        p = tmp_path / f"log{e}.csv"
        p.write_text("\n".join(rows) + "\n", encoding="utf-8")
        files.append(p)
    doc = _frf(tmp_path, files, ["--columns", "u1=Force1,u2=Force2,y1=Acc1,y2=Acc2"])
    assert _lines(doc) == reference


@pytest.mark.parametrize("delim", [";", ",", "\t"])
def test_trailing_rows_of_delimiters_only_are_blank_lines(tmp_path, data, reference, delim):
    """A spreadsheet's export ends in rows of delimiters only (";;;;;", CRLF, spaces): blank trailing
    lines, the same FRF (it used to be "line 386, column Force: '' is not a number (empty cell)").
    Negative control: the same row inside the data is an empty line there, one message, no file."""
    files = []
    for e, (u, y) in enumerate(data):
        rows = _text(u, y, ["Time", "Force", "Force2", "Acc", "Acc2"], delim=delim, time=True).splitlines()
        p = tmp_path / f"x{e}.csv"
        p.write_bytes(("\r\n".join(rows + [delim * 4, " " + delim + " " + delim * 3, delim * 6, ""])).encode())
        files.append(p)
    cols = ["--columns", "u1=Force,u2=Force2,y1=Acc,y2=Acc2"]
    assert _lines(_frf(tmp_path, files, cols)) == reference
    rows = files[0].read_bytes().decode().split("\r\n")
    rows.insert(101, delim * 4)
    files[0].write_bytes("\r\n".join(rows).encode())
    _fails(tmp_path, files, cols, f"'{files[0]}' line 102: empty line inside the data")


def test_comment_lines_before_the_header(tmp_path, data, reference):
    """A logger writes its settings as '#' lines before the header (after a BOM here): skipped, the
    same FRF, and the lines named in messages are the file's (it used to be "column '# Logger X'
    ... not found"). Negative controls: a bad cell names its line counting the comments; comments
    and no header are one message, no file; a '#' line inside the data is still an error there."""
    files = []
    head = "# Logger X-200, firmware 3.1\n# sample rate: 1000 Hz\n#\n"
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"c{e}.csv"
        p.write_bytes(b"\xef\xbb\xbf" + (head + _text(u, y, ["Time", "Force", "Force2", "Acc", "Acc2"], time=True)).encode())
        files.append(p)
    cols = ["--columns", "u1=Force,u2=Force2,y1=Acc,y2=Acc2"]
    assert _lines(_frf(tmp_path, files, cols)) == reference
    good = files[0].read_bytes()
    rows = good.decode("utf-8-sig").split("\n")
    bad = rows[:10] + [rows[10].rsplit(",", 1)[0] + ",oops"] + rows[11:]   # file line 11: 3 comments, header, 6 rows
    files[0].write_bytes(b"\xef\xbb\xbf" + "\n".join(bad).encode())
    _fails(tmp_path, files, cols, f"'{files[0]}' line 11, column Acc2: 'oops' is not a number")
    files[0].write_bytes(b"\xef\xbb\xbf" + "\n".join(rows[:6] + ["# a note"] + rows[6:]).encode())
    _fails(tmp_path, files, cols, f"'{files[0]}' line 7")
    files[0].write_text(head, encoding="utf-8")
    _fails(tmp_path, files, cols, f"'{files[0]}' is empty after 3 comment lines")


def test_column_names_with_commas(tmp_path, data, reference):
    """Channel names with a unit after a comma ("Force, N" in a ';' file, or quoted in a ',' file):
    --columns takes them plainly (a piece without '=' continues the name before it) or quoted
    (it used to split 'u1=Force, N' at the comma: "' N' is not <u<k>|y<k>>=<column name>")."""
    names = ["Time", "Force, N", "Force2, N", "Acc, m/s2", "Acc2, m/s2"]
    files = []
    for e, (u, y) in enumerate(data):
        rows = _text(u, y, names, delim=";", time=True).splitlines()
        p = tmp_path / f"n{e}.csv"
        p.write_text("\n".join(rows) + "\n", encoding="utf-8")
        files.append(p)
    for spec in ('u1=Force, N,u2=Force2, N,y1=Acc, m/s2,y2=Acc2, m/s2',
                 'u1="Force, N",u2="Force2, N",y1="Acc, m/s2",y2="Acc2, m/s2"'):
        assert _lines(_frf(tmp_path, files, ["--columns", spec])) == reference, spec
    # negative control: a misspelt name is one message listing the columns, with their commas
    _fails(tmp_path, files, ["--columns", "u1=Force, N,u2=Force2, N,y1=Acc, m/s2,y2=Acc3, m/s2"],
           "no column 'Acc3, m/s2' (for y2)", "'Acc2, m/s2'")


def test_quoted_numbers(tmp_path, data, reference):
    """Every cell quoted, header and numbers ("0.25", as QUOTE_ALL exports write them): the same FRF
    (it used to be "line 2, column Force: '"0.25"' is not a number"). Negative controls: a quote
    left open and a non-number inside quotes are one message naming line and column."""
    files = []
    for e, (u, y) in enumerate(data):
        rows = _text(u, y, ["Time", "Force", "Force2", "Acc", "Acc2"], delim=";", time=True).splitlines()
        p = tmp_path / f"q{e}.csv"
        p.write_text("\n".join(";".join(f'"{c}"' for c in r.split(";")) for r in rows) + "\n", encoding="utf-8")
        files.append(p)
    cols = ["--columns", "u1=Force,u2=Force2,y1=Acc,y2=Acc2"]
    assert _lines(_frf(tmp_path, files, cols)) == reference
    good = files[0].read_text(encoding="utf-8").split("\n")
    for bad in ('"%s', '"x%s"', '%s"'):   # quote left open, a non-number inside quotes, a stray quote
        rows = list(good)
        c = rows[6].split(";")
        c[1] = bad % c[1].strip('"')
        rows[6] = ";".join(c)
        files[0].write_text("\n".join(rows), encoding="utf-8")
        _fails(tmp_path, files, cols, f"'{files[0]}' line 7, column Force: '{c[1]}' is not a number")


def test_quoted_cells_hold_delimiters(tmp_path, data, reference):
    """A logger's first row carries the rate and a quoted comment with a comma; header names quoted
    with a delimiter inside: delimiters inside quotes are text (RFC 4180), the same FRF. It used to
    split the comment, shift row 1 one column right (Force read the rate, 1000) and pass silently;
    with ';' and a comma in a quoted name the header's delimiter was taken as ','."""
    for delim in (",", ";"):
        files = []
        for e, (u, y) in enumerate(data):
            rows = [delim.join(['"Time, s"', "Comment", "Fs", "Force", "Force2", "Acc", "Acc2", '"Note, free"']) + delim]
            for k in range(u.shape[0]):
                com = f'"Operator: J. Smith{delim} shift ""2"""' if k % 50 == 0 else ""
                rows.append(delim.join([repr(k * 1e-3), com, "1000" if k == 0 else "",
                                        *(repr(float(v)) for v in (*u[k], *y[k])), ""]) + delim)
            p = tmp_path / f"c{e}.csv"
            p.write_text("\n".join(rows) + "\n", encoding="utf-8")
            files.append(p)
        doc = _frf(tmp_path, files, ["--columns", "u1=Force,u2=Force2,y1=Acc,y2=Acc2"])
        assert _lines(doc) == reference, delim
    # negative control: a quote left open runs to the end of its line, so that row is ragged
    text = files[0].read_text(encoding="utf-8").split("\n")
    text[3] = text[3].replace(";", ';"', 1)
    files[0].write_text("\n".join(text), encoding="utf-8")
    _fails(tmp_path, files, ["--columns", "u1=Force,u2=Force2,y1=Acc,y2=Acc2"], f"'{files[0]}' line 4: ragged row")


def test_tab_delimiter_and_time_column(tmp_path, data, reference):
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"t{e}.tsv"
        p.write_text(_text(u, y, ["t", "u1", "u2", "y1", "y2"], delim="\t", time=True), encoding="utf-8")
        files.append(p)
    assert _lines(_frf(tmp_path, files)) == reference


def _npy_files(tmp_path, data, fortran=False):
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"e{e}.npy"
        x = np.column_stack([u, y])
        np.save(p, np.asfortranarray(x) if fortran else x)
        files.append(p)
    return files


@pytest.mark.parametrize("fortran", [False, True])
def test_npy_matrix_with_positional_columns(tmp_path, data, reference, fortran):
    files = _npy_files(tmp_path, data, fortran)
    assert _lines(_frf(tmp_path, files, ["--columns", "u1=1,u2=2,y1=3,y2=4"])) == reference


def test_npy_float32_and_transposed(tmp_path, data):
    """float32 samples are widened exactly; a channels x samples matrix is read as such."""
    files32, filesT = [], []
    for e, (u, y) in enumerate(data):
        x = np.column_stack([u, y]).astype(np.float32)
        p = tmp_path / f"f{e}.npy"
        np.save(p, x)
        files32.append(p)
        q = tmp_path / f"T{e}.npy"
        np.save(q, x.T.astype(np.float64))
        filesT.append(q)
    cols = ["--columns", "u1=1,u2=2,y1=3,y2=4"]
    assert _lines(_frf(tmp_path, files32, cols, "a.json")) == _lines(_frf(tmp_path, filesT, cols, "b.json"))


@pytest.mark.parametrize("compress", [False, True])
def test_npz_vectors_by_name(tmp_path, data, reference, compress):
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"e{e}.npz"
        (np.savez_compressed if compress else np.savez)(p, u1=u[:, 0], u2=u[:, 1], y1=y[:, 0], y2=y[:, 1],
                                                        t=np.arange(u.shape[0]) * 1e-3)
        files.append(p)
    assert _lines(_frf(tmp_path, files)) == reference


def test_npz_matrix_columns_mapped(tmp_path, data, reference):
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"m{e}.npz"
        np.savez_compressed(p, force=u, acc=y, fs=np.array([1000.0]))
        files.append(p)
    doc = _frf(tmp_path, files, ["--columns", "u1=force:1,u2=force:2,y1=acc:1,y2=acc:2"])
    assert _lines(doc) == reference


def test_mat_v5_scipy(tmp_path, data, reference):
    sio = pytest.importorskip("scipy.io")
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"e{e}.mat"
        # a logger's layout: one matrix of channels plus a scalar rate and a name string
        sio.savemat(p, {"Force": u, "Acc1": y[:, :1], "Acc2": y[:, 1], "fs": 1000.0, "note": "bench 3"})
        files.append(p)
    doc = _frf(tmp_path, files, ["--columns", "u1=Force:1,u2=Force:2,y1=Acc1,y2=Acc2"])
    assert _lines(doc) == reference


def _mat_v5_by_hand(path, variables, big_endian, compress):
    """A MATLAB v5 file written element by element (MathWorks "MAT-File Format", Level 5), in either
    byte order, with names of up to 4 characters in small elements, a 1x1 value in a small data
    element and each variable's samples stored as int16 (MATLAB stores a double class in a narrower
    type when its values fit): the layouts scipy does not write."""
    import struct
    import zlib
    o = ">" if big_endian else "<"

    def el(t, data):
        if len(data) <= 4:   # a small element: the byte count in the upper half of the type word
            return struct.pack(o + "I", len(data) << 16 | t) + data.ljust(4, b"\0")
        return struct.pack(o + "II", t, len(data)) + data + b"\0" * (-len(data) % 8)

    text = b"MATLAB 5.0 MAT-file, written by hand for msid's tests".ljust(116, b" ")
    out = text + b"\0" * 8 + struct.pack(o + "H", 0x0100) + (b"MI" if big_endian else b"IM")
    for name, v in variables.items():
        v = np.atleast_2d(np.asarray(v))
        body = (el(6, struct.pack(o + "II", 6, 0)) + el(5, struct.pack(o + "2i", *v.shape)) + el(1, name.encode())
                + el(3 if v.dtype == np.int16 else 9, v.astype(o + ("i2" if v.dtype == np.int16 else "f8")).tobytes("F")))
        m = struct.pack(o + "II", 14, len(body)) + body
        out += struct.pack(o + "II", 15, len(zlib.compress(m))) + zlib.compress(m) if compress else m
    path.write_bytes(out)


@pytest.mark.parametrize("big_endian", [False, True])
@pytest.mark.parametrize("compress", [False, True])
def test_mat_v5_byte_order_small_elements_and_packed_types(tmp_path, data, big_endian, compress):
    """msid's own v5 reader: either byte order, compressed or not, small elements (names, a 1x1 int16),
    samples stored as int16 for a double class: the FRF equals the CSV reader's of the same integers."""
    files, csvs = [], []
    for e, (u, y) in enumerate(data):
        ui, yi = np.round(u * 1000).astype(np.int16), np.round(y * 1000).astype(np.int16)
        p = tmp_path / f"h{e}.mat"
        _mat_v5_by_hand(p, {"u1": ui[:, 0], "u2": ui[:, 1], "y1": yi[:, 0], "y2": yi[:, 1], "fs": np.array([[1e3]]),
                            "n": np.array([[7]], dtype=np.int16)}, big_endian, compress)
        files.append(p)
        c = tmp_path / f"h{e}.csv"
        c.write_text(_text(ui.astype(float), yi.astype(float), ["u1", "u2", "y1", "y2"]))
        csvs.append(c)
    assert _lines(_frf(tmp_path, files, name="mat.json")) == _lines(_frf(tmp_path, csvs, name="csv.json"))


def test_mat_names_case_insensitive_and_a_typo_lists_every_variable(tmp_path, data, reference):
    """A .mat variable maps case-insensitively, as a CSV header or an .npz member does; a misspelt
    name lists every variable of the file (it used to list only those the mapping named, so the
    one meant was missing from the message, and 'force' did not find Force)."""
    sio = pytest.importorskip("scipy.io")
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"c{e}.mat"
        sio.savemat(p, {"Force": u[:, 0], "Force2": u[:, 1], "Acc": y, "time": np.arange(len(u)) * 1e-3})
        files.append(p)
    doc = _frf(tmp_path, files, ["--columns", "u1=force,u2=FORCE2,y1=acc:1,y2=Acc:2"])
    assert _lines(doc) == reference
    # the typo: every variable listed, Force2 among them
    _fails(tmp_path, files, ["--columns", "u1=Force,u2=Forc2,y1=Acc:1,y2=Acc:2"],
           f"'{files[0]}': no column 'Forc2' (for u2); the file has 'Force', 'Force2', 'Acc:1', 'Acc:2', 'time'")
    # the same mapping on .npz members (negative control: the behaviour the .mat now shares)
    z = tmp_path / "c.npz"
    np.savez(z, Force=data[0][0][:, 0], Force2=data[0][0][:, 1], Acc=data[0][1])
    _fails(tmp_path, [z, files[1]], ["--columns", "u1=Force,u2=Forc2,y1=Acc:1,y2=Acc:2"], "'Force2'")


def _write_mat73(path, variables):
    """MATLAB v7.3 (helpers.write_mat73): each variable a column of doubles."""
    cols = {}
    for name, v in variables.items():
        v = np.atleast_2d(np.asarray(v, dtype=float))
        cols[name] = v.T if v.shape[0] == 1 else v
    h.write_mat73(path, cols)


def test_mat_v73_hdf5(tmp_path, data, reference):
    files = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"h{e}.mat"
        _write_mat73(p, {"u1": u[:, 0], "u2": u[:, 1], "y1": y[:, 0], "y2": y[:, 1]})
        files.append(p)
    assert _lines(_frf(tmp_path, files)) == reference


# ---- bad files: one message naming file, row/line and column/variable; no output ----

def _fails(tmp_path, files, extra, *phrases):
    out = tmp_path / "never.json"
    args = ["frf", "--period", P, "--lines", ",".join(map(str, BINS))]
    for f in files:
        args += ["--experiment", f]
    r = h.run(*args, *extra, "-o", out)
    err = r.stderr.splitlines()
    assert r.returncode in (1, 2) and len(err) == 1, r.stderr
    for ph in phrases:
        assert ph in err[0], (ph, err[0])
    assert not out.exists()
    return err[0]


def test_bad_csv_named_cell(tmp_path, data):
    u, y = data[0]
    p = tmp_path / "bad.csv"
    text = _text(u, y, ["Time", "F1", "F2", "A1", "A2"], delim=";", time=True).splitlines()
    cells = text[9].split(";")
    cells[3] = "0,25.5"    # a comma and a point in A1, file line 10 (a thousands separator?)
    text[9] = ";".join(cells)
    p.write_text("\n".join(text) + "\n", encoding="utf-8")
    _fails(tmp_path, [p], ["--columns", "u1=F1,u2=F2,y1=A1,y2=A2"], f"'{p}' line 10, column A1",
           "'0,25.5' is not a number", "',' as the decimal separator: one ',' and no '.'")


def test_decimal_commas_and_a_units_row(tmp_path, data, reference):
    """A spreadsheet in a European locale: ';' (or tab) between cells and ',' as the decimal separator
    ("0,25"), a units row under the header ("s;N;N;m/s^2;m/s^2", one unit empty in the tab file); also quoted decimal commas in a
    ','-delimited file. The same FRF, bit for bit (it used to be "'0,25' is not a number", and the
    units row "'N' is not a number"). Negative controls: "1,234.5" (a thousands separator) and a
    second units-like row inside the data are one message naming line and column."""
    names = ["Zeit", "F1", "F2", "A1", "A2"]
    cols = ["--columns", "u1=F1,u2=F2,y1=A1,y2=A2"]
    for delim, units, quote in ((";", "s;N;N;m/s^2;m/s^2", ""), ("\t", "[s]\t[N]\t\t[m/s2]\t[m/s2]", ""),
                                (",", "s,N,N,m/s^2,m/s^2", '"')):
        files = []
        for e, (u, y) in enumerate(data):
            rows = _text(u, y, names, delim=delim, time=True).splitlines()
            body = [delim.join(quote + c.replace(".", ",") + quote for c in r.split(delim)) for r in rows[1:]]
            p = tmp_path / f"dc{e}.csv"
            p.write_text("\n".join([rows[0], units] + body) + "\n", encoding="utf-8")
            files.append(p)
        assert _lines(_frf(tmp_path, files, cols)) == reference, repr(delim)
    rows = files[0].read_text(encoding="utf-8").split("\n")   # the quoted ','-delimited file
    u, y = data[0]
    line8 = ",".join(f'"{c}"' for c in ["0,005", "1,234.5", *(str(float(v)).replace(".", ",") for v in (*u[5, 1:], *y[5]))])
    files[0].write_text("\n".join(rows[:7] + [line8] + rows[8:]), encoding="utf-8")
    _fails(tmp_path, files, cols, f"'{files[0]}' line 8, column F1: '\"1,234.5\"' is not a number",
           "one ',' and no '.'")
    files[0].write_text("\n".join(rows[:5] + [rows[1]] + rows[5:]), encoding="utf-8")
    _fails(tmp_path, files, cols, f"'{files[0]}' line 6, column F1: 'N' is not a number")


def test_bad_csv_missing_mapped_column(tmp_path, data):
    u, y = data[0]
    p = tmp_path / "a.csv"
    p.write_text(_text(u, y, ["t", "F1", "F2", "A1", "A2"], time=True), encoding="utf-8")
    _fails(tmp_path, [p], ["--columns", "u1=F1,u2=F2,y1=A1,y2=Acc2"], f"'{p}': no column 'Acc2' (for y2)",
           "'F1'")


def test_bad_csv_mapped_cell_missing(tmp_path, data):
    u, y = data[0]
    p = tmp_path / "short.csv"
    text = _text(u, y, ["u1", "u2", "y1", "y2"]).splitlines()
    text[20] = ",".join(text[20].split(",")[:3])
    p.write_text("\n".join(text) + "\n", encoding="utf-8")
    _fails(tmp_path, [p], [], f"'{p}' line 21: ragged row", "column y2 missing")


def test_bad_columns_option(tmp_path, data):
    p = _npy_files(tmp_path, data)[0]
    _fails(tmp_path, [p], ["--columns", "u1=1,u3=2,y1=3"], "--columns: inputs must be u1..u3 without gaps")
    _fails(tmp_path, [p], ["--columns", "u1=1,y1=1"], "column '1' is mapped twice")


def test_bad_npy_nan_names_row_and_column(tmp_path, data):
    u, y = data[0]
    x = np.column_stack([u, y])
    x[37, 2] = np.nan
    p = tmp_path / "nan.npy"
    np.save(p, x)
    _fails(tmp_path, [p], ["--columns", "u1=1,u2=2,y1=3,y2=4"], f"'{p}' row 38, column 3: NaN or Inf")


@pytest.mark.parametrize("bad", [np.nan, -np.nan, np.inf, -np.inf, "nan-payload"])
def test_bad_npy_zero_copy_every_nonfinite_kind(tmp_path, data, bad):
    """The mapped .npy (float64, C order, columns in order) is checked by an integer OR over the
    bit patterns: every exponent-all-ones pattern (NaN of either sign or with a payload, +-Inf)
    at the last sample is found, and named by its row and column."""
    u, y = data[0]
    x = np.column_stack([u, y])
    if bad == "nan-payload":
        x.view(np.uint64)[-1, 3] = np.uint64(0xFFF0000000000001)   # signalling NaN, sign set
    else:
        x[-1, 3] = bad
    p = tmp_path / "bad.npy"
    np.save(p, x)
    _fails(tmp_path, [p], ["--columns", "u1=1,u2=2,y1=3,y2=4"], f"'{p}' row {K * P}, column 4: NaN or Inf")


@pytest.mark.parametrize("case", ["whole", "blocks", "leftover", "skipped", "first_in_order", "before_input_check"])
def test_bad_npy_nan_found_by_the_lanes(tmp_path, data, case):
    """msid frf scans an in-place .npy for NaN/Inf in its measurement lanes, block by block, not in
    the reader (Record::finite_unchecked): the message and its precedence are the reader's. A NaN
    inside the periods (one block, or --block 100: several), in the rows after the last whole
    period, in a skipped period; two bad files: the first in file order although the other's NaN
    comes earlier in its record; file 1's input not periodic (an error of the input check, before
    the lanes) and file 2 with a NaN: the NaN, as when the reader scanned."""
    files = _npy_files(tmp_path, data)
    xs = [np.load(f) for f in files]
    extra = ["--columns", "u1=1,u2=2,y1=3,y2=4"]
    want = None
    if case in ("whole", "blocks"):
        xs[1][199, 1] = np.nan
        want = f"'{files[1]}' row 200, column 2: NaN or Inf"
        if case == "blocks":
            extra += ["--block", "100"]
    elif case == "leftover":
        xs[0] = np.vstack([xs[0], xs[0][:10]])
        xs[0][K * P + 6, 3] = -np.inf
        want = f"'{files[0]}' row {K * P + 7}, column 4: NaN or Inf"
    elif case == "skipped":
        xs[1][4, 0] = np.inf
        extra += ["--skip-periods", "1"]
        want = f"'{files[1]}' row 5, column 1: NaN or Inf"
    elif case == "first_in_order":
        xs[0][K * P - 1, 2] = np.nan
        xs[1][0, 2] = np.nan
        want = f"'{files[0]}' row {K * P}, column 3: NaN or Inf"
    else:
        xs[0][:, :2] = np.random.default_rng(3).standard_normal((K * P, 2))   # not periodic: the input check fails
        xs[1][300, 3] = np.nan
        want = f"'{files[1]}' row 301, column 4: NaN or Inf"
    for f, x in zip(files, xs):
        np.save(f, x)
    _fails(tmp_path, files, extra, want)
    if case == "before_input_check":   # negative control: without the NaN the input check speaks
        xs[1][300, 3] = 0.0
        np.save(files[1], xs[1])
        _fails(tmp_path, files, extra, f"'{files[0]}': the input is not periodic")


def test_npy_zero_copy_extreme_values(tmp_path, data):
    """Controls of the check above: the smallest subnormal and -0.0 are samples (the FRF is written);
    the largest finite double is beyond the samples' range (1e150) and refused by the reader with its
    place, in the zero-copy scan as in the others (it overflowed the core's DFT and lost its period)."""
    files = _npy_files(tmp_path, data)
    x = np.load(files[0])
    x[-3, 2] = 5e-324
    x[-4, 2] = -0.0
    np.save(files[0], x)
    doc = _frf(tmp_path, files, ["--columns", "u1=1,u2=2,y1=3,y2=4"])
    assert doc["experiments"][0]["periods_nonfinite"] == 0 and doc["experiments"][1]["periods_nonfinite"] == 0
    x[-2, 3] = -np.finfo(float).max
    np.save(files[0], x)
    _fails(tmp_path, files, ["--columns", "u1=1,u2=2,y1=3,y2=4"],
           f"'{files[0]}' row {len(x) - 1}, column 4: -1.79769e+308 is beyond the samples' range (|x| <= 1e+150")


def test_bad_npy_without_columns_and_truncated(tmp_path, data):
    p = _npy_files(tmp_path, data)[0]
    _fails(tmp_path, [p], [], f"'{p}' holds one {K * P} x 4 matrix", "--columns u1=1,y1=2")
    b = p.read_bytes()
    t = tmp_path / "trunc.npy"
    t.write_bytes(b[:-100])
    _fails(tmp_path, [t], ["--columns", "u1=1,u2=2,y1=3,y2=4"], f"'{t}': truncated")
    c = tmp_path / "c.npy"
    np.save(c, np.zeros((K * P, 4), complex))
    _fails(tmp_path, [c], ["--columns", "u1=1,u2=2,y1=3,y2=4"], "'<c16' is not supported")


def test_bad_npy_dimension_beyond_32_bits(tmp_path):
    """A shape of 2^32 + 1 rows over 16 bytes of data: on a 32-bit build a size_t dimension wrapped to 1,
    so the file read as one row of two values (then taken as 2 samples x 1 channel). Every architecture
    must give the same truncation message with the 64-bit sizes the header states."""
    hdr = b"{'descr': '<f8', 'fortran_order': False, 'shape': (4294967297, 2), }"
    hdr += b" " * (63 - (10 + len(hdr)) % 64) + b"\n"
    t = tmp_path / "wide.npy"
    t.write_bytes(b"\x93NUMPY\x01\x00" + len(hdr).to_bytes(2, "little") + hdr + np.array([1.5, 2.5]).tobytes())
    _fails(tmp_path, [t], ["--columns", "u1=1,y1=2"],
           f"'{t}': truncated: the header says 4294967297 x 2 <f8 (68719476752 bytes of data) but 16 are there")


def test_bad_npz_lengths_and_corrupt(tmp_path, data):
    u, y = data[0]
    p = tmp_path / "len.npz"
    np.savez(p, u1=u[:, 0], u2=u[:, 1], y1=y[:-1, 0], y2=y[:, 1])
    _fails(tmp_path, [p], [], f"'{p}': variable 'y1' has {K * P - 1} samples but 'u1' has {K * P}")
    q = tmp_path / "inf.npz"
    y2 = y.copy()
    y2[5, 1] = np.inf
    np.savez_compressed(q, u1=u[:, 0], u2=u[:, 1], y1=y2[:, 0], y2=y2[:, 1])
    _fails(tmp_path, [q], [], f"'{q}' row 6, column y2: NaN or Inf")
    z = tmp_path / "junk.npz"
    z.write_bytes(b"not a zip at all" * 10)
    _fails(tmp_path, [z], [], f"'{z}' is not an .npz (zip) file")
    # a deflated member with its data damaged
    d = tmp_path / "damaged.npz"
    with zipfile.ZipFile(d, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, v in (("u1", u[:, 0]), ("u2", u[:, 1]), ("y1", y[:, 0]), ("y2", y[:, 1])):
            with zf.open(name + ".npy", "w") as f:
                np.lib.format.write_array(f, v)
    raw = bytearray(d.read_bytes())
    raw[200:260] = b"\xff" * 60
    d.write_bytes(bytes(raw))
    _fails(tmp_path, [d], [], f"'{d}' variable 'u1'")


def test_bad_mat(tmp_path, data):
    sio = pytest.importorskip("scipy.io")
    u, y = data[0]
    p = tmp_path / "cplx.mat"
    sio.savemat(p, {"u1": u[:, 0] + 0j, "u2": u[:, 1], "y1": y[:, 0], "y2": y[:, 1]})
    _fails(tmp_path, [p], ["--columns", "u1=u1,u2=u2,y1=y1,y2=y2"], f"'{p}' variable 'u1' is complex")
    q = tmp_path / "nan.mat"
    y2 = y.copy()
    y2[99, 0] = np.nan
    sio.savemat(q, {"u1": u[:, 0], "u2": u[:, 1], "y1": y2[:, 0], "y2": y2[:, 1]})
    _fails(tmp_path, [q], [], f"'{q}' row 100, column y1: NaN or Inf")
    r = tmp_path / "junk.mat"
    r.write_bytes(b"MATLAB 5.0 MAT-file" + b"\0" * 30)
    _fails(tmp_path, [r], [], f"'{r}'")
    s = tmp_path / "names.mat"
    sio.savemat(s, {"Force": u, "Acc": y})
    _fails(tmp_path, [s], [], f"'{s}' has no input columns", "'Force:1'", "--columns")


def test_bad_mat73_h5py_default_class_attribute(tmp_path, data):
    """A v7.3 file written with h5py's default MATLAB_class attribute (a NUL-padded string, which
    libmatio reads as 'doubl'): the message says so and how to write the file (it used to be
    "variable 'Acc' is not a numeric array" for a float64 dataset). Negative control: the same
    samples with a NUL-terminated attribute (test_mat_v73_hdf5's writer) are read."""
    h5py = pytest.importorskip("h5py")
    u, y = data[0]
    p = tmp_path / "h5py.mat"
    with h5py.File(p, "w", userblock_size=512) as f:
        for name, v in {"Force": u, "Acc": y}.items():
            f.create_dataset(name, data=v.T).attrs["MATLAB_class"] = np.bytes_("double")
    h.mat73_header(p)
    cols = ["--columns", "u1=Force:1,u2=Force:2,y1=Acc:1,y2=Acc:2"]
    _fails(tmp_path, [p], cols, f"'{p}' variable ", "MATLAB_class", "h5py")
    ok = []
    for e, (u, y) in enumerate(data):
        ok.append(tmp_path / f"ok{e}.mat")
        _write_mat73(ok[-1], {"u1": u[:, 0], "u2": u[:, 1], "y1": y[:, 0], "y2": y[:, 1]})
    _frf(tmp_path, ok)


def test_large_csv_two_threads_same_result_and_line_numbers(tmp_path):
    """Over 4 MiB the CSV is parsed by two threads: the FRF equals the .npy of
    the same samples, and an error or a blank line in the second half is
    reported at its true line."""
    rng = np.random.default_rng(11)
    Kb, n = 2500, np.arange(P)
    per = np.stack([sum(np.cos(2 * np.pi * b * n / P + rng.uniform(0, 2 * np.pi)) for b in BINS) for _ in range(2)], 1)
    u = np.tile(per, (Kb, 1)) + 1e-3 * rng.standard_normal((Kb * P, 2))
    y = u @ np.array([[0.5, -0.2], [0.3, 1.0]]) + 0.01 * rng.standard_normal((Kb * P, 2))
    x = np.column_stack([u[:, 0], y[:, 0]])   # SISO: one experiment
    text = "u1,y1\n" + "".join(f"{a!r},{b!r}\n" for a, b in x.tolist())
    assert len(text) > 5 << 20
    big = tmp_path / "big.csv"
    big.write_text(text, encoding="utf-8")
    npy = tmp_path / "big.npy"
    np.save(npy, x)
    assert _lines(_frf(tmp_path, [big], name="c.json")) == \
        _lines(_frf(tmp_path, [npy], ["--columns", "u1=1,y1=2"], name="n.json"))
    rows = text.split("\n")
    k = int(0.8 * len(rows))               # file line k + 1, in the second thread's part
    bad = rows.copy()
    bad[k] = bad[k].replace(",", ",x", 1)
    b1 = tmp_path / "bad1.csv"
    b1.write_text("\n".join(bad), encoding="utf-8")
    _fails(tmp_path, [b1], [], f"'{b1}' line {k + 1}, column y1")
    blank = rows.copy()
    blank[k] = ""
    b2 = tmp_path / "bad2.csv"
    b2.write_text("\n".join(blank), encoding="utf-8")
    _fails(tmp_path, [b2], [], f"'{b2}' line {k + 1}: empty line inside the data")


def test_number_formats_parse_exactly(tmp_path):
    """The fast number parser (exact Clinger path, else std::from_chars) gives
    the doubles Python's float() gives, for numbers written in many styles
    (shortest repr, 9/15/17 significant digits, exponents, 20 decimals, '+'):
    the FRF equals the one of the same values written as repr."""
    rng = np.random.default_rng(5)
    n = np.arange(P * K)
    u = np.cos(2 * np.pi * 3 * n / P) + 0.5 * np.cos(2 * np.pi * 5 * n / P + 1) + 1e-3 * rng.standard_normal(n.size)
    y = 0.7 * u + 0.01 * rng.standard_normal(n.size)
    styles = ["%r", "%.9g", "%.3e", "%.15g", "%.17g", "%.1f", "%E", "%.20f", "%g", "%+.12e"]

    def cell(v, i):
        f = styles[i % len(styles)]
        return repr(float(v)) if f == "%r" else f % v
    rows = [(cell(a, i), cell(b, i + 3)) for i, (a, b) in enumerate(zip(u, y))]
    styled = tmp_path / "styled.csv"
    styled.write_text("u1,y1\n" + "".join(f"{a},{b}\n" for a, b in rows), encoding="utf-8")
    ref = tmp_path / "ref.csv"
    ref.write_text("u1,y1\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in rows), encoding="utf-8")
    out = []
    for f in (styled, ref):
        o = tmp_path / (f.stem + ".json")
        h.run_ok("frf", "--period", P, "--lines", "3,5", "--experiment", f, "-o", o)
        out.append(h.load_json(o)["lines"])
    assert out[0] == out[1]


def test_streamed_csv_blocks_long_lines_pipe_and_error_order(tmp_path):
    """The CSV is streamed in 4 MiB blocks of whole lines: a bad cell or an
    empty line on either side of a block boundary is reported at its true
    line; a line longer than a block (5 MiB of blanks before a number), a
    missing final newline, CRLF and a named pipe give the same FRF as the
    plain file; a bad cell is reported before an earlier empty line whatever
    the block it falls in."""
    rng = np.random.default_rng(12)
    Kb, n = 4000, np.arange(P)
    per = sum(np.cos(2 * np.pi * b * n / P + rng.uniform(0, 2 * np.pi)) for b in BINS)
    u = np.tile(per, Kb) + 1e-3 * rng.standard_normal(Kb * P)
    y = 0.5 * u + 0.01 * rng.standard_normal(Kb * P)
    rows = ["u1,y1"] + [f"{a!r},{b!r}" for a, b in zip(u.tolist(), y.tolist())]
    text = "\n".join(rows) + "\n"
    assert len(text) > 9 << 20   # three blocks
    ref = tmp_path / "ref.csv"
    ref.write_text(text, encoding="utf-8")
    want = _lines(_frf(tmp_path, [ref], name="ref.json"))
    # line index (0-based) of the first line that starts at or after byte `off`
    starts = np.cumsum([0] + [len(r) + 1 for r in rows])
    at = lambda off: int(np.searchsorted(starts, off))  # noqa: E731
    for off in ((4 << 20) - 1, 4 << 20, (6 << 20) + 7, 8 << 20):
        for k in (at(off) - 1, at(off)):
            bad = rows.copy()
            bad[k] = bad[k].replace(",", ",x", 1)
            f = tmp_path / f"bad{k}.csv"
            f.write_text("\n".join(bad) + "\n", encoding="utf-8")
            _fails(tmp_path, [f], [], f"'{f}' line {k + 1}, column y1")
            blank = rows.copy()
            blank[k] = ""
            f.write_text("\n".join(blank) + "\n", encoding="utf-8")
            _fails(tmp_path, [f], [], f"'{f}' line {k + 1}: empty line inside the data")
    both = rows.copy()
    both[5], both[at(9 << 20)] = "", both[at(9 << 20)].replace(",", ",x", 1)
    f = tmp_path / "both.csv"
    f.write_text("\n".join(both) + "\n", encoding="utf-8")
    _fails(tmp_path, [f], [], f"'{f}' line {at(9 << 20) + 1}, column y1")
    longl = rows.copy()
    longl[3] = " " * (5 << 20) + longl[3]
    f = tmp_path / "long.csv"
    f.write_text("\n".join(longl), encoding="utf-8")   # and no final newline
    assert _lines(_frf(tmp_path, [f], name="long.json")) == want
    f = tmp_path / "crlf.csv"
    f.write_bytes(text.replace("\n", "\r\n").encode())
    assert _lines(_frf(tmp_path, [f], name="crlf.json")) == want
    import os
    import threading
    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    w = threading.Thread(target=lambda: fifo.write_text(text, encoding="utf-8"))
    w.start()
    try:
        assert _lines(_frf(tmp_path, [fifo], name="pipe.json")) == want
    finally:
        w.join()


def test_csv_memory_is_the_samples_plus_a_constant(tmp_path):
    """The CSV is streamed, not held. A 55 MB file whose rows are
    mostly an ignored text column holds 8 MB of samples (500,000 rows x 2
    mapped columns): peak RSS (getrusage of the child) must stay under the
    samples + 32 MiB. The reader that held the file peaked at 69 MiB here
    (negative control: main's binary fails this bound)."""
    if "ASAN_OPTIONS" in os.environ:   # scripts/sanitize.sh: ASan's shadow memory is most of the RSS there
        pytest.skip("peak RSS means nothing under AddressSanitizer (its shadow memory)")
    import subprocess
    n = 500_000
    rng = np.random.default_rng(21)
    t = np.arange(n)
    u = np.cos(2 * np.pi * 3 * t / P) + 0.01 * rng.standard_normal(n)
    y = 0.5 * u + 0.01 * rng.standard_normal(n)
    f = tmp_path / "wide.csv"
    pad = "x" * 90
    f.write_text("u1,y1,note\n" + "".join(f"{a:.6f},{b:.6f},{pad}\n" for a, b in zip(u, y)), encoding="utf-8")
    assert f.stat().st_size > 50e6
    # a fresh child per measurement: ru_maxrss of RUSAGE_CHILDREN is the largest child so far
    code = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True); "
            "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    out = subprocess.run([sys.executable, "-c", code, h.msid_bin(), "frf", "--period", str(P), "--lines", "3",
                          "--columns", "u1=u1,y1=y1", "--experiment", str(f), "-o", str(tmp_path / "o.json")],
                         capture_output=True, text=True, timeout=600, check=True).stdout.split()
    rc, kib = int(out[0]), int(out[1])
    samples = 8 * 2 * n
    assert rc == 0
    assert kib * 1024 < samples + (32 << 20), f"peak RSS {kib / 1024:.0f} MiB, samples {samples / 2**20:.0f} MiB"


def test_files_read_in_parallel_report_the_first_bad_file(tmp_path, data):
    """msid frf reads two regular CSV/.npy files at once (one thread each) and measures two
    experiments at once: the message is that of the first bad file in --experiment order
    whichever thread finds its error first, and three experiments (lanes 0, 1, 0) give the
    same FRF as the same files read one by one through a pipe (serial path)."""
    good = []
    for e, (u, y) in enumerate(data):
        p = tmp_path / f"g{e}.csv"
        h.write_csv(p, h.experiment_columns(u, y))
        good.append(p)
    bad = []
    for e, (u, y) in enumerate(data):
        lines = (tmp_path / f"g{e}.csv").read_text(encoding="utf-8").splitlines()
        cells = lines[5 + 3 * e].split(",")
        cells[1] = "x" + str(e)
        lines[5 + 3 * e] = ",".join(cells)
        p = tmp_path / f"b{e}.csv"
        p.write_text("\n".join(lines) + "\n", encoding="utf-8")
        bad.append(p)
    # the second file's error lies earlier in its file, and the small bad first file is read
    # by one thread while the other reads a large good .npy: still the first file's message
    _fails(tmp_path, [bad[0], bad[1]], [], f"'{bad[0]}' line 6, column u2", "'x0'")
    _fails(tmp_path, [good[0], bad[1]], [], f"'{bad[1]}' line 9, column u2", "'x1'")
    big = tmp_path / "big.csv"
    u, y = data[1]
    x = np.tile(np.column_stack([u, y]), (300, 1))
    np.savetxt(big, x, delimiter=",", header="u1,u2,y1,y2", comments="", fmt="%.17g")
    _fails(tmp_path, [bad[0], big], [], f"'{bad[0]}' line 6, column u2", "'x0'")
    # the control that a "first error found" order would fail: a large first file whose bad
    # cell is its last, a small second file bad at line 9 (found long before)
    text = big.read_text(encoding="utf-8").rstrip("\n").split("\n")
    text[-1] = "bad" + text[-1][text[-1].index(","):]
    big.write_text("\n".join(text) + "\n", encoding="utf-8")
    _fails(tmp_path, [big, bad[1]], [], f"'{big}' line {len(text)}, column u1", "'bad'")
    # three experiments: lanes 0, 1, 0; the same FRF as read serially (a pipe is read serially)
    third = tmp_path / "g2.csv"
    u, y = _samples(5)
    h.write_csv(third, h.experiment_columns(u, y))
    par = _frf(tmp_path, good + [third], name="par.json")
    r = subprocess.run([h.msid_bin(), "frf", "--period", str(P), "--lines", ",".join(map(str, BINS)),
                        "--experiment", str(good[0]), "--experiment", str(good[1]),
                        "--experiment", "/dev/stdin", "-o", str(tmp_path / "ser.json")],
                       input=third.read_bytes(), capture_output=True, timeout=600)   # stdin: a pipe
    assert r.returncode == 0, r.stderr.decode()
    ser = h.load_json(tmp_path / "ser.json")
    assert _lines(par) == _lines(ser)
