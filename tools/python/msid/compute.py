"""msid in process: the FRF of samples held in NumPy arrays (msid.frf), a measurement fed block by
block (msid.Measurement) and excitation designs (msid.design, msid.read_design), over the C++
libraries of the msid command line (the compiled module msid._msid). The same samples give the same
bits as `msid frf`; errors are msid's messages (ValueError; OSError for files). docs/python.md.

    d = msid.design(period=4096, lines="1:200", inputs=2)
    u = d.samples(experiment=0, periods=64)            # (64 * 4096, 2): drive the plant with it
    f = msid.frf([rec0, rec1], design=d)                 # rec: rows = samples, columns u1, u2, y1, y2
    f.G, f.cov, f.dof                                    # msid.FRF, as read_frf gives it

Only the compiled functions need msid._msid; the rest of the package imports without it.
"""
import os
import warnings
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np

from .files import FRF, frf_from_doc

PathLike = Union[str, "os.PathLike[str]"]
Bins = Union[str, Sequence[int], np.ndarray]

__all__ = ["frf", "Measurement", "Design", "design", "read_design", "NoteWarning"]


class NoteWarning(UserWarning):
    """A note msid prints beside a result (a start-up transient, samples after the last whole period, distortion)."""


def _ext():
    try:
        from . import _msid
    except ImportError as e:
        raise ImportError(
            f"this needs msid's compiled extension msid._msid, which this msid package does not have ({e}); build "
            "it with the msid build (./bootstrap.sh build, then PYTHONPATH=build/python) or install the package "
            "with it: pip install ./tools/python (docs/python.md)") from None
    return _msid


# ---- arguments as msid takes them ----

def _uint(v, what):
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)) or not 0 <= v <= 0xFFFFFFFF:
        raise ValueError(f"{what} must be a non-negative integer, not {v!r}")
    return int(v)


def _uint_list(v, what):
    """Bins as msid takes them: integers, or a string '1,2,10:20,1:2:9' (ranges include both ends)."""
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
            if len(parts) == 1:
                out.append(nums[0])
            elif len(parts) in (2, 3):
                a, b, st = nums[0], nums[-1], (nums[1] if len(parts) == 3 else 1)
                if st <= 0 or b < a:
                    raise ValueError(f"{what}: bad range '{item}'")
                out.extend(range(a, b + 1, st))
            else:
                raise ValueError(f"{what}: bad item '{item}'")
        return [_uint(x, what) for x in out]
    a = np.asarray(v)
    if a.ndim > 1 or (a.size and a.dtype.kind not in "iu"):
        raise ValueError(f"{what} must be integers (bins) or a string such as '1:200', not {v!r}")
    return [_uint(int(x), what) for x in a.reshape(-1)]


def _float(v, what):
    try:
        return float(v)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a number, not {v!r}") from None


def _options(skip_periods, fs, detect_lines, transient, alpha, dft):
    """The estimating options the extension shares between msid.frf and Measurement; those at their
    default are left out, as options not given on the command line (direct refuses the others)."""
    o = {"skip_periods": _uint(skip_periods, "skip_periods"),
         "fs": None if fs is None else _float(fs, "fs"),
         "detect_lines": None if detect_lines is None else _uint_list(detect_lines, "detect_lines"),
         "transient": str(transient), "alpha": _float(alpha, "alpha"), "dft": str(dft)}
    default = {"transient": "flag", "alpha": 0.01, "dft": "auto"}
    return {k: v for k, v in o.items() if v is not None and default.get(k) != v}


def _design_arg(design):
    if design is None or isinstance(design, Design):
        return design
    if isinstance(design, (str, os.PathLike)):
        return read_design(design)
    raise TypeError(f"design must be an msid.Design or a design file's path, not {type(design).__name__}")


def _column_spec(columns):
    if columns is None:
        return ""
    if isinstance(columns, dict):
        return ",".join(f"{k}={v}" for k, v in columns.items())
    return str(columns)


