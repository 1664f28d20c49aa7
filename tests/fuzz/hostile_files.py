"""Small experiment files whose sizes lie: each claims far more memory than its bytes can hold. Used by
tests/integration/test_peak_rss_bounds.py (each must give one message, a non-zero exit and a peak RSS
of a few MB) and, run as a script, to write them as fuzz_files seeds (the first byte picks the reader,
fuzz_files.cpp: 4 .npy, 6 .npz, 7 .mat, 3 CSV):
    python3 tests/fuzz/hostile_files.py tests/fuzz/corpus/fuzz_files
FILES: (name, file suffix, selector, maker); a maker returns (bytes, the memory its sizes claim in bytes).
Those of at most 4 KiB are seeds (regress-*).
MATLAB v5 layout: MathWorks "MAT-File Format" (Level 5); zip: PKWARE APPNOTE 6.3."""
import io
import struct
import sys
import zlib
from pathlib import Path

MI_INT8, MI_INT32, MI_UINT32, MI_DOUBLE, MI_MATRIX, MI_COMPRESSED = 1, 5, 6, 9, 14, 15
CELL, STRUCT, DOUBLE = 1, 2, 6


def mat_header():
    text = b"MATLAB 5.0 MAT-file, Platform: GLNXA64, Created on: Fri Nov 27 00:00:00 2026"
    return text.ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM"


def element(t, data, nbytes=None):
    """A tag (type, byte count: len(data) unless a lie is asked for) and the data padded to 8 bytes."""
    n = len(data) if nbytes is None else nbytes
    return struct.pack("<II", t, n) + data + b"\0" * (-len(data) % 8)


def matrix(cls, dims, name, *parts, nbytes=None):
    body = (element(MI_UINT32, struct.pack("<II", cls, 0)) + element(MI_INT32, struct.pack(f"<{len(dims)}I", *dims))
            + element(MI_INT8, name) + b"".join(parts))
    return element(MI_MATRIX, body, nbytes)


def compressed(m):
    z = zlib.compress(m)
    return struct.pack("<II", MI_COMPRESSED, len(z)) + z


def mat_v5_cell_name():
    # a compressed 1x1 cell whose cell is a matrix with a name of 0xBE020001 bytes: libmatio 1.5.23
    # (ReadNextCell) rounds it up to 8 and asks for malloc(0xBE020008 + 1) = 3,187,802,121 bytes, the
    # out-of-memory the readers were bounded against, before it inflates a byte of the name
    cell = struct.pack("<II", MI_MATRIX, 64) + element(MI_UINT32, struct.pack("<II", DOUBLE, 0)) + \
        element(MI_INT32, struct.pack("<2I", 1, 1)) + struct.pack("<II", MI_INT8, 0xBE020001) + b"\0" * 24
    return mat_header() + compressed(matrix(CELL, (1, 1), b"c", cell)), 0xBE020008 + 1


def mat_v5_nested_cell_count():
    # a compressed 1x1 cell holding a cell of 65536 x 65536 cells (one pointer each: 32 GiB)
    inner = matrix(CELL, (65536, 65536), b"", b"")
    return mat_header() + compressed(matrix(CELL, (1, 1), b"c", inner)), 65536 * 65536 * 8


def mat_v5_uncompressed_nested_cell():
    # the same nested cell count, uncompressed (an earlier check bounded the top matrix only)
    inner = matrix(CELL, (65536, 65536), b"", b"")
    return mat_header() + matrix(CELL, (1, 1), b"c", inner), 65536 * 65536 * 8


def mat_v5_struct_field_names():
    # a compressed 1x1 struct whose field names claim 2 GiB (64-byte names: 33,554,431 fields)
    names_len = struct.pack("<HH", MI_INT32, 4) + struct.pack("<I", 64)
    names = struct.pack("<II", MI_INT8, 0x7FFFFFC0) + b"u1".ljust(64, b"\0")
    return mat_header() + compressed(matrix(STRUCT, (1, 1), b"s", names_len, names)), 0x7FFFFFC0


def mat_v5_double_claims():
    # a compressed double matrix of 40000 x 40000 (12.8 GB of doubles) whose data part holds 8 bytes
    data = element(MI_DOUBLE, struct.pack("<d", 1.0))
    return mat_header() + compressed(matrix(DOUBLE, (40000, 40000), b"u1", data)), 40000 * 40000 * 8


def mat_v5_matrix_beyond_ratio():
    # a compressed element whose matrix claims 4 GiB - 1 bytes from about 60 compressed bytes
    data = element(MI_DOUBLE, struct.pack("<d", 1.0))
    return mat_header() + compressed(matrix(DOUBLE, (1, 1), b"u1", data, nbytes=0xFFFFFFFF)), 0xFFFFFFFF


def npy(shape, data=b"", descr="<f8"):
    h = "{'descr': '%s', 'fortran_order': False, 'shape': (%s), }" % (descr, ", ".join(map(str, shape)) + ("," if len(shape) == 1 else ""))
    h = h.ljust(118) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(h)) + h.encode() + data


