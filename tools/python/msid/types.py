"""The data types of msid in Python: an FRF (msid-frf/1), a Model (msid-model/1) and what a model's
validation and modes report, as NumPy arrays with their document form (docs/frf-format.md,
docs/model-format.md). Nothing here needs the compiled module but Model.validate and Model.modes, which
run `msid validate` and `msid modes` in process.

    f.G: L x ny x nu complex, f.cov: L x g x g (g = ny nu), f.dof: L
    m.A, m.B, m.C, m.D; m.response(f) evaluates the model at f's lines

Conventions of the files, kept here: G[i][j] maps input j to output i; covariances are of vec(G),
which stacks the columns of G (G[i][j] has index i + ny*j); cov[a][b] = E[(v_a - E v_a) conj(v_b - E v_b)].
Every key of a document that these types do not turn into an array is kept (FRF.meta, FRF.line_extra,
Model.doc), so read -> write keeps the file valid for the msid-frf/1 and msid-model/1 schemas and for
`msid fit` / `msid validate`.
"""
import json
import math
import os
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from . import regions
from ._args import _file_text, _records, _uint
from ._compiled import ext as _ext

PathLike = Union[str, "os.PathLike[str]"]
ArrayLike = Any   # what np.asarray takes

__all__ = ["FRF", "Model", "Validation", "Modes", "FormatError"]

FRF_FORMAT = "msid-frf/1"
MODEL_FORMAT = "msid-model/1"
_LINE_ARRAYS = ("bin", "freq", "freq_hz", "omega", "real", "G", "cov", "dof", "cov_known_input", "dof_known_input")


class FormatError(ValueError):
    """A file that is not a valid msid document; the message names the file and the key."""


def _cmat(obj, shape, where):
    try:
        re = np.asarray(obj["re"], dtype=float)
        im = np.asarray(obj["im"], dtype=float)
    except (TypeError, KeyError, ValueError) as e:
        raise FormatError(f"{where}: expected a complex matrix {{re, im}} ({e})") from None
    if re.shape != tuple(shape) or im.shape != tuple(shape):
        raise FormatError(f"{where}: expected shape {tuple(shape)}, got re {re.shape} / im {im.shape}")
    return re + 1j * im


def _cmats(objs, shape, where, key):
    """One complex matrix {re, im} per line, stacked (L, *shape) by one NumPy call per part; when any
    is bad, the first bad one is named as _cmat names it."""
    shape = tuple(shape)
    try:
        re = np.array([o["re"] for o in objs], dtype=float)
        im = np.array([o["im"] for o in objs], dtype=float)
        if re.shape == (len(objs),) + shape and im.shape == re.shape:
            return re + 1j * im
    except (TypeError, KeyError, ValueError):
        pass
    for k, o in enumerate(objs):
        _cmat(o, shape, f"{where}: lines[{k}].{key}")
    raise FormatError(f"{where}: lines[*].{key}: expected shape {shape}")


def _cmat_json(a):
    a = np.asarray(a)
    return {"re": np.real(a).tolist(), "im": np.imag(a).tolist()}


def _rmat(obj, shape, where):
    a = np.asarray(obj, dtype=float)
    if shape is not None and a.size == 0 and 0 in shape:
        return np.zeros(shape)
    if shape is not None and a.shape != tuple(shape):
        raise FormatError(f"{where}: expected shape {tuple(shape)}, got {a.shape}")
    return a


def _unvec(v, ny, nu):
    """Per-element values of vec(G) (index i + ny*j) as ny x nu; leading axes are kept."""
    v = np.asarray(v)
    return np.swapaxes(v.reshape(v.shape[:-1] + (nu, ny)), -1, -2)


