"""msid in process, over the C++ libraries of the msid command line (the compiled module msid._msid):
the FRF of samples held in NumPy arrays, one function per estimator (msid.frf: periodic records;
msid.lpm, msid.etfe: records of any input), a measurement fed block by block (msid.Measurement), a
device measured (msid.measure), excitation designs (msid.design, msid.read_design), fits (msid.fit)
and exports for other tools (msid.export). The same samples give the same bits as `msid frf`; errors
are msid's messages (ValueError; OSError for files). docs/python.md.

    d = msid.design(period=4096, lines="1:200", inputs=2)
    u = d.samples(experiment=0, periods=64)            # (64 * 4096, 2): drive the plant with it
    f = msid.frf([rec0, rec1], design=d)                 # rec: rows = samples, columns u1, u2, y1, y2
    f.G, f.cov, f.dof                                    # msid.FRF, as read_frf gives it

msid._msid is loaded on the first call that needs it (msid._compiled).
"""
import os
import warnings
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from ._args import (Bins, _below_nyquist, _column_spec, _float, _real_samples, _records, _uint,  # noqa: F401
                    _uint_list)
from ._compiled import ext as _ext
from .files import write_frf, write_model
from .types import FRF, Model, _frf_json, frf_from_doc

PathLike = Union[str, "os.PathLike[str]"]

__all__ = ["frf", "lpm", "etfe", "Measurement", "measure", "MeasurementInterrupted", "Design", "design",
           "read_design", "fit", "export", "NoteWarning", "ConvergenceWarning"]


class NoteWarning(UserWarning):
    """A note msid prints beside a result (a start-up transient, samples after the last whole period, distortion)."""


class ConvergenceWarning(UserWarning):
    """A fit whose iterations ran out before convergence (`msid fit` exits with status 3); the model is
    kept and marked "converged": false."""


class MeasurementInterrupted(KeyboardInterrupt):
    """Ctrl-C (KeyboardInterrupt) during msid.measure: .frf is the FRF of every complete period
    measured before it (meta["complete"] is False), as `msid measure` keeps it on Ctrl-C.

        try:
            f = msid.measure("modbus-tcp://192.168.1.20", design=d)
        except msid.MeasurementInterrupted as stop:
            f = stop.frf
    """

    def __init__(self, message, frf):
        super().__init__(message)
        self.frf = frf


def _options(skip_periods, fs, detect_lines, transient, alpha, dft, period=None):
    """The estimating options the extension shares between msid.frf and Measurement; those at their
    default are left out, as options not given on the command line (direct refuses the others).
    `period`: the design's or the given one, if known (detection lines beyond it are refused unexpanded)."""
    if (type(skip_periods) is int and skip_periods == 0 and fs is None and detect_lines is None
            and type(transient) is str and transient == "flag" and type(alpha) is float and alpha == 0.01
            and type(dft) is str and dft == "auto"):
        return {}   # every option at its default: nothing to check or pass on
    o = {"skip_periods": _uint(skip_periods, "skip_periods"),
         "fs": None if fs is None else _float(fs, "fs"),
         "detect_lines": None if detect_lines is None else _uint_list(detect_lines, "detect_lines",
                                                                      _below_nyquist(period)),
         "transient": str(transient), "alpha": _float(alpha, "alpha"), "dft": str(dft)}
    default = {"transient": "flag", "alpha": 0.01, "dft": "auto"}
    return {k: v for k, v in o.items() if v is not None and default.get(k) != v}


def _design_arg(design):
    if design is None or isinstance(design, Design):
        return design
    if isinstance(design, (str, os.PathLike)):
        return read_design(design)
    raise TypeError(f"design must be an msid.Design or a design file's path, not {type(design).__name__}")


def _notes(res):
    """msid's notes in Python's words, as its errors are raised: a note the libraries share with the command
    line names its flags ("use --skip-periods"), which Python takes as keywords."""
    words = _ext()._python_words
    return [words(n) for n in res["notes"]]


def _result(res, where):
    a = res["frf"]   # the arrays of the FRF document (msid._msid: frf_to_py), numbers with their bits
    f = FRF._of_arrays(a)
    f.notes = _notes(res)
    f.reports = list(res.get("reports", []))
    for n in f.notes:
        warnings.warn(n, NoteWarning, stacklevel=3)
    return f


# ---- the FRF of records: one function per estimator ----

Records = Any   # one 2-D array or DataFrame per experiment (or one alone), or experiment files' paths
Columns = Union[str, Dict[str, str], None]