def npy_shape_claims():
    # a .npy whose header claims 2^31 x 2 float64 (32 GiB) over 16 bytes of data
    return npy((1 << 31, 2), b"\0" * 16), (1 << 31) * 2 * 8


def zip_member(name, payload):
    """One deflated zip member at offset 0: its local header and data, and the fields its central
    directory entries repeat (version, flags, method, time, date, CRC, sizes)."""
    data = zlib.compress(payload)[2:-4]   # raw deflate
    fields = struct.pack("<HHHHHIII", 20, 0, 8, 0, 0, zlib.crc32(payload), len(data), len(payload))
    local = b"PK\3\4" + fields + struct.pack("<HH", len(name), 0) + name + data
    return local, fields


def npz(local, entries):
    """A zip of one member's bytes and central directory entries (fields, name) all pointing at it."""
    cd = b"".join(b"PK\1\2" + struct.pack("<H", 20) + f + struct.pack("<HHHHHII", len(n), 0, 0, 0, 0, 0, 0) + n
                  for f, n in entries)
    return local + cd + b"PK\5\6" + struct.pack("<HHHHIIH", 0, 0, len(entries), len(entries), len(cd), len(local), 0)


def npz_overlapping_members(pairs=128, samples=1 << 20):
    """One deflated member of `samples` float64 zeros and 2 x pairs directory entries u1.., y1.. all
    pointing at it: each a legal 1032:1 member. The default: 8 MiB each (about 8 KiB deflated), 256
    entries, 2 GiB together from 21,907 bytes."""
    local, fields = zip_member(b"u1.npy", npy((samples,), b"\0" * (8 * samples)))
    names = [f"{c}{k}.npy".encode() for c in "uy" for k in range(1, pairs + 1)]
    return npz(local, [(fields, n) for n in names]), 2 * pairs * 8 * samples


def npz_two_entries_one_member():
    # the same, small: u1 and y1 naming one member of 131,072 zeros (1 MiB, about 1 KiB deflated)
    return npz_overlapping_members(1, 1 << 17)


def npz_member_size_lies():
    # a deflated member declaring 3 GiB uncompressed from about 30 compressed bytes
    local, fields = zip_member(b"u1.npy", npy((2,), b"\0" * 16))
    fields = fields[:-4] + struct.pack("<I", 3 << 30)
    return npz(local, [(fields, b"u1.npy")]), 3 << 30


def csv_long_cell():
    # a CSV whose second cell is 2,000,000 digits without a line end (no size to lie about: the reader's
    # memory is its 4 MiB window, a buffer as long as the longest line, and the samples)
    return b"u1,y1\n1," + b"9" * 2000000, 2000000


FILES = [
    ("regress-mat-v5-cell-name-3g", ".mat", 7, mat_v5_cell_name),
    ("regress-mat-v5-nested-cell-count", ".mat", 7, mat_v5_nested_cell_count),
    ("regress-mat-v5-uncompressed-nested-cell", ".mat", 7, mat_v5_uncompressed_nested_cell),
    ("regress-mat-v5-struct-field-names", ".mat", 7, mat_v5_struct_field_names),
    ("regress-mat-v5-double-claims", ".mat", 7, mat_v5_double_claims),
    ("regress-mat-v5-matrix-beyond-ratio", ".mat", 7, mat_v5_matrix_beyond_ratio),
    ("regress-npy-shape-claims", ".npy", 4, npy_shape_claims),
    ("regress-npz-two-entries-one-member", ".npz", 6, npz_two_entries_one_member),
    ("npz-overlapping-members-2g", ".npz", 6, npz_overlapping_members),
    ("regress-npz-member-size-lies", ".npz", 6, npz_member_size_lies),
    ("csv-long-cell", ".csv", 3, csv_long_cell),
]


def matlab_class(ds, cls):
    """An h5py dataset's MATLAB_class attribute as MATLAB writes it: a fixed-length NULLTERM string
    (h5py's default NUL-padded string reads back truncated in libmatio)."""
    import h5py
    import numpy as np
    tid = h5py.h5t.C_S1.copy()
    tid.set_size(len(cls))
    tid.set_strpad(h5py.h5t.STR_NULLTERM)
    a = h5py.h5a.create(ds.id, b"MATLAB_class", tid, h5py.h5s.create(h5py.h5s.SCALAR))
    a.write(np.array(cls.encode(), dtype=f"S{len(cls)}"), mtype=tid)   # the bytes, no conversion


MAT73_HEADER = (b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Fri Nov 27 00:00:00 2026 HDF5 schema 1.00 ."
                .ljust(116, b" ") + b"\0" * 8 + b"\x00\x02" + b"IM")


def mat73_header(path):
    """The MATLAB header in the 512-byte user block of an HDF5 file h5py wrote (userblock_size=512)."""
    with open(path, "r+b") as f:
        f.write(MAT73_HEADER)