class FRF:
    """A frequency response with its uncertainty: an msid-frf/1 document as arrays (msid.frf, read_frf).

    Arrays (L lines, ny outputs, nu inputs, g = ny nu):
      bins (L,) int, freq (L,) cycles/sample, freq_hz (L,) or None, omega (L,) rad/s or None (CT files),
      real (L,) bool (DC lines), G (L, ny, nu) complex,
      cov, cov_known_input (L, g, g) complex or None, dof, dof_known_input (L,) float or None.
    meta: every top-level key but `lines`; line_extra: per line, the keys not held in arrays.
    """

    def __init__(self, G: ArrayLike, freq: ArrayLike, bins: Optional[ArrayLike] = None, cov: Optional[ArrayLike] = None,
                 dof: Optional[ArrayLike] = None, cov_known_input: Optional[ArrayLike] = None,
                 dof_known_input: Optional[ArrayLike] = None, freq_hz: Optional[ArrayLike] = None,
                 omega: Optional[ArrayLike] = None, real: Optional[ArrayLike] = None,
                 meta: Optional[Dict[str, Any]] = None, line_extra: Optional[Sequence[Dict[str, Any]]] = None) -> None:
        self.G = np.asarray(G, dtype=complex)
        if self.G.ndim != 3:
            raise ValueError("G must be L x ny x nu")
        L = self.G.shape[0]
        self.freq = np.asarray(freq, dtype=float).reshape(L)
        self.bins = None if bins is None else np.asarray(bins, dtype=int).reshape(L)
        self.cov = None if cov is None else np.asarray(cov, dtype=complex)
        self.dof = None if dof is None else np.asarray(dof, dtype=float).reshape(L)
        self.cov_known_input = None if cov_known_input is None else np.asarray(cov_known_input, dtype=complex)
        self.dof_known_input = None if dof_known_input is None else np.asarray(dof_known_input, dtype=float).reshape(L)
        self.freq_hz = None if freq_hz is None else np.asarray(freq_hz, dtype=float).reshape(L)
        self.omega = None if omega is None else np.asarray(omega, dtype=float).reshape(L)
        self.real = np.zeros(L, bool) if real is None else np.asarray(real, dtype=bool).reshape(L)
        self.meta = dict(meta or {})
        self.line_extra = [dict(e) for e in line_extra] if line_extra is not None else [{} for _ in range(L)]
        self.notes = []     # msid.frf / Measurement.frf: msid's notes on the estimate
        self.reports = []   # msid.frf: what period="auto" / lines="auto" found

    @classmethod
    def _of_arrays(cls, a: Dict[str, Any]) -> "FRF":
        """The FRF of msid._msid's arrays (frf_to_py: already of the dtypes and shapes above), taken as
        they are: the checks and conversions of __init__ are for arrays from elsewhere."""
        f = cls.__new__(cls)
        f.G = a["G"]
        f.freq, f.bins, f.cov, f.dof = a["freq"], a.get("bin"), a.get("cov"), a.get("dof")
        f.cov_known_input, f.dof_known_input = a.get("cov_known_input"), a.get("dof_known_input")
        f.freq_hz, f.omega, f.real = a.get("freq_hz"), a.get("omega"), a["real"]
        f.meta = a["meta"]
        f.line_extra = a["line_extra"]
        f.notes, f.reports = [], []
        return f

    def __repr__(self) -> str:
        # what an FRF is at a glance: outputs x inputs, lines and their range, the estimator, the domain
        L = self.n_lines
        if L:
            f, unit = self.hz_axis()
            span = f"at {f[0]:.4g} {unit}" if L == 1 else f"{float(np.min(f)):.4g}–{float(np.max(f)):.4g} {unit}"
        else:
            span = "no frequencies"
        imp = self.meta.get("imported")
        # msid's own estimate says which estimator made it; another tool's FRF says where it came from
        parts = [] if isinstance(imp, dict) else [str(self.meta.get("method", "periodic"))]
        if self.domain == "ct":
            parts.append("ct")
        if isinstance(imp, dict):
            parts.append(f"imported ({imp.get('format', 'another tool')})")
        return f"<FRF {self.n_outputs}x{self.n_inputs}, {L} line{'' if L == 1 else 's'} {span}, {', '.join(parts)}>"

    # sizes and axes
    @property
    def n_lines(self) -> int:
        return self.G.shape[0]

    @property
    def n_outputs(self) -> int:
        return self.G.shape[1]

    @property
    def n_inputs(self) -> int:
        return self.G.shape[2]

    @property
    def domain(self) -> str:
        return self.meta.get("domain", "dt")

    @property
    def sample_time(self) -> Optional[float]:
        return self.meta.get("sample_time")

    def omega_axis(self) -> np.ndarray:
        """Line frequencies in rad/s (rad/sample when the file has no sample time): the model's frequency."""
        if self.omega is not None:
            return self.omega.copy()
        h = self.sample_time
        return 2 * np.pi * self.freq / (h if h else 1.0)

    def hz_axis(self) -> Tuple[np.ndarray, str]:
        """(frequencies, unit): Hz when the sample rate is known, else cycles/sample."""
        if self.freq_hz is not None:
            return self.freq_hz.copy(), "Hz"
        if self.omega is not None:
            return self.omega / (2 * np.pi), "Hz"
        if self.sample_time:
            return self.freq / self.sample_time, "Hz"
        return self.freq.copy(), "cycles/sample"

    # uncertainty
    def _pick(self, which):
        if which == "cov":
            return self.cov, self.dof
        if which == "known-input":
            return self.cov_known_input, self.dof_known_input if self.dof_known_input is not None else self.dof
        raise ValueError("which must be 'cov' or 'known-input'")

    def variance(self, which: str = "cov") -> Optional[np.ndarray]:
        """Variance of each element of G, (L, ny, nu), from the diagonal of the covariance of vec(G)."""
        c, _ = self._pick(which)
        if c is None:
            return None
        return _unvec(np.real(np.diagonal(c, axis1=1, axis2=2)), self.n_outputs, self.n_inputs)

    def std(self, which: str = "cov") -> Optional[np.ndarray]:
        v = self.variance(which)
        return None if v is None else np.sqrt(np.maximum(v, 0.0))

    def radius(self, level: float = 0.95, which: str = "cov") -> Optional[np.ndarray]:
        """Radius of the exact `level` confidence disc of each G element, (L, ny, nu) (see msid.regions)."""
        v = self.variance(which)
        if v is None:
            return None
        _, dof = self._pick(which)
        return regions.radius(v, None if dof is None else dof[:, None, None], level, self.real[:, None, None])

    def subsystem(self, outputs: Sequence[int], inputs: Sequence[int]) -> "FRF":
        """The FRF of the given outputs and inputs (0-based lists), covariances restricted to them: a valid
        FRF of its own (write_frf), e.g. one SISO path of a MIMO measurement."""
        outputs, inputs = list(outputs), list(inputs)
        ny = self.n_outputs
        idx = [i + ny * j for j in inputs for i in outputs]   # vec of the sub-matrix, columns stacked

        def sub(c):
            return None if c is None else c[:, idx][:, :, idx]
        meta = dict(self.meta)
        meta["n_outputs"], meta["n_inputs"] = len(outputs), len(inputs)
        if "noise_cov" in meta:
            meta["noise_cov"] = _cmat_json(_cmat(meta["noise_cov"], (ny, ny), "noise_cov")[np.ix_(outputs, outputs)])
        extra = []
        for e in self.line_extra:
            e = {k: v for k, v in e.items() if k not in ("cond", "input_snr", "cov_noise", "dof_noise", "var_nl", "var_s", "nl_p_value")}
            if "noise_cov" in e:
                e["noise_cov"] = _cmat_json(_cmat(e["noise_cov"], (ny, ny), "noise_cov")[np.ix_(outputs, outputs)])
            if isinstance(e.get("snr"), list) and len(e["snr"]) == ny:
                e["snr"] = [e["snr"][i] for i in outputs]
            extra.append(e)
        return FRF(self.G[:, outputs][:, :, inputs], self.freq, bins=self.bins, cov=sub(self.cov), dof=self.dof,
                   cov_known_input=sub(self.cov_known_input), dof_known_input=self.dof_known_input,
                   freq_hz=self.freq_hz, omega=self.omega, real=self.real, meta=meta, line_extra=extra)

    def signal_names(self) -> Tuple[List[str], List[str]]:
        """(input names, output names): the file's `input_names`/`output_names` when it has them, else
        u1.., y1.. (the names msid prints)."""
        return _signal_names(self.meta, self.n_inputs, self.n_outputs)

    def signal_units(self) -> Tuple[List[str], List[str]]:
        """(input units, output units): the file's `input_units`/`output_units` when it has them ("" where
        a unit is unknown), else "" for every signal."""
        return _signal_units(self.meta, self.n_inputs, self.n_outputs)

    def gain_unit(self, output: int, input: int) -> str:
        """The unit of G[output, input] ("m/s^2/N"), or "" when either unit is unknown."""
        ui, uo = self.signal_units()
        return f"{uo[output]}/{ui[input]}" if uo[output] and ui[input] else ""

    # python-control
    def to_control(self, name: Optional[str] = None) -> Any:
        """python-control FRD of G (frequencies in rad/s, or rad/sample without a sample time) with a name
        (`name`, else the file's source), dt (the sample time of a DT file, True when it has none; 0 for CT)
        and the signal names. A DT FRD also evaluates at points z on the unit circle, at its own lines
        (python-control's Nyquist contour of a DT system): control.nyquist_plot(frd, frd.omega)."""
        ins, outs = self.signal_names()
        dt = 0 if self.domain == "ct" else (self.sample_time or True)
        return _frd_class()(np.transpose(self.G, (1, 2, 0)), self.omega_axis(), dt=dt,
                            name=name or _system_name(self.meta.get("source"), "msid_frf"), inputs=ins, outputs=outs)

    @classmethod
    def from_control(cls, frd: Any, period_samples: Optional[int] = None, sample_time: Optional[float] = None,
                     cov: Optional[ArrayLike] = None, dof: Optional[ArrayLike] = None, **meta: Any) -> "FRF":
        """An FRF from a python-control FRD.

        A continuous-time FRD (dt = 0) without `period_samples` is a continuous-time FRF at its own
        frequencies (rad/s, no sample time, no DFT bins), as msid.import_frf reads other tools' FRFs:
        msid.fit makes a continuous-time model of it, unweighted without `cov`/`dof` (no p-value).
        Otherwise the FRD frequencies (rad/s with `sample_time`, else rad/sample) must be DFT bins
        k/period_samples; `cov`/`dof` (L x g x g, L) are optional: without them the file has no
        uncertainty and is written with a zero covariance and dof 1 (msid fit then needs --weight none)."""
        om = np.asarray(frd.omega, dtype=float)
        G = np.transpose(np.asarray(frd.frdata if hasattr(frd, "frdata") else frd.fresp), (2, 0, 1))
        if period_samples is None:
            if getattr(frd, "dt", 0) not in (0, None):
                raise ValueError("a discrete-time FRD needs period_samples (the DFT length of its bins)")
            ins = [str(x) for x in getattr(frd, "input_labels", [])]
            outs = [str(x) for x in getattr(frd, "output_labels", [])]
            m = {"period_samples": 0, "domain": "ct", "imported": {"format": "python-control FRD",
                                                                   "source": str(getattr(frd, "name", ""))}}
            if len(ins) == G.shape[2] and len(outs) == G.shape[1]:
                m["input_names"], m["output_names"] = ins, outs
            m.update(meta)
            return cls(G, np.zeros(len(om)), bins=np.arange(len(om)), cov=cov, dof=dof,
                       cov_known_input=cov, dof_known_input=dof, omega=om, freq_hz=om / (2 * np.pi),
                       real=(om == 0) & np.all(np.imag(G) == 0, axis=(1, 2)), meta=m)
        freq = om * (sample_time if sample_time else 1.0) / (2 * np.pi)
        bins = np.rint(freq * period_samples).astype(int)
        if np.any(np.abs(bins - freq * period_samples) > 1e-6 * period_samples) or np.any(freq > 0.5 + 1e-12):
            raise ValueError("FRD frequencies are not DFT bins of period_samples at or below Nyquist")
        m = {"period_samples": int(period_samples), "domain": "dt"}
        if sample_time:
            m["sample_time"] = float(sample_time)
            m["fs_hz"] = 1.0 / float(sample_time)
        m.update(meta)
        return cls(G, bins / period_samples, bins=bins, cov=cov, dof=dof, real=(bins == 0), meta=m,
                   freq_hz=(bins / period_samples / sample_time) if sample_time else None)