def frf(records: Records, *, design: Union["Design", PathLike, None] = None, period: Union[int, str, None] = None,
        lines: Optional[Bins] = None, skip_periods: int = 0, fs: Optional[float] = None, columns: Columns = None,
        n_inputs: Optional[int] = None, detect_lines: Optional[Bins] = None, transient: str = "flag",
        alpha: float = 0.01, dft: str = "auto", block: Optional[int] = None, realisations: Optional[int] = None,
        direct: bool = False, method: str = "periodic", **estimator: Any) -> FRF:
    """The FRF of periodic (multisine) records, as `msid frf` estimates it from files: the same request
    gives the same bits (docs/statistics.md for the estimator and its exact statistics). For records of
    any input (noise, sweeps, steps) see msid.lpm and msid.etfe.

    records: one experiment's samples, or a list with one per experiment. Each is a 2-D array (rows are
      samples, periods back to back; columns u1..u_nu then y1..y_ny, numbered from 1 for `columns`) or a
      pandas DataFrame (its column names, u1.. y1.. or mapped by `columns`). C-contiguous float64 arrays
      are read in place; other real dtypes and layouts are copied once. Or experiment files (a path, or a
      list of paths: CSV, .npy, .npz, .mat), read as `msid frf --experiment` reads them: a CSV record
      passes through the core block by block (with period or lines "auto" too: a first pass finds them),
      so a file far larger than memory is estimated in a few tens of MB (docs/records.md).
    design: an msid.Design or a design file (period, lines, inputs, experiments), or else
    period, lines: samples per period and excited bins; either may be "auto" (found from the inputs).
      lines takes integers or msid's string form ("1:200", "1,3,5:2:21").
    n_inputs: the number of input columns of a plain array (default: the design's).
    columns: which columns feed u1.., y1.. ("u1=Force,y1=Acc" or {"u1": "Force", "y1": "Acc"}), as --columns.
    skip_periods, fs, detect_lines, transient ("flag", "drop", "off"), alpha, dft ("auto", "stream",
      "fft"), block, realisations, direct: the options of `msid frf` (msid frf --help).
    method: "periodic" (default). method="lpm" or "etfe" with that estimator's keywords is msid.lpm or
      msid.etfe, kept for older callers; a keyword of another estimator is a TypeError, as Python
      gives for any unknown keyword.

    Returns an msid.FRF; its .notes are msid's notes (also issued as NoteWarning) and .reports what
    period/lines "auto" found. Raises ValueError with msid's message for bad records or options.
    """
    if method != "periodic":
        return _frf_by_method(records, method, estimator, design=design, period=period, lines=lines,
                              skip_periods=skip_periods, fs=fs, columns=columns, n_inputs=n_inputs,
                              detect_lines=detect_lines, transient=transient, alpha=alpha, dft=dft, block=block,
                              realisations=realisations, direct=direct)
    if estimator:
        raise TypeError(f"frf() got an unexpected keyword argument '{next(iter(estimator))}'")
    D = _design_arg(design)
    if n_inputs is None and D is not None:
        n_inputs = D.n_inputs
    if isinstance(period, str) and period == "auto":
        P = None
    elif period is not None:
        P = _uint(period, "period")
    else:
        P = None if D is None else D.period
    opts = _options(skip_periods, fs, detect_lines, transient, alpha, dft, P)
    if isinstance(period, str) and period == "auto":
        opts["auto_period"] = True
    elif period is not None:
        opts["period"] = P
    if isinstance(lines, str) and lines == "auto":
        opts["auto_lines"] = True
    elif lines is not None:
        opts["lines"] = _uint_list(lines, "lines", _below_nyquist(P))
    if block is not None:
        opts["block"] = _uint(block, "block")
    if realisations is not None:
        opts["realisations"] = _uint(realisations, "realisations")
    opts["direct"] = bool(direct)
    paths = _file_paths(records)
    if paths is not None:
        if n_inputs is not None and design is None:
            raise ValueError("n_inputs applies to plain arrays: a file names its columns (u1.., y1.. or columns=)")
        spec = columns if isinstance(columns, str) else ",".join(f"{k}={v}" for k, v in (columns or {}).items())
        return _result(_ext().frf_files(paths, spec, opts, None if D is None else D._impl), "msid.frf")
    arrays, names, colnames, nus = _records(records, columns, n_inputs)
    return _result(_ext().frf(arrays, names, colnames, nus, opts, None if D is None else D._impl), "msid.frf")


def _frf_by_method(records, method, estimator, **periodic):
    """msid.frf(method="lpm" | "etfe", ...): that estimator's function on the keywords given. The
    periodic estimator's keywords given a value of their own are passed on too, so that the call is
    refused in Python's words for an unknown keyword, naming the function that refuses it."""
    est = {"lpm": lpm, "etfe": etfe}.get(method) if isinstance(method, str) else None
    if est is None:
        raise ValueError(f"method must be 'periodic', 'lpm' or 'etfe', not {method!r}")
    defaults = {"design": None, "period": None, "lines": None, "skip_periods": 0, "detect_lines": None,
                "transient": "flag", "alpha": 0.01, "dft": "auto", "block": None, "realisations": None,
                "direct": False, "fs": None, "columns": None, "n_inputs": None}
    given = {k: v for k, v in periodic.items()
             if k in ("fs", "columns", "n_inputs") or not (v is defaults[k] or (type(v) is type(defaults[k])
                                                                             and v == defaults[k]))}
    return est(records, **given, **estimator)