def _real_samples(a, where):
    """C-contiguous float64, the form the core reads in place; any other real dtype or layout is copied
    once (integers, float32, a Fortran-order or strided array), anything else refused."""
    if a.dtype.kind not in "fiu":
        raise ValueError(f"'{where}': dtype {a.dtype} is not supported (float32/64 or integers; complex is not)")
    return np.ascontiguousarray(a, dtype=np.float64)


def _record(r, where, spec, n_inputs):
    """One experiment's record as (samples, column names, nu): a 2-D array (rows are samples; columns
    u1..u_nu then y1..y_ny, numbered from 1 as in a .npy) or a pandas DataFrame (named columns)."""
    ext = _ext()
    if hasattr(r, "columns") and hasattr(r, "iloc"):     # a pandas DataFrame
        names = [str(c) for c in r.columns]
        idx, nu, _ = ext.resolve_columns(where, names, spec)
        a = _real_samples(r.iloc[:, list(idx)].to_numpy(), where)
        return a, [names[i] for i in idx], nu
    a = np.asarray(r)
    if a.ndim != 2:
        raise ValueError(f"'{where}': a {a.ndim}-dimensional array of shape {a.shape}; expected a samples x "
                         "channels matrix (rows are samples; columns u1..u_nu, y1..y_ny)")
    C = a.shape[1]
    if not spec:
        if n_inputs is None:
            raise ValueError(f"'{where}' holds one {a.shape[0]} x {C} matrix without column names: give n_inputs "
                             "(or design), or map its columns (numbered from 1) with columns='u1=1,y1=2,...'")
        nu = _uint(n_inputs, "n_inputs")
        spec = ",".join([f"u{k + 1}={k + 1}" for k in range(min(nu, C))] +
                        [f"y{k + 1}={nu + k + 1}" for k in range(max(C - nu, 0))])
        if nu == 0 or C <= nu:
            raise ValueError(f"'{where}' has {C} column(s): {nu} input(s) leave no output column")
    names = [str(k + 1) for k in range(C)]
    idx, nu, _ = ext.resolve_columns(where, names, spec)
    idx = list(idx)
    if idx != list(range(C)):
        a = a[:, idx]
    if a.shape[0] == 0:
        raise ValueError(f"'{where}' holds no samples")
    return _real_samples(a, where), [names[i] for i in idx], nu


def _records(records, columns, n_inputs):
    items = list(records) if isinstance(records, (list, tuple)) else [records]
    if not items:
        raise ValueError("no records given: one 2-D array (or DataFrame) per experiment")
    spec = _column_spec(columns)
    out = [_record(r, f"records[{k}]", spec, n_inputs) for k, r in enumerate(items)]
    return [o[0] for o in out], [f"records[{k}]" for k in range(len(out))], [o[1] for o in out], [o[2] for o in out]


def _result(res, where):
    f = frf_from_doc(res["doc"], where)
    f.notes = list(res["notes"])
    f.reports = list(res.get("reports", []))
    for n in f.notes:
        warnings.warn(n, NoteWarning, stacklevel=3)
    return f


# ---- the FRF of records ----