def frf_from_doc(doc: Dict[str, Any], where: str = "document") -> FRF:
    """An FRF from an msid-frf/1 document already in memory (a dict, as json.load gives it): the one
    converter of read_frf and msid.frf. `where` names the document in errors."""
    if not isinstance(doc, dict) or doc.get("format") != FRF_FORMAT:
        got = doc.get("format") if isinstance(doc, dict) else None
        raise FormatError(f"{where}: format is {json.dumps(got)}, expected \"{FRF_FORMAT}\"")
    try:
        ny, nu = int(doc["n_outputs"]), int(doc["n_inputs"])
        lines = doc["lines"]
    except (KeyError, TypeError, ValueError) as e:
        raise FormatError(f"{where}: missing or bad {e}") from None
    if not isinstance(lines, list) or not lines:
        raise FormatError(f"{where}: 'lines' must be a non-empty array")
    g = ny * nu
    if not all(isinstance(ln, dict) for ln in lines):
        raise FormatError(f"{where}: every entry of 'lines' must be an object")
    have = {k: all(k in ln for ln in lines) for k in _LINE_ARRAYS}
    G = _cmats([ln.get("G") for ln in lines], (ny, nu), where, "G")
    cov = _cmats([ln["cov"] for ln in lines], (g, g), where, "cov") if have["cov"] else None
    cki = _cmats([ln["cov_known_input"] for ln in lines], (g, g), where, "cov_known_input") \
        if have["cov_known_input"] else None
    extra = [{a: b for a, b in ln.items() if a not in _LINE_ARRAYS} for ln in lines]

    def col(key, dtype=float):
        return np.array([ln[key] for ln in lines], dtype=dtype) if have[key] else None

    meta = {a: b for a, b in doc.items() if a != "lines"}
    return FRF(G, col("freq"), bins=col("bin", int), cov=cov, dof=col("dof"), cov_known_input=cki,
               dof_known_input=col("dof_known_input"), freq_hz=col("freq_hz"), omega=col("omega"),
               real=np.array([bool(ln.get("real", False)) for ln in lines]), meta=meta, line_extra=extra)