def lpm(records: Records, *, order: Optional[int] = None, window: Optional[int] = None,
        band: Union[str, Tuple[float, float], None] = None, reference: Any = None, fs: Optional[float] = None,
        columns: Columns = None, n_inputs: Optional[int] = None, threads: Optional[int] = None) -> FRF:
    """The FRF of records of any input (noise, sweeps, steps) by the local polynomial method, as
    `msid frf --method lpm` (docs/statistics.md, "The local polynomial method").

    records, columns, n_inputs, fs: as msid.frf (fs: the sample rate in Hz, for the frequency axis and band).
    order: the local polynomials' degree R (0..8, default 2); window: the half-width W in bins (default
      the smallest the order and the inputs allow).
    band: (f1, f2) or "F1:F2": Hz with fs, else cycles/sample; only the lines inside are estimated.
    reference: for noisy inputs or a closed loop, the reference signal of each input, as file or
      DataFrame column names ("r1=Cmd" or ["Cmd"]) or samples (one n_rows x n_inputs array per record).
    threads: worker threads (1..64; default: msid's).

    Returns an msid.FRF (meta["method"] == "lpm"); ValueError with msid's message for bad records or options.
    """
    opts: Dict[str, Any] = {"method": "lpm"}
    for k, v in (("order", order), ("window", window), ("threads", threads)):
        if v is not None:
            opts[k] = _uint(v, k)
    return _frf_est(records, opts, band=band, reference=reference, fs=fs, columns=columns, n_inputs=n_inputs)


def etfe(records: Records, *, period: int, delta: Optional[float] = None, gstar: Optional[float] = None,
         band: Union[str, Tuple[float, float], None] = None, fs: Optional[float] = None, columns: Columns = None,
         n_inputs: Optional[int] = None, threads: Optional[int] = None) -> FRF:
    """The empirical transfer function estimate of records of any input, with its finite-sample bound,
    as `msid frf --method etfe` (docs/statistics.md, "The ETFE").

    records, columns, n_inputs, fs: as msid.frf.
    period: the input's period M in samples (required).
    delta: the bound's risk level in (0, 1); gstar: a bound on the plant's gain (>= 0), as --delta and
      --gstar.
    band: (f1, f2) or "F1:F2": Hz with fs, else cycles/sample. threads: worker threads (1..64).

    Returns an msid.FRF (meta["method"] == "etfe"); ValueError with msid's message for bad records or options.
    """
    opts: Dict[str, Any] = {"method": "etfe", "period": _uint(period, "period")}
    if threads is not None:
        opts["threads"] = _uint(threads, "threads")
    for k, v in (("delta", delta), ("gstar", gstar)):
        if v is not None:
            opts[k] = _float(v, k)
    return _frf_est(records, opts, band=band, reference=None, fs=fs, columns=columns, n_inputs=n_inputs)


def _band(band):
    """band as (f1, f2, text): a pair of numbers or msid's "F1:F2"."""
    if isinstance(band, str):
        parts = band.split(":")
        if len(parts) != 2:
            raise ValueError(f"band must be (f1, f2) or 'F1:F2' (got '{band}')")
        try:
            f1, f2 = float(parts[0]), float(parts[1])
        except ValueError:
            raise ValueError(f"band: '{band}' is not F1:F2 (two numbers)") from None
        return (_float(f1, "band"), _float(f2, "band"), band)
    try:
        f1, f2 = band
    except (TypeError, ValueError):
        raise ValueError(f"band must be (f1, f2) or 'F1:F2', not {band!r}") from None
    f1, f2 = _float(f1, "band"), _float(f2, "band")
    return (f1, f2, f"{f1:g}:{f2:g}")


def _reference_names(reference):
    """reference as column names in order r1..: "r1=Cmd,r2=..." (or "r1,r2"), or a list of names."""
    if isinstance(reference, str):
        return list(_ext().parse_reference(reference))
    names = [str(n) for n in reference]
    if not names:
        raise ValueError("reference: no column named")
    return names


