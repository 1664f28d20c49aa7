"""Writes the binary-record seeds of fuzz_files (run once; the files are in the repository):
    python3 tests/fuzz/gen_file_seeds.py tests/fuzz/corpus/fuzz_files
The first byte picks the reader (fuzz_files.cpp): 4 .npy, 5 .npy through the zero-copy view, 6 .npz,
7 .mat. Small records (8 rows) in the layouts the readers handle: float64/float32/int16, C and Fortran
order, big-endian, a 1-D vector; .npz stored and deflated; .mat v5 (compressed and not) and v4."""
import io
import sys
import zipfile
from pathlib import Path

import numpy as np
import scipy.io

out = Path(sys.argv[1])
rng = np.random.default_rng(15)
x = rng.standard_normal((8, 2))


def put(name, sel, data):
    (out / name).write_bytes(bytes([sel]) + data)


def npy(a):
    b = io.BytesIO()
    np.save(b, a)
    return b.getvalue()


put("npy-f8", 4, npy(x))
put("npy-f4-fortran", 4, npy(np.asfortranarray(x.astype(np.float32))))
put("npy-i2-bigendian", 4, npy((x * 1000).astype(">i2")))
put("npy-vector", 4, npy(x[:, 0].copy()))
put("npy-view-f8", 5, npy(x))
for comp, tag in ((zipfile.ZIP_STORED, "stored"), (zipfile.ZIP_DEFLATED, "deflated")):
    b = io.BytesIO()
    with zipfile.ZipFile(b, "w", comp) as z:
        z.writestr("u1.npy", npy(x[:, 0].copy()))
        z.writestr("y1.npy", npy(x[:, 1].copy()))
    put(f"npz-{tag}", 6, b.getvalue())
for kw, tag in (({"do_compression": True}, "v5z"), ({}, "v5"), ({"format": "4"}, "v4")):
    b = io.BytesIO()
    scipy.io.savemat(b, {"u1": x[:, :1], "y1": x[:, 1:]}, **kw)
    put(f"mat-{tag}", 7, b.getvalue())
# every MATLAB class msid's v5 reader skips (cell, struct, char, sparse, logical, complex) beside the numeric
# ones it reads, compressed and not; and a small v7.3 file (HDF5) with one double vector
import scipy.sparse  # noqa: E402
others = {"u1": x[:, :1], "y1": x[:, 1:], "c": np.array([[x[:2, 0], "ab"]], dtype=object),
          "s": {"a": 1.0, "b": x[:2, 1]}, "t": "text", "sp": scipy.sparse.csc_matrix(np.eye(3)),
          "l": np.array([True, False]), "z": x[:2, 0] + 1j}
for kw, tag in (({"do_compression": True}, "v5z-every-class"), ({}, "v5-every-class")):
    b = io.BytesIO()
    scipy.io.savemat(b, others, **kw)
    put(f"mat-{tag}", 7, b.getvalue())