def frf_to_doc(frf: FRF, complete: bool = True) -> Dict[str, Any]:
    """The msid-frf/1 document of an FRF (a dict), as write_frf writes it. complete=False leaves out
    what the FRF does not hold (a line's cov, dof, cov_known_input, snr) instead of neutral values:
    the document msid.fit hands to the fit, which then weighs exactly as `msid fit` on the file."""
    L, ny, nu = frf.G.shape
    g = ny * nu
    doc = {"format": FRF_FORMAT}
    doc.update({k: v for k, v in frf.meta.items() if k != "format"})
    doc["n_inputs"], doc["n_outputs"] = nu, ny
    doc.setdefault("generator", "msid python package")
    doc.setdefault("domain", "dt")
    doc.setdefault("n_experiments", 1)
    if "period_samples" not in doc:
        raise ValueError("an FRF needs meta['period_samples'] (the DFT length of its bins)")
    doc.setdefault("periods_used", 0)
    doc.setdefault("periods_rejected", 0)
    # a BLA of one period per realisation has no noise part: nothing neutral stands in for it
    total_only = (frf.meta.get("nonlinear_distortion") or {}).get("noise_separated") is False
    if not total_only:
        doc.setdefault("noise_cov", _cmat_json(np.zeros((ny, ny))))
    doc.setdefault("experiments", [{"source": "python", "samples": 0, "periods_total": 0, "periods_skipped": 0,
                                    "periods_used": 1, "periods_gap": 0, "periods_nonfinite": 0,
                                    "transient_flagged": [], "transient_dropped": [], "leftover_samples": 0}])
    P = int(doc["period_samples"])
    bins = frf.bins if frf.bins is not None else np.rint(frf.freq * P).astype(int)
    lines = []
    for k in range(L):
        ln = {"bin": int(bins[k]), "freq": float(frf.freq[k])}
        if frf.freq_hz is not None:
            ln["freq_hz"] = float(frf.freq_hz[k])
        if frf.omega is not None:
            ln["omega"] = float(frf.omega[k])
        if frf.real[k]:
            ln["real"] = True
        ln["G"] = _cmat_json(frf.G[k])
        # an imported FRF without covariance stays without (msid fit: unweighted, no p-value)
        neutral = complete and "imported" not in frf.meta
        if frf.cov is not None or neutral:
            c = frf.cov[k] if frf.cov is not None else np.zeros((g, g))
            ln["cov"] = _cmat_json(c)
            ln["dof"] = float(frf.dof[k]) if frf.dof is not None else 1.0
        if frf.cov_known_input is not None:
            ln["cov_known_input"] = _cmat_json(frf.cov_known_input[k])
        elif neutral and not total_only:
            ln["cov_known_input"] = ln["cov"]
        if frf.dof_known_input is not None:
            ln["dof_known_input"] = float(frf.dof_known_input[k])
        extra = frf.line_extra[k] if k < len(frf.line_extra) else {}
        ln.update(extra)
        if (neutral or (complete and "cov" in ln)) and not total_only:
            ln.setdefault("snr", [None] * ny)
        lines.append(ln)
    doc["lines"] = lines
    return doc