def _frf_est(records, opts, *, band, reference, fs, columns, n_inputs):
    """msid.lpm and msid.etfe on arrays or files: `opts` holds the estimator's checked keywords."""
    opts["fs"] = None if fs is None else _float(fs, "fs")
    if band is not None:
        opts["band"] = _band(band)
    paths = _file_paths(records)
    if paths is not None:
        if n_inputs is not None:
            raise ValueError("n_inputs applies to plain arrays: a file names its columns (u1.., y1.. or columns=)")
        if reference is not None:
            opts["reference"] = _reference_names(reference)
        return _result(_ext().frf_est_files(paths, _column_spec(columns), opts), "msid.frf")
    arrays, names, colnames, nus = _records(records, columns, n_inputs)
    refs = []
    if reference is not None:
        items = list(records) if isinstance(records, (list, tuple)) else [records]
        if isinstance(reference, str) or (isinstance(reference, (list, tuple)) and reference
                                          and all(isinstance(n, str) for n in reference)):
            cols = _reference_names(reference)   # columns of each DataFrame
            for k, r in enumerate(items):
                if not (hasattr(r, "columns") and hasattr(r, "iloc")):
                    raise ValueError(f"reference names columns ({', '.join(cols)}): records[{k}] is an array "
                                     "without column names; give the reference samples (one array per record)")
                missing = [c for c in cols if c not in r.columns]
                if missing:
                    raise ValueError(f"'records[{k}]' has no column '{missing[0]}' (reference)")
                refs.append(_real_samples(r[cols].to_numpy(), f"reference[{k}]"))
        else:
            ritems = list(reference) if isinstance(reference, (list, tuple)) else [reference]
            if len(ritems) != len(items):
                raise ValueError(f"reference: {len(ritems)} array(s) for {len(items)} record(s); give one per record")
            for k, a in enumerate(ritems):
                a = np.asarray(a)
                if a.ndim == 1:
                    a = a[:, None]
                if a.ndim != 2:
                    raise ValueError(f"'reference[{k}]': a {a.ndim}-dimensional array; expected n_rows x n_inputs")
                refs.append(_real_samples(a, f"reference[{k}]"))
    return _result(_ext().frf_est(arrays, names, colnames, nus, opts, refs), "msid.frf")


def _file_paths(records) -> Optional[List[str]]:
    """records as experiment files: a path or a list of paths (str or os.PathLike); None for samples."""
    if type(records) is np.ndarray:
        return None
    one = isinstance(records, (str, os.PathLike))
    many = isinstance(records, (list, tuple)) and len(records) > 0 and \
        all(isinstance(r, (str, os.PathLike)) for r in records)
    if not (one or many):
        return None
    return [os.fspath(r) for r in ([records] if one else records)]


# ---- a measurement fed block by block ----

class Measurement:
    """The FRF job fed with samples as they arrive (a device callback: python-can, sounddevice, nidaqmx).

        m = msid.Measurement(design=d, skip_periods=2)
        m.push(block, experiment=0)    # rows [u1..u_nu, y1..y_ny], any number of rows, experiments in turn
        m.progress                     # whole periods received per experiment
        f = m.frf()                    # msid.FRF

    Any block sizes give the same bits, equal to msid.frf on the whole records. Experiments are measured
    one after another: pushing to another experiment closes the open one. The transient test keeps up
    to `max_periods` periods per experiment (default 4 x the design's periods + 8; a period more is an
    error), at most 32 MiB of them: beyond that, later periods are used untested (docs/statistics.md
    "Long records"); transient="off" keeps none. Options as msid.frf.
    """

    def __init__(self, design: Union["Design", PathLike], *, skip_periods: int = 0, fs: Optional[float] = None,
                 detect_lines: Optional[Bins] = None, transient: str = "flag", alpha: float = 0.01, dft: str = "auto",
                 max_periods: Optional[int] = None) -> None:
        D = _design_arg(design)
        if D is None:
            raise ValueError("a Measurement needs a design (period, lines, inputs and experiments)")
        self.design = D
        opts = _options(skip_periods, fs, detect_lines, transient, alpha, dft, D.period)
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

    def __repr__(self) -> str:
        return (f"<msid.Measurement P = {self.design.period}, {self.design.n_lines} lines, "
                f"{self.design.n_experiments} experiment(s), periods received {self.progress}>")


# ---- a device measured in process ----