def frf(records: Any, *, design: Union["Design", PathLike, None] = None, period: Union[int, str, None] = None,
        lines: Optional[Bins] = None, skip_periods: int = 0, fs: Optional[float] = None, method: str = "periodic",
        columns: Union[str, Dict[str, str], None] = None, n_inputs: Optional[int] = None,
        detect_lines: Optional[Bins] = None, transient: str = "flag", alpha: float = 0.01, dft: str = "auto",
        block: Optional[int] = None, realisations: Optional[int] = None, direct: bool = False) -> FRF:
    """The FRF of multisine records, as `msid frf` estimates it from files: the same request gives the
    same bits (docs/statistics.md for the estimator and its exact statistics).

    records: one experiment's samples, or a list with one per experiment. Each is a 2-D array (rows are
      samples, periods back to back; columns u1..u_nu then y1..y_ny, numbered from 1 for `columns`) or a
      pandas DataFrame (its column names, u1.. y1.. or mapped by `columns`). C-contiguous float64 arrays
      are read in place; other real dtypes and layouts are copied once.
    design: an msid.Design or a design file (period, lines, inputs, experiments), or else
    period, lines: samples per period and excited bins; either may be "auto" (found from the inputs).
      lines takes integers or msid's string form ("1:200", "1,3,5:2:21").
    n_inputs: the number of input columns of a plain array (default: the design's).
    columns: which columns feed u1.., y1.. ("u1=Force,y1=Acc" or {"u1": "Force", "y1": "Acc"}), as --columns.
    skip_periods, fs, detect_lines, transient ("flag", "drop", "off"), alpha, dft ("auto", "stream",
      "fft"), block, realisations, direct: the options of `msid frf` (msid frf --help).
    method: "periodic" (the multisine estimator; `msid frf --method lpm|etfe` is the command line's).

    Returns an msid.FRF; its .notes are msid's notes (also issued as NoteWarning) and .reports what
    period/lines "auto" found. Raises ValueError with msid's message for bad records or options.
    """
    if method != "periodic":
        raise ValueError(f"method {method!r}: msid.frf estimates periodic records (method='periodic'); "
                         "for lpm or etfe use `msid frf --method lpm|etfe`")
    D = _design_arg(design)
    if n_inputs is None and D is not None:
        n_inputs = D.n_inputs
    opts = _options(skip_periods, fs, detect_lines, transient, alpha, dft)
    if isinstance(period, str) and period == "auto":
        opts["auto_period"] = True
    elif period is not None:
        opts["period"] = _uint(period, "period")
    if isinstance(lines, str) and lines == "auto":
        opts["auto_lines"] = True
    elif lines is not None:
        opts["lines"] = _uint_list(lines, "lines")
    if block is not None:
        opts["block"] = _uint(block, "block")
    if realisations is not None:
        opts["realisations"] = _uint(realisations, "realisations")
    opts["direct"] = bool(direct)
    arrays, names, colnames, nus = _records(records, columns, n_inputs)
    return _result(_ext().frf(arrays, names, colnames, nus, opts, None if D is None else D._impl), "msid.frf")


# ---- a measurement fed block by block ----

class Measurement:
    """The FRF job fed with samples as they arrive (a device callback: python-can, sounddevice, nidaqmx).

        m = msid.Measurement(design=d, skip_periods=2)
        m.push(block, experiment=0)    # rows [u1..u_nu, y1..y_ny], any number of rows, experiments in turn
        m.progress                     # whole periods received per experiment
        f = m.frf()                    # msid.FRF

    Any block sizes give the same bits, equal to msid.frf on the whole records. Experiments are measured
    one after another: pushing to another experiment closes the open one. The transient test keeps up
    to `max_periods` periods per experiment (default 4 x the design's periods + 8); transient="off"
    keeps none. Options as msid.frf.
    """

    def __init__(self, design: Union["Design", PathLike], *, skip_periods: int = 0, fs: Optional[float] = None,
                 detect_lines: Optional[Bins] = None, transient: str = "flag", alpha: float = 0.01, dft: str = "auto",
                 max_periods: Optional[int] = None):
        D = _design_arg(design)
        if D is None:
            raise ValueError("a Measurement needs a design (period, lines, inputs and experiments)")
        self.design = D
        opts = _options(skip_periods, fs, detect_lines, transient, alpha, dft)
        if max_periods is None:
            max_periods = 4 * (D.periods or 64) + 8
        self._m = _ext().Measurement(D._impl, opts, _uint(max_periods, "max_periods"))

    def push(self, block: np.ndarray, experiment: int = 0) -> None:
        """Push rows of experiment `experiment` (counted from 0): a 2-D array (a 1-D one is one row)."""
        e = _uint(experiment, "experiment")
        a = np.asarray(block)
        if a.ndim == 1:
            a = a.reshape(1, -1)
        if a.ndim != 2:
            raise ValueError(f"'experiment {e}': a {a.ndim}-dimensional block of shape {a.shape}; expected rows x "
                             "channels (u1..u_nu, y1..y_ny)")
        self._m.push(_real_samples(a, f"experiment {e}"), e)

    @property
    def progress(self) -> List[int]:
        """Whole periods received per experiment (a list, experiment 0 first)."""
        return list(self._m.progress())

    def frf(self) -> FRF:
        """Close the measurement and estimate: an msid.FRF (ValueError if an experiment has too few periods)."""
        return _result(self._m.frf(), "msid.Measurement")

    def __repr__(self):
        return (f"<msid.Measurement P = {self.design.period}, {self.design.n_lines} lines, "
                f"{self.design.n_experiments} experiment(s), periods received {self.progress}>")