class Model:
    """A parametric model, an msid-model/1 document (msid.fit, read_model): the state-space model (A, B,
    C, D), its domain and sample time, the model's FRF at the data lines (frf_G: L x ny x nu, frf_freq),
    and `doc` (every key of the file)."""

    def __init__(self, doc: Dict[str, Any], path: Optional[PathLike] = None) -> None:
        self.doc = doc
        self.path = path
        self.notes = []     # msid.fit: msid's notes on the fit
        where = f"'{path}'" if path else "model"
        try:
            n, nu, ny = int(doc["order"]), int(doc["n_inputs"]), int(doc["n_outputs"])
        except (KeyError, TypeError, ValueError) as e:
            raise FormatError(f"{where}: missing or bad {e}") from None
        self.A = _rmat(doc.get("A", []), (n, n), where + ".A")
        self.B = _rmat(doc.get("B", []), (n, nu), where + ".B")
        self.C = _rmat(doc.get("C", []), (ny, n), where + ".C")
        self.D = _rmat(doc.get("D"), (ny, nu), where + ".D")
        fr = doc.get("frf") or []
        self.frf_freq = np.array([e["freq"] for e in fr], float)
        self.frf_G = np.array([_cmat(e["G"], (ny, nu), f"{where}.frf[{k}].G") for k, e in enumerate(fr)]).reshape(
            len(fr), ny, nu)

    @property
    def structure(self) -> str:
        """How the model is parametrised: "pole-residue" (ml --param poles), "LMFD" (a matrix fraction,
        A..D its observer-form realisation), "multi" (the records' modal model) or "state space"."""
        if isinstance(self.doc.get("pole_residue"), dict):
            return "pole-residue"
        if isinstance(self.doc.get("lmfd"), dict):
            return "LMFD"
        if isinstance(self.doc.get("multi"), dict):
            return "multi"
        return "state space"

    def __repr__(self) -> str:
        conv = ", not converged" if self.doc.get("converged") is False else ""
        return (f"<Model {self.doc.get('method', 'model')}, order {self.order}, {self.structure}, "
                f"{self.n_outputs}x{self.n_inputs}, {self.domain}{conv}>")

    @property
    def domain(self) -> str:
        return self.doc.get("domain", "dt")

    @property
    def sample_time(self) -> Optional[float]:
        return self.doc.get("sample_time")

    @property
    def order(self) -> int:
        return self.A.shape[0]

    @property
    def n_inputs(self) -> int:
        return self.B.shape[1] if self.B.size else self.D.shape[1]

    @property
    def n_outputs(self) -> int:
        return self.D.shape[0]

    @property
    def poles_at_bound(self) -> List[complex]:
        """The poles (complex, in the model's variable s or z; pairs by their Im > 0 member) that the stable
        pole-residue fit held on the stability bound: their damping is the constraint's, not an estimate
        (`parameters.at_bound`, `pole_residue.poles[k].at_bound`). Empty for other models."""
        pr = self.doc.get("pole_residue")
        if not isinstance(pr, dict):
            return []
        return [complex(p["re"], p["im"]) for p in pr.get("poles", []) if isinstance(p, dict) and p.get("at_bound")]

    @property
    def stabilisation(self) -> Optional[Dict[str, Any]]:
        """The order-selection block (stabilisation diagram) or None."""
        s = self.doc.get("order_selection")
        return s if isinstance(s, dict) and s.get("orders") else None

    def response_at(self, x: ArrayLike) -> np.ndarray:
        """G(x) = C (x I - A)^-1 B + D at complex points x (s = j omega for CT, z for DT): (len(x), ny, nu)."""
        x = np.atleast_1d(np.asarray(x, dtype=complex))
        n = self.order
        out = np.empty((x.size, self.n_outputs, self.n_inputs), complex)
        for k, p in enumerate(x):
            out[k] = self.D + (self.C @ np.linalg.solve(p * np.eye(n) - self.A, self.B) if n else 0)
        return out

    def response(self, frf: FRF) -> np.ndarray:
        """The model's FRF at the lines of an FRF (the points `msid validate` uses: docs/fitting.md)."""
        if self.domain == "ct":
            return self.response_at(1j * frf.omega_axis())
        return self.response_at(np.exp(2j * np.pi * frf.freq))

    def validate(self, frf: Union[FRF, PathLike, None] = None, **options: Any) -> "Validation":
        """`msid validate` of this model on an FRF (msid.FRF or file), or for a multi model on records=
        (msid.validate's options): an msid.Validation."""
        return validate(self, frf, **options)

    def modes(self) -> "Modes":
        """`msid modes` of this model: natural frequencies, damping ratios (residues) with standard
        deviations, an msid.Modes."""
        return modes(self)

    def signal_names(self) -> Tuple[List[str], List[str]]:
        """(input names, output names): the file's `input_names`/`output_names` when it has them, else
        u1.., y1.."""
        return _signal_names(self.doc, self.n_inputs, self.n_outputs)

    def signal_units(self) -> Tuple[List[str], List[str]]:
        """(input units, output units) as FRF.signal_units: carried from the FRF it was fitted to."""
        return _signal_units(self.doc, self.n_inputs, self.n_outputs)

    def to_control(self, form: str = "ss", name: Optional[str] = None) -> Any:
        """python-control StateSpace (form='ss') or TransferFunction (form='tf'); DT models carry dt =
        sample_time (True when unknown), CT models dt = 0; the system is named (`name`, else
        "msid_<method>_order_<n>") and so are its inputs and outputs (signal_names())."""
        import control
        if form not in ("ss", "tf"):
            raise ValueError("form must be 'ss' or 'tf'")
        dt = 0 if self.domain == "ct" else (self.sample_time or True)
        ins, outs = self.signal_names()
        name = name or f"msid_{self.doc.get('method', 'model')}_order_{self.order}"
        sys = control.ss(self.A, self.B, self.C, self.D, dt, name=name, inputs=ins, outputs=outs)
        return sys if form == "ss" else control.ss2tf(sys, name=name, inputs=ins, outputs=outs)

    @classmethod
    def from_control(cls, sys: Any, frf: FRF, source: Optional[str] = None, n_params: int = 0) -> "Model":
        """A model file from a python-control system (StateSpace or TransferFunction) and the FRF it models.

        `method` is "external"; `frf[]` holds the model at the FRF's lines, and `cost` is the weighted
        residual of docs/fitting.md (V = sum over complex lines |L^-1 vec(e)|^2 + 1/2 over real lines,
        with the FRF's `cov`) against half the residual degrees of freedom less `n_params` (the free
        parameters behind the system, if known: `msid validate` subtracts them from its dof too);
        `msid validate` recomputes the cost with the exact law."""
        import control
        ss = control.ss(sys)
        domain = "ct" if ss.dt == 0 else "dt"
        if domain != frf.domain:
            raise ValueError(f"the system is {domain} but the FRF is {frf.domain}")
        A, B, C, D = (np.atleast_2d(np.asarray(M, float)) for M in (ss.A, ss.B, ss.C, ss.D))
        n = A.shape[0] if ss.nstates else 0
        doc = {"format": MODEL_FORMAT, "generator": "msid python package (python-control)",
               "source": source or frf.meta.get("source", ""), "domain": domain}
        h = frf.sample_time if frf.sample_time else (ss.dt if domain == "dt" and ss.dt not in (True, None) else None)
        if h:
            doc["sample_time"] = float(h)
        doc.update({"method": "external", "settings": {"weight": "cov"}, "order": int(n),
                    "n_inputs": int(ss.ninputs), "n_outputs": int(ss.noutputs),
                    "A": A.reshape(n, n).tolist(), "B": B.reshape(n, ss.ninputs).tolist(),
                    "C": C.reshape(ss.noutputs, n).tolist(), "D": D.reshape(ss.noutputs, ss.ninputs).tolist(),
                    "n_params": int(n_params)})
        eig = np.linalg.eigvals(A) if n else np.zeros(0)
        stable = bool(np.all(eig.real < 0)) if domain == "ct" else bool(np.all(np.abs(eig) < 1))
        doc["stable"] = stable
        doc["stability"] = {"stable": stable, "enforced": False}
        doc["stability"]["max_real_pole" if domain == "ct" else "max_abs_pole"] = (
            (float(eig.real.max()) if domain == "ct" else float(np.abs(eig).max())) if n else None)
        tmp = cls(doc)
        Gm = tmp.response(frf)
        value, rdof = 0.0, 0
        for k in range(frf.n_lines):
            e = (frf.G[k] - Gm[k]).T.reshape(-1)  # vec: columns stacked
            if frf.cov is not None and frf.dof is not None:
                w = np.real(np.conj(e) @ np.linalg.solve(frf.cov[k], e))
            else:
                w = float(np.vdot(e, e).real)
            value += 0.5 * w if frf.real[k] else w
            rdof += e.size if frf.real[k] else 2 * e.size
        rdof -= int(n_params)
        mean, p_value = _cost_law(frf, rdof, value)
        doc["cost"] = {"value": float(value), "expected": mean, "dof": float(rdof), "p_value": p_value,
                       "weight": "cov" if frf.cov is not None else "none"}
        doc["frf"] = []
        for k in range(frf.n_lines):
            e = {"bin": int(frf.bins[k]) if frf.bins is not None else k, "freq": float(frf.freq[k])}
            if domain == "ct":
                e["omega"] = float(frf.omega_axis()[k])
            e["G"] = _cmat_json(Gm[k])
            e["cov"] = None
            doc["frf"].append(e)
        return cls(doc)