def measure(device: str, design: Union["Design", PathLike], *, periods: Optional[int] = None, skip_periods: int = 0,
            rate: float = 0, fs: Optional[float] = None, scale: float = 0.001, timeout: float = 10.0,
            detect_lines: Optional[Bins] = None, transient: str = "flag", alpha: float = 0.01, dft: str = "auto",
            progress: Optional[Callable[[Dict[str, Any]], None]] = None, on_device: bool = False,
            stream_check: bool = False, map: Optional[PathLike] = None, realtime: bool = True) -> FRF:
    """Measure a device as `msid measure` does, in process: identify it, upload the design as
    parameters (the device regenerates the multisine with msid's core), run every experiment, and
    return the FRF of what was measured (docs/measure.md). No process is started.

    device: a device URI: "modbus-tcp://HOST[:PORT][?unit=N]", "modbus-rtu:///dev/ttyX?baud=N[&parity=E...]"
      or "can://IFACE[?fd=1&base=0x200]" (SocketCAN).
    design: an msid.Design or a design file; its inputs must be the device's.
    periods: periods per experiment (default: the design's, else 8); skip_periods: leading periods left
      out (transient). rate: the device's sample rate in whole Hz (0: as fast as the link carries; a rate
      also sets the frequency axis of a DT design); fs: the axis's rate for an unpaced device.
    scale: value of one int16 step; timeout: seconds without a new sample before giving up.
    detect_lines, transient, alpha, dft: as msid.frf.
    progress: called with a dict (experiment, experiments, periods, periods_target, periods_total,
      rejected, samples_lost, link_errors, snr_db, eta_s) after every event and at most every 20 ms
      between them, from the calling thread. An exception it raises ends the run and is raised again.

    on_device: the device estimates (extension estimate/1, as `msid modbus|can measure --on-device`):
      no sample crosses the link, msid reads each line's G, covariances and dof, bit for bit what the
      host would compute (no detect_lines; dft is the device's streaming path). stream_check: the device
      also streams its samples, the host estimates from them and both must agree bit for bit (OSError
      otherwise); the host's FRF is .host_frf of the result. A stop while the device estimates leaves no
      FRF (KeyboardInterrupt); progress then sees only which experiment runs.

    map: a device description (msid-device/1, docs/devices.md) for a device that does not run msid's
      firmware (a PLC, a drive): msid then generates the excitation and writes it to the description's
      drive channels once per tick at `rate` (required, any positive number of Hz), reads the measure
      channels in the same tick, checks every value against the limits before writing anything, and
      writes the safe values on every way out, as `msid measure --map` does. The design has one input per
      drive channel. scale, fs and on_device do not apply; realtime=False leaves the scheduling alone
      (no SCHED_FIFO, no locked memory). The `acquisition` block has the tick loop's `timing`.
      With the closed-loop preset (preset = "csv-loop", a CiA 402 drive's velocity loop) the FRF returned
      is the plant through the reference (frf.json of the command line) and .reference_frf is the FRF from
      the reference to every measured signal (its reference.json: the torque demand's row C S, the
      velocity's z T); .reference_frf is None for every other run.

    Returns an msid.FRF with the `acquisition` block in .meta (counts of samples, losses, retries).
    Ctrl-C ends the run after the complete periods and raises msid.MeasurementInterrupted (a
    KeyboardInterrupt) holding their FRF; a Ctrl-C before every experiment has 2 periods raises a plain
    KeyboardInterrupt. Raises OSError when the device cannot be reached or fails, ValueError for a bad
    request. The GIL is released while the device runs.
    """
    D = _design_arg(design)
    if D is None:
        raise ValueError("msid.measure needs a design (msid.design or a design file)")
    if map is not None:
        return _measure_mapped(device, D, map, periods, skip_periods, rate, fs, scale, timeout, detect_lines,
                               transient, alpha, dft, progress, on_device, realtime)
    opts = _options(skip_periods, fs, detect_lines, transient, alpha, dft, D.period)
    if fs is not None and rate:
        raise ValueError("fs is for an unpaced device; rate already sets the sample rate")
    r = _float(rate, "rate")
    if not (0 <= r <= 4e9 and r == int(r)):
        raise ValueError(f"rate must be a whole number of Hz (0: unpaced), not {rate!r}")
    if progress is not None and not callable(progress):
        raise TypeError(f"progress must be callable, not {type(progress).__name__}")
    if stream_check and not on_device:
        raise ValueError("stream_check applies to on_device=True (the device estimates and streams)")
    if on_device and opts.get("dft") is not None:
        raise ValueError("dft does not apply to on_device=True (the device's streaming DFT path is used)")
    K = (D.periods or 8) if periods is None else _uint(periods, "periods")
    res = _ext().measure(str(device), D._impl, opts, K, int(r), _float(scale, "scale"), _float(timeout, "timeout"),
                         progress, bool(on_device), bool(stream_check))
    f = _result(res, "msid.measure")
    f.reference_frf = None   # only the closed-loop preset of a described device measures through a reference
    if "host" in res:
        f.host_frf = FRF._of_arrays(res["host"])
    if res["interrupted"]:
        raise MeasurementInterrupted(f"msid.measure: interrupted: {res['summary']}", f)
    return f


def _measure_mapped(device, D, map, periods, skip_periods, rate, fs, scale, timeout, detect_lines, transient,
                    alpha, dft, progress, on_device, realtime) -> FRF:
    """msid.measure(..., map=...): a described device with host-timed excitation."""
    if not isinstance(map, (str, os.PathLike)):
        raise TypeError(f"map must be a path to a device description, not {type(map).__name__}")
    if fs is not None:
        raise ValueError("fs does not apply with map: rate is the sample rate")
    if scale != 0.001:
        raise ValueError("scale does not apply with map: the description scales each channel")
    if on_device:
        raise ValueError("on_device does not apply with map: the host excites and estimates")
    r = _float(rate, "rate")
    if not (0 < r <= 100000):
        raise ValueError(f"rate must be in (0, 100000] Hz with map (the host ticks at that rate), not {rate!r}")
    if progress is not None and not callable(progress):
        raise TypeError(f"progress must be callable, not {type(progress).__name__}")
    opts = _options(skip_periods, None, detect_lines, transient, alpha, dft, D.period)
    K = (D.periods or 8) if periods is None else _uint(periods, "periods")
    res = _ext().measure_mapped(str(device), D._impl, opts, K, r, _float(timeout, "timeout"), progress,
                                os.fspath(map), bool(realtime))
    f = _result(res, "msid.measure")
    f.reference_frf = _reference_frf(res)
    if res["interrupted"]:
        raise MeasurementInterrupted(f"msid.measure: interrupted: {res['summary']}", f)
    return f


