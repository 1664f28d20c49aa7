"""Arguments as msid takes them: the checks shared by the estimators, the fits and the measurement
(integers, numbers, bin lists, column maps, records of samples), each refusing with the keyword's name:
TypeError for a wrong type, ValueError for a bad value."""
import math
import os
import sys
from typing import Sequence, Union

import numpy as np

from ._compiled import ext as _ext

Bins = Union[str, Sequence[int], np.ndarray]


# A range "a:b" of more items is refused before it is expanded, as the command line refuses it.
_MAX_RANGE = 50_000_000
# No period msid takes (at most 2^24 samples) has a line at or above 2^23.
_NO_LINE = 1 << 23


def _show(v):
    """A value as a message quotes it: its repr, cut to 60 characters; a NumPy scalar as the Python number
    it holds (NumPy 2's repr, "np.float64(inf)", is not what the user wrote)."""
    if isinstance(v, np.generic) and v.ndim == 0:
        v = v.item()
    r = repr(v)
    return r if len(r) <= 60 else r[:57] + "..."


def _uint(v, what, top=0xFFFFFFFF):
    """A non-negative integer keyword: TypeError for another type (a float is not truncated), ValueError
    out of 0..top (before anything is sized from it)."""
    if type(v) is int and 0 <= v <= top:   # the common case, without the checks below
        return v
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise TypeError(f"{what} must be an integer, not {type(v).__name__} {_show(v)}")
    if v < 0:
        raise ValueError(f"{what} must be a non-negative integer, not {_show(v)}")
    if v > top:
        raise ValueError(f"{what} must be at most {top}, not {_show(v)}")
    return int(v)