def _signal_names(doc, nu, ny):
    """(inputs, outputs) names of a file: its `input_names`/`output_names` lists when they have the right
    lengths, else u1..u<nu>, y1..y<ny>."""
    def pick(key, n, prefix):
        v = doc.get(key)
        if isinstance(v, list) and len(v) == n and all(isinstance(x, str) and x for x in v):
            return list(v)
        return [f"{prefix}{k + 1}" for k in range(n)]
    return pick("input_names", nu, "u"), pick("output_names", ny, "y")


def _signal_units(doc, nu, ny):
    """(inputs, outputs) units of a file: its `input_units`/`output_units` lists when they have the right
    lengths, else "" for each signal (unknown)."""
    def pick(key, n):
        v = doc.get(key)
        if isinstance(v, list) and len(v) == n and all(isinstance(x, str) for x in v):
            return list(v)
        return [""] * n
    return pick("input_units", nu), pick("output_units", ny)


def _system_name(source, default):
    """A python-control system name from a file's `source` (its base name without extension; python-control
    refuses '.' in names), else `default`."""
    if isinstance(source, str) and source.strip():
        base = os.path.splitext(os.path.basename(source.strip().split()[0].rstrip("/")))[0]
        return base.replace(".", "_") or default
    return default


_FRD = None