def _reference_frf(res) -> Optional[FRF]:
    """The reference path of a run (the closed-loop preset csv-loop): the FRF from the reference to every
    measured signal, what `msid measure --map` writes as reference.json, converted as read_frf converts
    that file (its notes are the run's, already warned of); None for a run without a reference path."""
    doc = res.get("reference")
    if doc is None:
        return None
    f = frf_from_doc(doc, "msid.measure's reference path")
    f.notes = _notes(res)
    return f


# ---- files for other tools ----

def export(src: Union["FRF", "Model", PathLike], out: PathLike, *, known_input: bool = False) -> None:
    """An FRF or a model for other tools, as `msid export` writes it: `out` ending in .csv (an FRF: G, the
    standard deviation of each element, dof, frequencies) or .mat (an FRF in the shape of MATLAB's
    idfrd, its CovarianceData scaled so that showConfidence draws the exact 95% regions; a model as the
    A, B, C, D, Ts and names that ss and idss take). src: a file, or an msid.FRF / msid.Model (written
    to a temporary file beside `out` first). known_input: the known-input covariance of an FRF.
    Nothing is written when it fails: ValueError for what cannot be exported, OSError for files."""
    out = os.fspath(out)
    ext = os.path.splitext(out)[1].lower()
    if ext not in (".csv", ".mat"):
        raise ValueError(f"'{out}': give a .csv or .mat file to export to")
    if isinstance(src, (FRF, Model)):
        import tempfile
        fd, tmp = tempfile.mkstemp(suffix=".json", dir=os.path.dirname(os.path.abspath(out)))
        os.close(fd)
        name = "(in-memory FRF)" if isinstance(src, FRF) else "(in-memory model)"
        try:
            (write_frf if isinstance(src, FRF) else write_model)(tmp, src)
            _ext().export_file(tmp, out, ext == ".csv", bool(known_input))
        except (ValueError, OSError) as e:   # the message names the object, not the temporary file
            if isinstance(e, OSError) and e.errno:
                raise type(e)(e.errno, str(e.strerror).replace(tmp, name)) from None
            raise type(e)(str(e).replace(tmp, name)) from None
        finally:
            os.remove(tmp)
        return
    _ext().export_file(os.fspath(src), out, ext == ".csv", bool(known_input))


# ---- designs ----