# ---- designs ----

class Design:
    """An excitation design (msid-design/1): built by msid.design, read by msid.read_design."""

    def __init__(self, impl):
        self._impl = impl

    period = property(lambda self: self._impl.period, doc="samples per period")
    n_inputs = property(lambda self: self._impl.n_inputs)
    n_experiments = property(lambda self: self._impl.n_experiments)
    cond_max = property(lambda self: self._impl.cond_max, doc="largest condition number over the lines")

    @property
    def bins(self):
        """Excited DFT bins (the line of each frequency)."""
        return np.array(self._impl.bins, dtype=int)

    @property
    def n_lines(self):
        return len(self._impl.bins)

    @property
    def doc(self):
        """The msid-design/1 document (a dict)."""
        return self._impl.doc

    @property
    def periods(self):
        """Recommended periods per experiment (None if the design does not say)."""
        return self._impl.doc.get("periods")

    def crest_factor(self, experiment: int, inp: int) -> float:
        """max|u|/rms(u) of input `inp` in `experiment` (both from 0)."""
        return self._impl.crest_factor(_uint(experiment, "experiment"), _uint(inp, "input"))

    def samples(self, experiment: int = 0, periods: Optional[int] = None) -> np.ndarray:
        """The inputs of `experiment` (from 0) over `periods` periods (default: the design's, else 1):
        a (periods * period, n_inputs) float64 array, the samples `msid excite --csv` writes."""
        if periods is None:
            periods = self.periods or 1
        return self._impl.samples(_uint(experiment, "experiment"), _uint(periods, "periods"))

    def save(self, path: PathLike) -> None:
        """Write the design as an msid-design/1 file (atomic), as `msid excite -o` does."""
        self._impl.save(os.fspath(path))

    def __repr__(self):
        b = self.bins
        return (f"<msid.Design P = {self.period}, {self.n_lines} lines (bins {b[0]}..{b[-1]}), "
                f"{self.n_inputs} input(s) x {self.n_experiments} experiment(s), max cond {self.cond_max:.4g}>")


def design(period: int, lines: Optional[Bins] = None, *, omega: Optional[Sequence[float]] = None,
           sample_time: Optional[float] = None, amplitudes: Union[float, Sequence[float], None] = None,
           phases: str = "random", seed: int = 1, inputs: int = 1, experiments: Optional[int] = None,
           pattern: str = "dft", periods: int = 8) -> "Design":
    """A multisine design with the options of `msid excite`: `lines` (bins, or msid's string form
    "1:200") or `omega` (rad/s) with `sample_time` (s); amplitudes (one value, one per line, or
    inputs x lines), phases "random" (seeded) or "schroeder", inputs and experiments (default = inputs),
    pattern "dft" or "hadamard", periods (recommended per experiment). Returns an msid.Design."""
    om = [] if omega is None else [_float(w, "omega") for w in np.asarray(omega, dtype=float).reshape(-1)]
    amp = [] if amplitudes is None else [_float(x, "amplitudes") for x in np.asarray(amplitudes, dtype=float).reshape(-1)]
    return Design(_ext().design(_uint(period, "period"), [] if lines is None else _uint_list(lines, "lines"), om,
                                0.0 if sample_time is None else _float(sample_time, "sample_time"), amp, str(phases),
                                int(seed), _uint(inputs, "inputs"), 0 if experiments is None else _uint(experiments, "experiments"),
                                str(pattern), _uint(periods, "periods")))


def read_design(path: PathLike) -> "Design":
    """Read an msid-design/1 file (OSError if it cannot be read, ValueError if it is not a valid design)."""
    return Design(_ext().read_design(os.fspath(path)))