def _frd_class():
    """control.FrequencyResponseData whose DT systems also evaluate at z = exp(j omega dt) on the unit
    circle, at their own lines: python-control 0.10 evaluates an FRD at j omega only, so its Nyquist
    contour of a DT FRD (points z) raised ValueError."""
    global _FRD
    if _FRD is None:
        import control

        class FRD(control.FrequencyResponseData):
            def __call__(self, x=None, squeeze=None, return_magphase=None):
                if x is not None and self.isdtime(strict=True):
                    z = np.atleast_1d(np.asarray(x, complex))
                    if z.ndim == 1 and np.all(np.abs(np.abs(z) - 1) < 1e-9):
                        h = 1.0 if self.dt is True else float(self.dt)
                        w = np.angle(z) / h
                        # the round trip exp/angle moves omega by an ulp: snap to the line within 1e-9
                        k = np.clip(np.searchsorted(self.omega, w), 1, len(self.omega) - 1)
                        near = np.where(np.abs(self.omega[k - 1] - w) <= np.abs(self.omega[k] - w),
                                        self.omega[k - 1], self.omega[k]) if len(self.omega) > 1 else self.omega[:1]
                        w = np.where(np.abs(near - w) <= 1e-9 * np.maximum(np.abs(near), 1e-300), near, w)
                        x = 1j * (w if np.ndim(x) else w[0])
                return super().__call__(x, squeeze=squeeze, return_magphase=return_magphase)

            def __getitem__(self, key):   # frd[i, j] (a SISO path, for nyquist_plot) keeps the DT evaluation
                sub = super().__getitem__(key)
                sub.__class__ = type(self)
                return sub
        _FRD = FRD
    return _FRD


def _cost_law(frf, rdof, value):
    """Mean and p-value of the weighted cost V (eq. 40) of a model with `rdof` real residual degrees of
    freedom, as docs/fitting.md ("Validation") states it: each complex term |e|^2/v is F(2, 2n)-like with
    mean n/(n - ny) and the relative variance of an inverse Wishart moment; V is matched by a scaled
    chi-square c chi2(k) with those two moments. n: the smallest dof over the lines; for the
    nonparametric covariance of a multi-input periodic FRF one experiment's share (dof / m), for a
    robust-BLA file dof / nu. Without a covariance (unit weights): n infinite. p-value None without scipy."""
    ny = frf.n_outputs
    if frf.cov is None or frf.dof is None:
        n = math.inf
    else:
        dof = frf.dof.astype(float).copy()
        meth = frf.meta.get("method", "periodic")
        m = int(frf.meta.get("n_experiments", 1))
        real = int((frf.meta.get("nonlinear_distortion") or {}).get("realisations", 1) or 1)
        if frf.n_inputs > 1 and m > 1 and meth not in ("lpm", "etfe") and real < 2:
            dof /= m
        if frf.n_inputs > 1 and real >= 2:
            dof /= frf.n_inputs
        n = float(dof.min())
    mu, s2 = 1.0, 1.0
    if math.isfinite(n) and n < 1e8:
        mu = n / (n - ny) if n > ny else math.inf
        rel = (n ** 3 / ((n - 1) ** 2 * (n - 2))) / (n / (n - 1)) ** 2 if n > 2 else 1e300
        s2 = rel * mu * mu
    mean, var = 0.5 * rdof * mu, 0.5 * rdof * s2
    try:
        from scipy import stats
        c, k = var / (2 * mean), 2 * mean * mean / var
        p = float(stats.chi2.sf(value / c, k)) if math.isfinite(c) and math.isfinite(k) and k > 0 else None
    except ImportError:
        p = None
    return (float(mean) if math.isfinite(mean) else None), p


def model_to_doc(model: "Model") -> Dict[str, Any]:
    """The msid-model/1 document of a Model (its doc, with A..D from the arrays), as write_model writes it."""
    doc = dict(model.doc)
    doc["format"] = MODEL_FORMAT
    for k in ("A", "B", "C", "D"):
        doc[k] = np.asarray(getattr(model, k), float).tolist()
    for k in ("A", "B", "C", "D"):
        if not all(math.isfinite(x) for row in doc[k] for x in row):
            raise ValueError(f"model {k} is not finite")
    return doc


def _frf_json(frf: Union[FRF, PathLike], what: str) -> Tuple[str, str]:
    """An FRF (msid.FRF, or an FRF file's path) as JSON text and the name msid gives it: an msid-frf/1
    file is handed over as written, so the fit reads the bytes `msid fit` reads and names it by its path;
    another tool's file is imported as `msid fit` imports it."""
    if isinstance(frf, (str, os.PathLike)):
        path = os.fspath(frf)
        if os.path.isfile(path) and _ext().frf_format(path, "") != "msid":
            return _ext().import_frf(path, ""), path
        return _file_text(frf)
    if not isinstance(frf, FRF):
        raise TypeError(f"{what} must be an msid.FRF or an msid-frf/1 file's path, not {type(frf).__name__}")
    import json
    doc = frf_to_doc(frf, complete=False)
    try:
        return json.dumps(doc, allow_nan=False), "(in-memory FRF)"
    except ValueError as e:   # NaN or an infinity in the arrays
        raise ValueError(f"{what}: {e} (an FRF holds finite numbers only)") from None