def _machine_memory():
    """Bytes of physical memory (0 when the system does not say)."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 0


class Design:
    """An excitation design (msid-design/1): built by msid.design, read by msid.read_design."""

    def __init__(self, impl: Any) -> None:
        self._impl = impl   # msid._msid's design

    @property
    def period(self) -> int:
        """Samples per period."""
        return self._impl.period

    @property
    def n_inputs(self) -> int:
        return self._impl.n_inputs

    @property
    def n_experiments(self) -> int:
        return self._impl.n_experiments

    @property
    def cond_max(self) -> float:
        """The largest condition number over the lines."""
        return self._impl.cond_max

    @property
    def bins(self) -> np.ndarray:
        """Excited DFT bins (the line of each frequency)."""
        return np.array(self._impl.bins, dtype=int)

    @property
    def n_lines(self) -> int:
        return len(self._impl.bins)

    @property
    def doc(self) -> Dict[str, Any]:
        """The msid-design/1 document (a dict)."""
        return self._impl.doc

    @property
    def periods(self) -> Optional[int]:
        """Recommended periods per experiment (None if the design does not say)."""
        return self._impl.doc.get("periods")

    def _experiment(self, experiment):
        e = _uint(experiment, "experiment")
        if e >= self.n_experiments:
            raise ValueError(f"experiment {e}: the design has {self.n_experiments} (counted from 0)")
        return e

    def crest_factor(self, experiment: int, inp: int) -> float:
        """max|u|/rms(u) of input `inp` in `experiment` (both from 0)."""
        e, i = self._experiment(experiment), _uint(inp, "input")
        if i >= self.n_inputs:
            raise ValueError(f"input {i}: the design has {self.n_inputs} (counted from 0)")
        return self._impl.crest_factor(e, i)

    def samples(self, experiment: int = 0, periods: Optional[int] = None) -> np.ndarray:
        """The inputs of `experiment` (from 0) over `periods` periods (default: the design's, else 1):
        a (periods * period, n_inputs) float64 array, the samples `msid excite --csv` writes. An array
        larger than this machine's memory is refused (ValueError) before it is allocated."""
        if periods is None:
            periods = self.periods or 1
        e, K = self._experiment(experiment), _uint(periods, "periods")
        need = K * self.period * self.n_inputs * 8
        have = _machine_memory()
        if have and need > have:
            raise ValueError(f"periods = {K}: {K} x {self.period} samples x {self.n_inputs} input(s) take "
                             f"{need / 2 ** 30:.3g} GiB, more than this machine's memory ({have / 2 ** 30:.3g} GiB); "
                             "ask for fewer periods at a time")
        return self._impl.samples(e, K)

    def save(self, path: PathLike) -> None:
        """Write the design as an msid-design/1 file (atomic), as `msid excite -o` does."""
        self._impl.save(os.fspath(path))

    def __repr__(self) -> str:
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
    P = _uint(period, "period")
    return Design(_ext().design(P, [] if lines is None else _uint_list(lines, "lines", _below_nyquist(P)), om,
                                0.0 if sample_time is None else _float(sample_time, "sample_time"), amp, str(phases),
                                _uint(seed, "seed", 2 ** 64 - 1), _uint(inputs, "inputs"), 0 if experiments is None else _uint(experiments, "experiments"),
                                str(pattern), _uint(periods, "periods")))


def read_design(path: PathLike) -> "Design":
    """Read an msid-design/1 file (OSError if it cannot be read, ValueError if it is not a valid design)."""
    return Design(_ext().read_design(os.fspath(path)))


# ---- fits and validation ----

def _order(order):
    if order is None:
        return None
    if isinstance(order, str):
        return order
    if isinstance(order, range):
        if order.step != 1 or len(order) == 0:
            raise ValueError(f"order range must be consecutive and non-empty, not {order!r}")
        return f"{order.start}:{order.stop - 1}"
    return str(_uint(order, "order"))


_FRF_FIT_OPTIONS = {"nd", "nn", "domain", "weight", "noise_var", "r", "stable", "allow_unstable", "no_d", "pins", "start",
                    "max_iter", "delta", "beta", "feedthrough", "param", "refine", "weight_smooth"}
_CISSIM_OPTIONS = {"period", "lines", "design", "max_order", "block_rows", "lags", "skip_periods", "reduced", "no_d",
                   "no_covariance", "unweighted", "allow_unstable", "isp", "refine", "columns", "n_inputs"}
_MULTI_OPTIONS = {"order_rule", "noise_ar", "noise_ar_order", "input_noise_ratio", "fs", "feedthrough", "start",
                  "max_iter", "columns", "n_inputs", "noise_records"}


def _frf_fit_opts(method, order, o):
    u = lambda k: None if o.get(k) is None else _uint(o[k], k)          # noqa: E731
    f = lambda k: None if o.get(k) is None else _float(o[k], k)         # noqa: E731
    t = lambda k: None if o.get(k) is None else str(o[k])               # noqa: E731
    pins = o.get("pins", ())
    return {"method": method, "order": _order(order), "nd": u("nd"), "nn": u("nn"), "domain": t("domain"),
            "weight": t("weight"), "noise_var": f("noise_var"), "r": u("r"),
            "stable": bool(o.get("stable", False)), "allow_unstable": bool(o.get("allow_unstable", False)),
            "no_d": bool(o.get("no_d", False)), "pins": [str(p) for p in ([pins] if isinstance(pins, str) else pins)],
            "start": None if o.get("start") is None else os.fspath(o["start"]), "max_iter": u("max_iter"),
            "delta": f("delta"), "beta": f("beta"), "feedthrough": t("feedthrough"), "param": t("param"),
            "refine": t("refine"), "weight_smooth": u("weight_smooth")}


def _cissim_opts(order, o):
    D = _design_arg(o.get("design"))
    period, lines = o.get("period"), o.get("lines")
    if D is not None:
        if period is not None or lines is not None:
            raise ValueError("give either design or period/lines, not both")
        period, lines = D.period, list(D.bins)
    u = lambda k: None if o.get(k) is None else _uint(o[k], k)          # noqa: E731
    return {"period": None if period is None else _uint(period, "period"),
            "lines": None if lines is None else _uint_list(lines, "lines", _below_nyquist(
                period if type(period) is int else None)),
            "order": None if order is None else _uint(order, "order"), "max_order": u("max_order"),
            "block_rows": u("block_rows"), "lags": u("lags"), "skip_periods": _uint(o.get("skip_periods", 1), "skip_periods"),
            "reduced": bool(o.get("reduced", False)), "no_d": bool(o.get("no_d", False)),
            "no_covariance": bool(o.get("no_covariance", False)), "unweighted": bool(o.get("unweighted", False)),
            "allow_unstable": bool(o.get("allow_unstable", False)), "isp": str(o.get("isp", "auto")),
            "refine": str(o.get("refine", "ml"))}, (None if D is None else D.n_inputs)


def _multi_opts(order, o):
    ar = o.get("noise_ar")
    return {"order": _order(order), "order_rule": None if o.get("order_rule") is None else str(o["order_rule"]),
            "noise_ar": None if ar is None else [_float(c, "noise_ar") for c in np.asarray(ar, dtype=float).reshape(-1)],
            "noise_ar_order": None if o.get("noise_ar_order") is None else _uint(o["noise_ar_order"], "noise_ar_order"),
            "input_noise_ratio": None if o.get("input_noise_ratio") is None else _float(o["input_noise_ratio"], "input_noise_ratio"),
            "fs": None if o.get("fs") is None else _float(o["fs"], "fs"),
            "feedthrough": str(o.get("feedthrough", "no")), "start": str(o.get("start", "auto")),
            "max_iter": None if o.get("max_iter") is None else _uint(o["max_iter"], "max_iter"),
            "columns": _column_spec(o.get("columns")) or None}


def fit(data: Any, method: str = "subspace", order: Union[int, str, range, None] = None, **options: Any) -> Model:
    """A parametric model, as `msid fit` fits it from files: the same data and options give the same model
    document (docs/fitting.md for the methods, their defaults and options).

    method "subspace", "lmfd", "ml": data is an msid.FRF (msid.frf, read_frf) or an msid-frf/1 file's path.
      order: an integer, "auto" or a range "a:b" / "a:step:b" (also range(a, b + 1)): the order scan fits every
      order and keeps one, with the scan in model.stabilisation. None: the method's default (ml: auto;
      subspace: from the singular values). Options: nd, nn (LMFD degrees), domain ("dt", "ct"), weight ("cov",
      "known-input", "none"), noise_var, r, stable, allow_unstable, no_d, pins (["N0=0", ...]), start, max_iter,
      delta, beta, feedthrough ("auto", "yes", "no"), param ("poles", "lmfd"), refine ("ml", "none" or a number
      of steps), weight_smooth.
    method "cissim": data is periodic time records as msid.frf takes them (one 2-D array or DataFrame per
      experiment; columns u1.., y1..). Options: design, or period and lines; max_order, block_rows, lags,
      skip_periods (default 1), reduced, no_d, no_covariance, unweighted, allow_unstable, isp, refine,
      columns, n_inputs.
    method "multi": data is records of any lengths (inputs may be left out: free responses, n_inputs=0).
      order is required. Options: order_rule ("mdl", "aic"), noise_ar (c1..cp), noise_ar_order,
      noise_records (noise-only records, same columns), input_noise_ratio, fs, feedthrough ("no", "yes"),
      start ("auto", "kung", "prony", "sm"), max_iter, columns, n_inputs.
    The option names are `msid fit`'s with underscores for dashes.

    Returns an msid.Model (model.notes: msid's notes, also issued as NoteWarning). Iterations that ran out
    give the best iterate marked "converged": false and a ConvergenceWarning (`msid fit` exits with 3).
    Raises ValueError with msid's message when the data cannot give the model or an option is bad, OSError
    for a file it cannot read, TypeError for an option the method does not take.
    """
    method = str(method)
    allowed = {"subspace": _FRF_FIT_OPTIONS, "lmfd": _FRF_FIT_OPTIONS, "ml": _FRF_FIT_OPTIONS,
               "cissim": _CISSIM_OPTIONS, "multi": _MULTI_OPTIONS}.get(method)
    if allowed is None:
        raise ValueError(f"method must be one of 'subspace', 'lmfd', 'ml', 'cissim', 'multi', not '{method}'")
    bad = sorted(set(options) - allowed)
    if bad:
        raise TypeError(f"msid.fit(method='{method}') takes no option {', '.join(bad)} "
                        f"(its options: {', '.join(sorted(allowed))})")
    if method == "cissim":
        opts, nu = _cissim_opts(order, options)
        n_inputs = options.get("n_inputs", nu)
        recs = _records(data, options.get("columns"), n_inputs)
        res = _ext().fit_records(method, recs, ([], [], [], []), opts)
    elif method == "multi":
        opts = _multi_opts(order, options)
        recs = _records(data, options.get("columns"), options.get("n_inputs"), free=True)
        nr = options.get("noise_records")
        noise = ([], [], [], []) if nr is None else _records(nr, options.get("columns"), options.get("n_inputs"),
                                                             free=True, label="noise_records")
        res = _ext().fit_records(method, recs, noise, opts)
    else:
        text, name = _frf_json(data, "frf")
        res = _ext().fit(text, name, _frf_fit_opts(method, order, options))
    m = Model(res["model"])
    m.notes = _notes(res)
    for n in m.notes:
        warnings.warn(n, NoteWarning, stacklevel=2)
    if not res["converged"]:
        why = _ext()._python_words(res["not_converged"])   # msid's "...: wrote the best iterate to " (and the file's path)
        why = why[:why.rfind(": wrote")] if ": wrote" in why else why.rstrip()
        warnings.warn(why + ": the model is the best iterate, marked \"converged\": false", ConvergenceWarning,
                      stacklevel=2)
    return m