def mat_v73_huge(path, kind):
    """A v7.3 file (HDF5, 512-byte user block) with one chunked dataset never written: 'double' claims
    2^20 x 2^20 doubles (8 TiB), 'cell' 2^16 x 2^16 object references (32 GiB, which libmatio allocates
    twice while it lists the variables). Needs h5py; returns the claimed bytes."""
    import h5py
    import numpy as np
    with h5py.File(path, "w", userblock_size=512) as f:
        if kind == "double":
            ds = f.create_dataset("u1", shape=(1 << 20, 1 << 20), dtype="f8", chunks=(16, 16))
            claimed = (1 << 40) * 8
        else:
            ds = f.create_dataset("c", shape=(1 << 16, 1 << 16), dtype=h5py.ref_dtype, chunks=(16, 16))
            claimed = (1 << 32) * 8
        matlab_class(ds, kind)
    mat73_header(path)
    return claimed


def mat_v73_idfrd_huge(path):
    """An idfrd-shaped v7.3 file whose ResponseData (complex: a compound {real, imag}, chunked, never
    written) claims 2^20 x 1 x 2^20 values (16 TiB), beside a real Frequency and Ts. Needs h5py;
    returns the claimed bytes."""
    import h5py
    import numpy as np
    with h5py.File(path, "w", userblock_size=512) as f:
        rd = f.create_dataset("ResponseData", shape=(1 << 20, 1, 1 << 20), dtype=[("real", "<f8"), ("imag", "<f8")],
                              chunks=(16, 1, 16))
        fr = f.create_dataset("Frequency", data=np.arange(1.0, 11.0)[None, :])
        ts = f.create_dataset("Ts", data=np.zeros((1, 1)))
        for ds in (rd, fr, ts):
            matlab_class(ds, "double")
    mat73_header(path)
    return (1 << 40) * 16


def mat_v73_unlinked_cell(path):
    """A v7.3 file whose only variable, a 1x1 cell 'c', references a cell dataset of 2^16 x 2^16 (32 GiB of
    references) that no link names: kept alive by its reference count (H5Oincr_refcount, through ctypes
    into h5py's own HDF5) when its link is deleted. libmatio follows the reference while it lists the
    variables. Needs h5py; returns the claimed bytes, or None when h5py's HDF5 cannot be called."""
    import ctypes
    import glob
    import os
    import h5py
    import numpy as np
    libs = glob.glob(os.path.join(os.path.dirname(h5py.__file__), "..", "h5py.libs", "libhdf5-*.so*"))
    libs += glob.glob(os.path.join(os.path.dirname(h5py.__file__), "..", "h5py.libs", "libhdf5.so*"))
    if not libs:
        return None
    lib = ctypes.CDLL(libs[0])
    with h5py.File(path, "w", userblock_size=512) as f:
        x = f.create_dataset("#refs#/x", shape=(1 << 16, 1 << 16), dtype=h5py.ref_dtype, chunks=(16, 16))
        c = f.create_dataset("c", shape=(1, 1), dtype=h5py.ref_dtype)
        c[0, 0] = x.ref
        for ds in (x, c):
            matlab_class(ds, "cell")
        if lib.H5Oincr_refcount(ctypes.c_int64(x.id.id)) < 0:
            return None
        del f["#refs#/x"]
    mat73_header(path)
    return (1 << 32) * 8



def mat_v73_many_references(path, count=1 << 20):
    """A v7.3 file whose cell 'c' holds `count` object references, all to one 1x1 double, in a chunked
    dataset compressed with deflate (about 20 kB for 2^20), beside u1 and y1. libmatio allocates a
    variable and reads the target for every element while it lists the variables: 2^23 such references
    (a 119 kB file) took 3.5 GB and 16 minutes before the reference count was bounded by the file's
    size / 8. Needs h5py; returns the file's size."""
    import os
    import h5py
    import numpy as np
    with h5py.File(path, "w", userblock_size=512) as f:
        a = f.create_dataset("#refs#/a", data=np.zeros((1, 1)))
        chunk = min(count, 1 << 16)
        c = f.create_dataset("c", shape=(count, 1), dtype=h5py.ref_dtype, chunks=(chunk, 1), compression="gzip",
                             compression_opts=9)
        block = np.empty((chunk, 1), dtype=h5py.ref_dtype)
        block[:] = a.ref
        for i in range(0, count, chunk):
            c[i:i + chunk] = block
        u = f.create_dataset("u1", data=np.zeros((100, 1)))
        y = f.create_dataset("y1", data=np.zeros((100, 1)))
        for ds, cls in ((a, "double"), (c, "cell"), (u, "double"), (y, "double")):
            matlab_class(ds, cls)
    mat73_header(path)
    return os.path.getsize(path)

if __name__ == "__main__":
    out = Path(sys.argv[1])
    for seed, _, sel, make in FILES:
        data, _ = make()
        if len(data) <= 4096:   # a seed's size; the larger ones are the RSS test's only
            (out / seed).write_bytes(bytes([sel]) + data)