class Validation:
    """What `msid validate MODEL FRF` reports: the weighted residual cost of the model on the FRF against
    its law (docs/fitting.md, "Validation").

    cost, expected, dof, p_value; consistent (p_value >= 0.05); report: the msid-validation/1 document
    (`msid validate -o`), with per-line normalised residuals in report["lines"] and, when the FRF carries
    it, the noise level against the nonlinear distortion in report["nonlinear_distortion"]; text: the
    lines msid prints.
    """

    def __init__(self, res: Dict[str, Any]) -> None:
        self.report = res["report"]
        self.text = list(res["text"])
        # None: an FRF without covariance (another tool's, msid.import_frf) has no noise scale, no verdict
        self.consistent = None if res["consistent"] is None else bool(res["consistent"])
        self.cost = self.report["cost"]
        self.expected = self.report.get("expected")     # on records: the model's noise variance is the reference
        self.dof = self.report["dof"]
        self.p_value = self.report["p_value"]

    @property
    def normalised_residuals(self) -> np.ndarray:
        """Per line: the residual over its expectation under the model (about 1), an array (FRF validation)."""
        return np.array([ln["normalised_residual"] for ln in self.report.get("lines", [])], dtype=float)

    def __str__(self) -> str:
        return "\n".join(self.text)

    def __repr__(self) -> str:
        ref = f", expected {self.expected:.6g}" if self.expected is not None else ""
        if self.p_value is None:
            return f"<msid.Validation unweighted cost {self.cost:.6g} (dof {self.dof:.0f}): no covariance, no verdict>"
        verdict = "consistent" if self.consistent else "NOT consistent"
        return (f"<msid.Validation cost {self.cost:.6g}{ref} (dof {self.dof:.0f}), p-value {self.p_value:.4g}: "
                f"{verdict} at 5%>")


def _model_json(model: Union["Model", PathLike]) -> Tuple[str, str]:
    """A model (msid.Model, or an msid-model/1 file's path) as JSON text and the name msid gives it."""
    import json
    if isinstance(model, (str, os.PathLike)):
        return _file_text(model)
    if isinstance(model, Model):
        return json.dumps(model_to_doc(model), allow_nan=False), os.fspath(model.path or "(in-memory model)")
    raise TypeError(f"model must be an msid.Model or an msid-model/1 file's path, not {type(model).__name__}")


def validate(model: Union[Model, PathLike], frf: Union[FRF, PathLike, None] = None, *, weight: Optional[str] = None,
             lpm_lines: str = "independent", records: Any = None, lags: int = 10, own_records: bool = False,
             columns: Union[str, Dict[str, str], None] = None, n_inputs: Optional[int] = None) -> Validation:
    """`msid validate` in process. The model (msid.Model or a model file) on the FRF (msid.FRF or an FRF
    file): weight "cov", "known-input" or "none" (default: the model's fit weight, known-input or cov),
    lpm_lines "independent" (LPM files: every (2W+1)-th line) or "all". Or a model of method="multi" on
    time records (records=: arrays or DataFrames as msid.fit takes them, columns / n_inputs as there;
    lags: the whiteness test's lags; own_records=True: the records the model was fitted to, on which only
    the whiteness test counts), as `msid validate MODEL --experiment ...`. Returns a Validation;
    ValueError with msid's message when the model does not fit the data's channels or frequencies."""
    mtext, mname = _model_json(model)
    if records is not None:
        if frf is not None:
            raise ValueError("give an FRF or records, not both")
        recs = _records(records, columns, n_inputs, free=True)
        return Validation(_ext().validate_records(mtext, mname, recs, _uint(lags, "lags"), bool(own_records)))
    if frf is None:
        raise ValueError("give the FRF (or, for a multi model, records=) to validate the model on")
    ftext, fname = _frf_json(frf, "frf")
    opts = {"weight": None if weight is None else str(weight), "lpm_lines": str(lpm_lines)}
    return Validation(_ext().validate(mtext, mname, ftext, fname, opts))


class Modes:
    """What `msid modes MODEL` reports: per pole pair (or real pole) the natural frequency, damping ratio
    (and for FRF models the residues) with standard deviations. report: the msid-modes/1 document
    (`msid modes -o`); modes: its list of modes (dicts); text: what msid prints."""

    def __init__(self, res: Dict[str, Any]) -> None:
        self.report = res["report"]
        self.text = res["text"]
        self.modes = list(self.report.get("modes", []))

    @property
    def at_bound(self) -> List[Dict[str, Any]]:
        """The modes (dicts of `modes`) whose pole lies on the stability bound of the constrained fit: their
        damping is the constraint's, `sd_zeta` is None."""
        return [m for m in self.modes if m.get("at_bound")]

    def __str__(self) -> str:
        return self.text

    def __repr__(self) -> str:
        return f"<msid.Modes {len(self.modes)} mode(s) of {self.report.get('model')}>"


def modes(model: Union[Model, PathLike]) -> Modes:
    """`msid modes MODEL` in process (Model.modes()): an msid.Modes; ValueError with msid's message for a
    model without poles to report."""
    mtext, mname = _model_json(model)
    return Modes(_ext().modes(mtext, mname))