def _uint_list(v, what, stop_at=_NO_LINE):
    """Bins as msid takes them: integers, or a string '1,2,10:20,1:2:9' (ranges include both ends). The
    list ends after its first bin at or above `stop_at` (one msid refuses by name: at or beyond Nyquist),
    so a range such as '1:1000000000' is never expanded past what can be checked."""
    if isinstance(v, str):
        if not v.strip():
            raise ValueError(f"{what}: empty list")
        out = []
        for item in v.split(","):
            parts = item.split(":")
            try:
                nums = [int(p) for p in parts]
            except ValueError:
                raise ValueError(f"{what}: bad item '{item}'") from None
            if any(x < 0 for x in nums):
                raise ValueError(f"{what}: '{item}' is not a non-negative integer")
            if any(x > 0xFFFFFFFF for x in nums):
                raise ValueError(f"{what}: '{item}' is too large")
            if len(parts) == 1:
                out.append(np.array(nums, dtype=np.int64))
            elif len(parts) in (2, 3):
                a, b, st = nums[0], nums[-1], (nums[1] if len(parts) == 3 else 1)
                if st <= 0 or b < a:
                    raise ValueError(f"{what}: bad range '{item}'")
                if (b - a) // st > _MAX_RANGE:
                    raise ValueError(f"{what}: range '{item}' is too long")
                if b >= stop_at:   # up to the first bin msid refuses
                    b = min(b, a + ((max(stop_at - a, 0) + st - 1) // st) * st)
                out.append(np.arange(a, b + 1, st, dtype=np.int64))
            else:
                raise ValueError(f"{what}: bad item '{item}'")
            if out[-1].size and out[-1][-1] >= stop_at:
                break
        a = np.concatenate(out)
    elif type(v) is list and all(type(x) is int and 0 <= x < stop_at for x in v):   # plain ints: as given
        return list(v)
    else:
        a = np.asarray(v)
        if a.ndim > 1 or (a.size and a.dtype.kind not in "iu"):
            if a.dtype.kind in "fc" or a.dtype == object:
                raise TypeError(f"{what} must be integers (bins) or a string such as '1:200', not {_show(v)}")
            raise ValueError(f"{what} must be integers (bins) or a string such as '1:200', not {_show(v)}")
        a = a.reshape(-1).astype(np.int64, copy=False) if a.size else np.zeros(0, np.int64)
        bad = np.flatnonzero((a < 0) | (a > 0xFFFFFFFF))
        if bad.size:
            raise ValueError(f"{what} must be non-negative integers, not {int(a[bad[0]])}")
    beyond = np.flatnonzero(a >= stop_at)
    if beyond.size:
        a = a[:beyond[0] + 1]
    return a.tolist()


def _float(v, what):
    """A real keyword: TypeError for another type, ValueError for NaN, an infinity or a subnormal
    number (which the command line reads as no number: its reciprocal, a sample time, is infinite)."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
        raise TypeError(f"{what} must be a number, not {type(v).__name__} {_show(v)}")
    try:
        x = float(v)
    except OverflowError:
        raise ValueError(f"{what} must be a finite number, not {_show(v)}") from None
    if not math.isfinite(x):
        raise ValueError(f"{what} must be a finite number, not {_show(v)}")
    if x != 0 and abs(x) < sys.float_info.min:
        raise ValueError(f"{what}: {_show(v)} is below the smallest normal double ({sys.float_info.min:g})")
    return x


def _below_nyquist(period):
    """The first bin at or beyond Nyquist of `period` (for _uint_list), or no bound when it is unknown."""
    return (period + 1) // 2 if type(period) is int and period >= 0 else _NO_LINE


def _column_spec(columns):
    if columns is None:
        return ""
    if isinstance(columns, dict):
        return ",".join(f"{k}={v}" for k, v in columns.items())
    return str(columns)


def _real_samples(a, where):
    """C-contiguous float64, the form the core reads in place; any other real dtype or layout is copied
    once (integers, float32, a Fortran-order or strided array), anything else refused."""
    if a.dtype.kind not in "fiu" or a.dtype.itemsize > 8:
        raise ValueError(f"'{where}': dtype {a.dtype} is not supported (float16/32/64 or integers; complex is not)")
    return np.ascontiguousarray(a, dtype=np.float64)


def _record(r, where, spec, n_inputs, free=False):
    """One experiment's record as (samples, column names, nu): a 2-D array (rows are samples; columns
    u1..u_nu then y1..y_ny, numbered from 1 as in a .npy) or a pandas DataFrame (named columns)."""
    ext = _ext()
    if isinstance(r, (str, bytes, os.PathLike)):
        raise TypeError(f"'{where}' is a path among arrays: give every record as an array (or DataFrame), or "
                        "every record as a file's path")
    if hasattr(r, "columns") and hasattr(r, "iloc"):     # a pandas DataFrame
        names = [str(c) for c in r.columns]
        idx, nu, _ = ext.resolve_columns(where, names, spec, free)
        if len(r) == 0:
            raise ValueError(f"'{where}' holds no samples")
        part = r.iloc[:, list(idx)]
        kinds = {str(t) for t in part.dtypes}
        try:   # pandas' nullable dtypes (Float64, Int64: missing values as pd.NA) as NaN, which msid names
            a = part.to_numpy(dtype=np.float64, na_value=np.nan)
        except (TypeError, ValueError):
            raise ValueError(f"'{where}': columns of dtype {', '.join(sorted(kinds))} are not numbers "
                             "(float32/64 or integers)") from None
        return _real_samples(a, where), [names[i] for i in idx], nu
    try:
        a = np.asarray(r)
    except (TypeError, ValueError) as e:
        raise TypeError(f"'{where}' is not an array of samples ({e})") from None
    if a.ndim != 2:
        raise ValueError(f"'{where}': a {a.ndim}-dimensional array of shape {a.shape}; expected a samples x "
                         "channels matrix (rows are samples; columns u1..u_nu, y1..y_ny)")
    C = a.shape[1]
    names = [str(k + 1) for k in range(C)]
    if not spec:
        if n_inputs is None:
            raise ValueError(f"'{where}' holds one {a.shape[0]} x {C} matrix without column names: give n_inputs "
                             "(or design), or map its columns (numbered from 1) with columns='u1=1,y1=2,...'")
        nu = _uint(n_inputs, "n_inputs")
        if (nu == 0 and not free) or C <= nu:
            raise ValueError(f"'{where}' has {C} column(s): {nu} input(s) leave no output column")
        if a.shape[0] == 0:
            raise ValueError(f"'{where}' holds no samples")
        return _real_samples(a, where), names, nu   # the columns in order: u1..u_nu, then y1..
    idx, nu, _ = ext.resolve_columns(where, names, spec, free)
    idx = list(idx)
    if idx != list(range(C)):
        a = a[:, idx]
    if a.shape[0] == 0:
        raise ValueError(f"'{where}' holds no samples")
    return _real_samples(a, where), [names[i] for i in idx], nu


def _records(records, columns, n_inputs, free=False, label="records"):
    items = list(records) if isinstance(records, (list, tuple)) else [records]
    if not items:
        raise ValueError(f"no {label} given: one 2-D array (or DataFrame) per experiment")
    spec = _column_spec(columns)
    out = [_record(r, f"{label}[{k}]", spec, n_inputs, free) for k, r in enumerate(items)]
    return [o[0] for o in out], [f"{label}[{k}]" for k in range(len(out))], [o[1] for o in out], [o[2] for o in out]


def _file_text(path):
    """A document file's text and its path as msid names it (OSError with msid's wording; ValueError
    for a file that is not UTF-8 text, as no msid document is)."""
    path = os.fspath(path)
    try:
        with open(path, "r", encoding="utf-8") as fh:
            return fh.read(), path
    except OSError as e:
        raise OSError(e.errno, f"cannot open '{path}': {e.strerror}") from None
    except UnicodeDecodeError as e:
        raise ValueError(f"'{path}' is not an msid document: byte 0x{e.object[e.start]:02x} at offset {e.start} is "
                         "not UTF-8 text (JSON)") from None

